"""Results on disk whose content is verified on every read: :class:`ResultStore`.

One atomically written file per :class:`~optimizers.common.executor.TaskKey` under
``<directory>/results/``, and ``<directory>/identity.json`` recording what the results belong
to (an algorithm and its settings, a campaign's configuration, a dataset's recipe). Campaigns,
optimiser studies, imitation datasets and per-case optima keep their finished tasks here, so a
rerun of the same command does only what is missing.

The envelope. Every stored result carries

- its **key** (problem, seed, index),
- the **fingerprint** of the store's identity (the first 16 hex digits of the SHA-256 of the
  identity's canonical JSON),
- the **SHA-256 of its payload** and the payload's length,

in the form native to each format, so the files stay readable with the usual tools:

========  =====================================================================================
format    file
========  =====================================================================================
json      ``{"store": HEADER, "value": PAYLOAD}``: one JSON document; the checksum covers the
          bytes of ``PAYLOAD`` exactly as written.
pickle    one line ``lunar-result HEADER`` then the pickled payload: the header is checked
          before anything is unpickled, so a file copied in from elsewhere is never unpickled.
npz       the value's arrays plus the member ``__store__`` (the header, a string); the checksum
          covers each array's name, dtype, shape and bytes.
========  =====================================================================================

A read checks, in order: the envelope decodes (a truncated or undecodable file, or one written
without an envelope, fails here); the key is the one asked for (a file copied over another
key's file fails here); the fingerprint is this store's (a file from a store of other settings
fails here); the checksum matches (an edited value fails here); then the caller's checks:
``validate(value)`` and ``schema(key, value)`` (:class:`ResultSchema`: required fields, lists
of one length, values the key implies, such as the cases a chunk covers). A result that fails
any of them is *damaged*: :meth:`ResultStore.get` raises a ValueError naming the file and the
reason, and :meth:`ResultStore.load` (what :func:`~optimizers.common.executor.run_tasks` reads
with) moves it aside to ``<file>.damaged`` with a printed message, so its task runs again.

The identity. ``identity.json`` is created atomically and never overwritten (a temporary file
linked into place: of two processes creating the same store one wins and the other compares
with it). A store whose identity differs is refused, naming the differing keys. A directory
that holds results but whose ``identity.json`` is missing or unreadable is refused too: which
settings its results were made with can no longer be told, and adopting the new settings would
mix results of two configurations.

One writer per directory is the caller's :class:`~optimizers.common.lock.DirectoryLock`; the
store itself never locks (readers need no lock).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import pickle
import re
import zipfile
import zlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .checkpoint import atomic_write_bytes, temporary_sibling, write_synced

_SAFE = re.compile(r"[^A-Za-z0-9_.-]+")

__all__ = ["TaskKey", "ResultStore", "ResultSchema", "DamagedResult", "StoreIdentityError",
           "identity_fingerprint", "MISSING", "ENVELOPE_FORMAT"]

#: version of the envelope written around every stored result
ENVELOPE_FORMAT = 1
_PICKLE_MAGIC = b"lunar-result "
_NPZ_HEADER = "__store__"
_JSON_HEAD = b'{"store": '
_JSON_SEP = b', "value": '


@dataclass(frozen=True, order=True)
class TaskKey:
    """Identity of one task: the problem it belongs to, the master seed, the task's index.

    ``problem`` is any short string that names what the task works on (a problem's name and
    fingerprint, a scenario and shard size, an Optuna study); ``seed`` the master seed of the
    whole set of tasks; ``index`` the task's number within it.
    """

    problem: str
    seed: int
    index: int

    def __post_init__(self) -> None:
        if not isinstance(self.problem, str) or not self.problem:
            raise ValueError(f"TaskKey.problem = {self.problem!r} must be a non-empty string")
        for name in ("seed", "index"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise ValueError(f"TaskKey.{name} = {v!r} must be a non-negative int")

    @property
    def filename(self) -> str:
        """A file name unique to the key (characters outside ``[A-Za-z0-9_.-]`` become ``_``)."""
        return f"{_SAFE.sub('_', self.problem)}__seed{self.seed}__{self.index:06d}"



class _Missing:
    """The value of a key with no readable result (:meth:`ResultStore.load`)."""

    _instance = None

    def __new__(cls):
        if cls._instance is None:
            cls._instance = super().__new__(cls)
        return cls._instance

    def __repr__(self) -> str:
        return "MISSING"

    def __bool__(self) -> bool:
        return False

    def __reduce__(self):
        return (_Missing, ())


#: what :meth:`ResultStore.load` returns for a key without a readable result
MISSING = _Missing()


class DamagedResult(ValueError):
    """A stored result failed a check (envelope, key, store, checksum, validator, schema)."""


class StoreIdentityError(ValueError):
    """The directory holds a store of other settings, or one whose identity cannot be read."""


def _canonical_json(obj: Any) -> bytes:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str).encode()


def identity_fingerprint(identity: Mapping[str, Any] | None) -> str:
    """The first 16 hex digits of the SHA-256 of ``identity``'s canonical JSON (sorted keys)."""
    return hashlib.sha256(_canonical_json(dict(identity or {}))).hexdigest()[:16]


