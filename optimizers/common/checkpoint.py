"""Atomic, self-describing checkpoints for resumable solvers.

A checkpoint is a pickle of ``{"format": 1, "identity": {...}, "state": ...}`` written to a
temporary file in the same directory and moved into place with ``os.replace`` (a reader never
sees a half-written file; a kill leaves the previous checkpoint intact). ``identity`` records
what the state belongs to (algorithm, its settings, the problem's fingerprint, the seed);
:func:`load_checkpoint` refuses a file whose identity differs, naming the differing keys.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import secrets
from pathlib import Path
from typing import Any

__all__ = ["save_checkpoint", "load_checkpoint", "atomic_write_bytes", "save_figure_atomic",
           "save_npz_atomic", "temporary_sibling", "write_synced", "CheckpointMismatch"]

_FORMAT = 1


class CheckpointMismatch(ValueError):
    """The checkpoint belongs to another run (problem, settings or seed)."""


def temporary_sibling(path: str | os.PathLike) -> Path:
    """A name for a temporary file beside ``path`` that no other writer uses (hidden, this
    process's id and 64 random bits, ``.tmp``). The name exists before the file does, so an
    interrupt at any moment after the file is created can still remove it by name."""
    path = Path(path)
    return path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(8)}.tmp")


def write_synced(tmp: Path, data: bytes) -> None:
    """Create ``tmp`` (which must not exist) holding ``data``, flushed to disk."""
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    with os.fdopen(fd, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file in the same folder, fsync,
    ``os.replace``). An exception or interrupt (SIGINT, SIGTERM raised as an exception) at any
    point leaves either the previous ``path`` or the new one, and no temporary file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # the name is bound before the file exists: ``tempfile.mkstemp`` creates the file before
    # returning its name, and a signal handled in between left an orphan behind
    tmp = temporary_sibling(path)
    try:
        write_synced(tmp, data)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    return path


def save_figure_atomic(fig, path: str | os.PathLike, **savefig_kwargs) -> Path:
    """A matplotlib figure written atomically as the image format of ``path``'s suffix
    (rendered in memory, then :func:`atomic_write_bytes`); ``savefig_kwargs`` as
    ``Figure.savefig`` (``dpi``, ...)."""
    import io

    path = Path(path)
    buf = io.BytesIO()
    fig.savefig(buf, format=path.suffix.lstrip(".") or "png", **savefig_kwargs)
    return atomic_write_bytes(path, buf.getvalue())


def save_npz_atomic(path: str | os.PathLike, arrays: dict[str, Any], *,
                    compressed: bool = False) -> Path:
    """``arrays`` as an ``.npz`` (``np.savez``, or ``np.savez_compressed``) written atomically
    (built in memory, then :func:`atomic_write_bytes`)."""
    import io

    import numpy as np

    buf = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(buf, **arrays)
    return atomic_write_bytes(path, buf.getvalue())


def save_checkpoint(path: str | os.PathLike, identity: dict[str, Any], state: Any) -> Path:
    """Atomically write ``state`` with its ``identity`` to ``path``."""
    payload = {"format": _FORMAT, "identity": dict(identity), "state": state}
    return atomic_write_bytes(path, pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL))


def load_checkpoint(path: str | os.PathLike, identity: dict[str, Any]) -> Any:
    """The state stored at ``path``, after checking it belongs to ``identity``.

    Raises
    ------
    CheckpointMismatch
        The file records another algorithm, settings, problem or seed (the message names the
        keys and both values), or it is not a checkpoint of this format.
    ValueError
        The file is damaged (cannot be unpickled); the message names the file.
    """
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            payload = pickle.load(fh)
    except Exception as exc:  # any unpickling failure of a damaged or foreign file
        raise ValueError(f"checkpoint {path} is damaged and cannot be read ({exc!r}); delete it "
                         "to start afresh") from None
    if not isinstance(payload, dict) or payload.get("format") != _FORMAT:
        raise CheckpointMismatch(f"{path} is not a checkpoint of this version (format "
                                 f"{_FORMAT}); delete it to start afresh")
    stored = payload["identity"]
    diff = sorted(k for k in set(stored) | set(identity) if stored.get(k) != identity.get(k))
    if diff:
        details = "; ".join(f"{k}: checkpoint {stored.get(k)!r} vs this run {identity.get(k)!r}"
                            for k in diff)
        raise CheckpointMismatch(f"checkpoint {path} belongs to another run ({details}); use "
                                 "another checkpoint path or delete it")
    return payload["state"]