# ----------------------------------------------------------------------------- schema


@dataclass(frozen=True)
class ResultSchema:
    """What a result read for a key must hold (a ``schema`` of :class:`ResultStore`).

    A result is a mapping (a dict from JSON or pickle, the arrays of an npz).

    Parameters
    ----------
    required : sequence of str
        Fields every result has.
    same_length : sequence of str
        Per-item fields (e.g. per-case lists) that must all have one length; those absent are
        skipped (list them in ``required`` too where they must be there).
    expected : callable, optional
        ``expected(key) -> dict`` of fields whose values the key implies, compared exactly
        (lists and arrays element by element): e.g. ``{"case": list(range(first, first + n))}``
        for the chunk of cases that key ``k`` names, so a chunk's result stored under another
        chunk's key is refused.

    Examples
    --------
    >>> chunk = 100
    >>> schema = ResultSchema(
    ...     required=("case", "fuel_kg"), same_length=("case", "fuel_kg"),
    ...     expected=lambda key: {"case": list(range(chunk * key.index,
    ...                                              chunk * key.index + chunk))})
    """

    required: Sequence[str] = ()
    same_length: Sequence[str] = ()
    expected: Callable[[TaskKey], Mapping[str, Any]] | None = None

    def __call__(self, key: TaskKey, value: Any) -> None:
        """Raise ValueError naming the first field that differs from what ``key`` implies."""
        if not isinstance(value, Mapping):
            raise ValueError(f"holds a {type(value).__name__}, not a mapping of fields")
        missing = [f for f in self.required if f not in value]
        if missing:
            raise ValueError(f"lacks the field(s) {missing}")
        lengths = {}
        for f in self.same_length:
            if f in value:
                try:
                    lengths[f] = len(value[f])
                except TypeError:
                    raise ValueError(f"field {f!r} is not a list (it has no length)") from None
        if len(set(lengths.values())) > 1:
            raise ValueError("per-item fields of different lengths: "
                             + ", ".join(f"{f} {n}" for f, n in lengths.items()))
        if self.expected is not None:
            for f, want in dict(self.expected(key)).items():
                if f not in value:
                    raise ValueError(f"lacks the field {f!r} that its key implies")
                if not _same(value[f], want):
                    raise ValueError(f"field {f!r} = {_short(value[f])} is not "
                                     f"{_short(want)}, which its key {tuple(_key_list(key))} "
                                     "implies")


def _same(a: Any, b: Any) -> bool:
    import numpy as np

    try:
        return bool(np.array_equal(np.asarray(a), np.asarray(b)))
    except (TypeError, ValueError):
        return a == b


def _short(v: Any) -> str:
    text = repr(v.tolist() if hasattr(v, "tolist") else v)
    return text if len(text) <= 60 else text[:57] + "..."


def _key_list(key: TaskKey) -> list:
    return [key.problem, int(key.seed), int(key.index)]


# ----------------------------------------------------------------------------- envelopes


def _npz_digest(arrays: Mapping[str, Any]) -> tuple[str, int]:
    """SHA-256 and byte count over each array's name, dtype, shape and C-order bytes."""
    import numpy as np

    h = hashlib.sha256()
    n = 0
    for name in sorted(arrays):
        a = np.asarray(arrays[name])
        if a.dtype.hasobject:
            raise TypeError(f"array {name!r} holds Python objects; an npz store holds numeric, "
                            "boolean and string arrays only")
        h.update(f"{name}\0{a.dtype.str}\0{a.shape}\0".encode())
        data = np.ascontiguousarray(a).tobytes()
        h.update(data)
        n += len(data)
    return h.hexdigest(), n


def _json_default(o):
    import numpy as np

    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")


def _header(key: TaskKey, fingerprint: str, sha: str, n_bytes: int) -> dict:
    return {"format": ENVELOPE_FORMAT, "key": _key_list(key), "store": fingerprint,
            "sha256": sha, "bytes": int(n_bytes)}


class ResultStore:
    """Results on disk, one verified, atomically written file per task key.

    ``<directory>/results/<key.filename>.json`` (JSON values), ``.pkl`` (anything picklable,
    ``fmt="pickle"``) or ``.npz`` (dicts of numpy arrays, ``fmt="npz"``: compressed, read with
    ``allow_pickle=False``), each in its envelope (see the module docstring), and
    ``<directory>/identity.json``.

    Damaged files. :meth:`get` raises a :class:`DamagedResult` (a ValueError) naming the file
    and the reason; :meth:`load`, ``key in store`` and :meth:`readable` move a damaged file
    aside to ``<file>.damaged`` with a printed message naming it, so
    :func:`~optimizers.common.executor.run_tasks` runs its task again.

    Parameters
    ----------
    directory : path
    identity : dict, optional
        JSON-serialisable description of what the results belong to (algorithm, settings,
        problem fingerprint, ...). None is the empty identity ``{}`` (compared like any other).
    fmt : {"json", "pickle", "npz"}
    validate : callable, optional
        ``validate(value)`` raises ValueError if a value read back is incomplete (e.g. lacks a
        required array); such an entry counts as damaged.
    schema : callable, optional
        ``schema(key, value)`` raises ValueError if the value read for ``key`` is not what the
        key names (e.g. a :class:`ResultSchema`); such an entry counts as damaged.

    Raises
    ------
    StoreIdentityError
        (a ValueError) The directory holds a store of another identity (the message names the
        differing keys), or holds results but its ``identity.json`` is missing or unreadable.
    """

    _EXT = {"json": ".json", "pickle": ".pkl", "npz": ".npz"}

    def __init__(self, directory: str | os.PathLike, identity: dict | None = None,
                 fmt: str = "json", *, validate: Callable[[Any], None] | None = None,
                 schema: Callable[[TaskKey, Any], None] | None = None) -> None:
        if fmt not in self._EXT:
            raise ValueError(f"fmt = {fmt!r}; use 'json', 'pickle' or 'npz'")
        self.directory = Path(directory)
        self.fmt = fmt
        self.validate = validate
        self.schema = schema
        self._dir = self.directory / "results"
        self.identity = json.loads(json.dumps(dict(identity or {}), default=str))
        self.fingerprint = identity_fingerprint(self.identity)
        self._open_identity()
        self._dir.mkdir(parents=True, exist_ok=True)

    @classmethod
    def existing(cls, directory: str | os.PathLike, fmt: str = "json", **kwargs) -> ResultStore:
        """Open the store in ``directory`` under the identity it records (to read a store made
        elsewhere, e.g. a finished campaign's, without restating its settings); ``kwargs`` as
        the constructor's (``validate``, ``schema``).

        Raises
        ------
        StoreIdentityError
            ``directory`` has no readable ``identity.json``.
        """
        ident_file = Path(directory) / "identity.json"
        try:
            identity = json.loads(ident_file.read_bytes())
            if not isinstance(identity, dict):
                raise ValueError("not a JSON object")
        except (OSError, ValueError) as exc:
            raise StoreIdentityError(f"{directory} is not a result store with a readable "
                                     f"identity.json ({type(exc).__name__}: {exc})") from None
        return cls(directory, identity, fmt, **kwargs)

    # -- identity -------------------------------------------------------------------------------
    @property
    def identity_file(self) -> Path:
        return self.directory / "identity.json"

    def _stored_results(self) -> list[Path]:
        if not self._dir.is_dir():
            return []
        return [p for p in self._dir.iterdir()
                if p.suffix in (".json", ".pkl", ".npz") and not p.name.startswith(".")]

    def _open_identity(self) -> None:
        ident_file = self.identity_file
        self.directory.mkdir(parents=True, exist_ok=True)
        for _ in range(2):
            old = self._read_identity()
            if old is None:  # absent (or unreadable, with no results): create it
                self._create_identity()
                continue
            diff = sorted(k for k in set(old) | set(self.identity)
                          if old.get(k) != self.identity.get(k))
            if diff:
                raise StoreIdentityError(
                    f"{self.directory} holds results of another study, made with other "
                    "settings (differs in "
                    + "; ".join(f"{k}: stored {old.get(k)!r} vs {self.identity.get(k)!r}"
                                for k in diff)
                    + "); use another output directory or delete it")
            return
        raise StoreIdentityError(f"{ident_file} could not be created")  # pragma: no cover

    def _read_identity(self) -> dict | None:
        """The stored identity; None if absent (or unreadable) and the store holds nothing.

        Raises StoreIdentityError if the store holds results but the identity is missing or
        unreadable."""
        ident_file = self.identity_file
        try:
            old = json.loads(ident_file.read_bytes())
            if not isinstance(old, dict):
                raise ValueError("not a JSON object")
            return old
        except FileNotFoundError:
            problem = "is missing"
        except (OSError, ValueError) as exc:
            problem = f"is unreadable ({type(exc).__name__}: {exc})"
        n = len(self._stored_results())
        if n:
            raise StoreIdentityError(
                f"{self.directory} holds {n} stored result(s) but its identity.json {problem}, "
                "so the settings they were made with cannot be checked; restore identity.json, "
                "or use another output directory (or delete this one) to start afresh")
        if ident_file.exists():  # unreadable, nothing stored: replaced
            ident_file.unlink()
        return None

    def _create_identity(self) -> None:
        """Write ``identity.json`` atomically, never over an existing one (link, not
        replace: of two creators one wins and the other compares with it)."""
        data = json.dumps(self.identity, indent=1).encode()
        tmp = temporary_sibling(self.identity_file)
        try:
            write_synced(tmp, data)
            try:
                os.link(tmp, self.identity_file)
            except FileExistsError:
                pass
        finally:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)

    # -- files ----------------------------------------------------------------------------------
    @property
    def _ext(self) -> str:
        return self._EXT[self.fmt]

    def path(self, key: TaskKey) -> Path:
        """The file of ``key``'s result (whether or not it exists)."""
        return self._dir / (key.filename + self._ext)

    def __contains__(self, key: TaskKey) -> bool:
        return self.readable(key)

    def readable(self, key: TaskKey) -> bool:
        """True if ``key`` is stored and passes every check; a damaged file is moved aside
        (``.damaged``) with a message naming it, and False returned (its task runs again)."""
        return self.load(key) is not MISSING

    def load(self, key: TaskKey) -> Any:
        """The value stored under ``key``, or :data:`MISSING` (absent, or damaged: then moved
        aside to ``<file>.damaged`` with a printed message naming it and the reason)."""
        path = self.path(key)
        try:
            return self.get(key)
        except FileNotFoundError:
            return MISSING
        except DamagedResult as exc:
            try:
                os.replace(path, path.with_name(path.name + ".damaged"))
            except FileNotFoundError:  # pragma: no cover  (moved by another reader)
                pass
            print(f"{exc}: moved to {path.name}.damaged; its task runs again", flush=True)
            return MISSING

    # -- write ----------------------------------------------------------------------------------
    def encode(self, key: TaskKey, value: Any) -> bytes:
        """The bytes :meth:`put` writes for ``value`` under ``key`` (the envelope included)."""
        if self.fmt == "json":
            payload = json.dumps(value, default=_json_default).encode()
            head = json.dumps(_header(key, self.fingerprint, hashlib.sha256(payload).hexdigest(),
                                      len(payload)), sort_keys=True).encode()
            return b"".join((_JSON_HEAD, head, _JSON_SEP, payload, b"}"))
        if self.fmt == "pickle":
            payload = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
            head = json.dumps(_header(key, self.fingerprint, hashlib.sha256(payload).hexdigest(),
                                      len(payload)), sort_keys=True).encode()
            return b"".join((_PICKLE_MAGIC, head, b"\n", payload))
        import numpy as np

        if not isinstance(value, Mapping):
            raise TypeError(f"an npz store holds dicts of arrays; got {type(value).__name__} "
                            f"for {key}")
        if _NPZ_HEADER in value:
            raise ValueError(f"the array name {_NPZ_HEADER!r} is the store's own; rename it")
        arrays = {str(k): np.asarray(v) for k, v in value.items()}
        sha, n = _npz_digest(arrays)
        head = json.dumps(_header(key, self.fingerprint, sha, n), sort_keys=True)
        buf = io.BytesIO()
        np.savez_compressed(buf, **arrays, **{_NPZ_HEADER: np.array(head)})
        return buf.getvalue()

    def put(self, key: TaskKey, value: Any) -> Path:
        """Store ``value`` under ``key`` atomically, in its envelope (JSON: NaN/inf allowed,
        as Python writes; npz: a dict of arrays)."""
        return atomic_write_bytes(self.path(key), self.encode(key, value))

    # -- read -----------------------------------------------------------------------------------
    def get(self, key: TaskKey) -> Any:
        """The value stored under ``key``, after every check (see the module docstring).

        Raises
        ------
        FileNotFoundError
            Nothing is stored under ``key``.
        DamagedResult
            (a ValueError) The file fails a check; the message names it and the reason.
        """
        path = self.path(key)
        raw = path.read_bytes()
        try:
            value = self.decode(key, raw)
            if self.validate is not None:
                self.validate(value)
            if self.schema is not None:
                self.schema(key, value)
        except (ValueError, OSError, EOFError, KeyError, IndexError, TypeError, AttributeError,
                pickle.UnpicklingError, zipfile.BadZipFile, zlib.error) as exc:
            raise DamagedResult(f"stored result {path} is damaged ({type(exc).__name__}: "
                                f"{exc})") from None
        return value

    def decode(self, key: TaskKey, raw: bytes) -> Any:
        """The value in ``raw`` (a stored file's bytes) after the envelope's checks for
        ``key``; raises ValueError (or a decoder's error) naming the failed check."""
        if self.fmt == "json":
            if not raw.startswith(_JSON_HEAD):
                raise ValueError("no integrity envelope (an older format or another program's "
                                 "file)")
            head, end = json.JSONDecoder().raw_decode(raw[len(_JSON_HEAD):].decode())
            # raw_decode counts characters; the header is ASCII, so characters are bytes
            start = len(_JSON_HEAD) + end
            if raw[start:start + len(_JSON_SEP)] != _JSON_SEP or not raw.endswith(b"}"):
                raise ValueError("envelope not closed (truncated?)")
            payload = raw[start + len(_JSON_SEP):-1]
            self._check_header(key, head, hashlib.sha256(payload).hexdigest(), len(payload))
            return json.loads(payload)
        if self.fmt == "pickle":
            if not raw.startswith(_PICKLE_MAGIC):
                raise ValueError("no integrity envelope (an older format or another program's "
                                 "file)")
            nl = raw.find(b"\n")
            if nl < 0:
                raise ValueError("envelope not closed (truncated?)")
            head = json.loads(raw[len(_PICKLE_MAGIC):nl])
            payload = raw[nl + 1:]
            self._check_header(key, head, hashlib.sha256(payload).hexdigest(), len(payload))
            return pickle.loads(payload)  # only after the key, store and checksum are checked
        import numpy as np

        with np.load(io.BytesIO(raw), allow_pickle=False) as z:
            arrays = {f: z[f] for f in z.files}
        if _NPZ_HEADER not in arrays:
            raise ValueError("no integrity envelope (an older format or another program's file)")
        head = json.loads(str(arrays.pop(_NPZ_HEADER)))
        sha, n = _npz_digest(arrays)
        self._check_header(key, head, sha, n)
        return arrays

    def _check_header(self, key: TaskKey, head: Any, sha: str, n_bytes: int) -> None:
        if not isinstance(head, dict) or head.get("format") != ENVELOPE_FORMAT:
            raise ValueError(f"envelope of an unknown format ({_short(head)}; this version "
                             f"writes format {ENVELOPE_FORMAT})")
        if head.get("key") != _key_list(key):
            raise ValueError(f"holds the result of key {tuple(head.get('key') or ())}, not of "
                             f"{tuple(_key_list(key))} (a file copied over another's?)")
        if head.get("store") != self.fingerprint:
            raise ValueError(f"belongs to another store (identity fingerprint "
                             f"{head.get('store')!r}, this store's {self.fingerprint!r})")
        if head.get("bytes") != n_bytes:
            raise ValueError(f"payload of {n_bytes} bytes, the envelope says {head.get('bytes')}"
                             " (truncated or edited)")
        if head.get("sha256") != sha:
            raise ValueError("checksum mismatch: the content changed after it was written")

    def keys(self) -> list[str]:
        """File stems of the stored results (sorted; not checked: see :meth:`load`)."""
        return sorted(p.name[:-len(self._ext)] for p in self._dir.glob("*" + self._ext))
