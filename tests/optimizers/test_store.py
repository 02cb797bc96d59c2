"""The result store verifies what it reads: each result's key, the store's identity, a checksum
of the payload and the caller's schema; damaged results are named, moved aside and run again;
a store whose identity is lost refuses to open (optimizers.common.store)."""

from __future__ import annotations

import json
import pickle
import shutil
import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from optimizers.common import probe_tasks as pt
from optimizers.common.executor import LocalExecutor, Task, TaskKey, run_tasks
from optimizers.common.store import (
    MISSING,
    DamagedResult,
    ResultSchema,
    ResultStore,
    StoreIdentityError,
    identity_fingerprint,
)

FORMATS = ("json", "pickle", "npz")
CHUNK = 4


def _chunk_value(k: int, fmt: str):
    """A campaign-like chunk result: the cases the chunk covers and per-case lists."""
    cases = list(range(CHUNK * k, CHUNK * k + CHUNK))
    value = {"case": cases, "fuel_kg": [300.0 + c / 7 for c in cases],
             "success": [c % 3 != 0 for c in cases]}
    return {f: np.asarray(v) for f, v in value.items()} if fmt == "npz" else value


def _chunk_task(k: int, fmt: str) -> dict:
    return _chunk_value(k, fmt)


def _expected_cases(key: TaskKey) -> dict:
    return {"case": list(range(CHUNK * key.index, CHUNK * key.index + CHUNK))}


SCHEMA = ResultSchema(required=("case", "fuel_kg", "success"),
                      same_length=("case", "fuel_kg", "success"), expected=_expected_cases)


def _key(k: int) -> TaskKey:
    return TaskKey("chunk", 3, k)


def _equal(a, b) -> bool:
    if isinstance(a, dict):
        return set(a) == set(b) and all(np.array_equal(a[f], b[f]) for f in a)
    return a == b


# --------------------------------------------------------------------------- the envelope


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_chunk_copied_over_another_chunks_file_is_refused(tmp_path, capsys, fmt):
    """Copying one chunk's result file over another key's file was accepted: the results of
    cases 0-3 were then read as those of cases 4-7. Now the key in the envelope is checked."""
    store = ResultStore(tmp_path, {"campaign": 1}, fmt=fmt)
    for k in (0, 1):
        store.put(_key(k), _chunk_value(k, fmt))
    shutil.copyfile(store.path(_key(0)), store.path(_key(1)))
    with pytest.raises(DamagedResult, match=r"holds the result of key \('chunk', 3, 0\), not "
                                             r"of \('chunk', 3, 1\)"):
        store.get(_key(1))
    res, rep = run_tasks([Task(_key(k), _chunk_task, (k, fmt)) for k in (0, 1)],
                         LocalExecutor(0), store)
    assert (rep.n_skipped, rep.n_done) == (1, 1)  # chunk 1 moved aside and flown again
    assert "holds the result of key" in capsys.readouterr().out
    assert store.path(_key(1)).with_name(store.path(_key(1)).name + ".damaged").exists()
    assert _equal(store.get(_key(1)), _chunk_value(1, fmt))


@pytest.mark.parametrize("fmt", FORMATS)
def test_every_result_carries_key_store_and_checksum(tmp_path, fmt):
    store = ResultStore(tmp_path, {"study": "x"}, fmt=fmt)
    store.put(_key(2), _chunk_value(2, fmt))
    raw = store.path(_key(2)).read_bytes()
    if fmt == "json":  # one JSON document, readable with any JSON tool
        doc = json.loads(raw)
        head, value = doc["store"], doc["value"]
        assert value == _chunk_value(2, fmt)
    elif fmt == "pickle":
        head = json.loads(raw.split(b"\n", 1)[0].split(b" ", 1)[1])
    else:  # an ordinary npz: the header is one more member
        with np.load(store.path(_key(2))) as z:
            head = json.loads(str(z["__store__"]))
            np.testing.assert_array_equal(z["case"], [8, 9, 10, 11])
    assert head["key"] == ["chunk", 3, 2]
    assert head["store"] == identity_fingerprint({"study": "x"}) == store.fingerprint
    assert len(head["sha256"]) == 64 and head["format"] == 1


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_result_of_another_store_is_refused(tmp_path, fmt):
    """Same key, other settings: the fingerprint of the store's identity differs."""
    a = ResultStore(tmp_path / "a", {"seed": 1}, fmt=fmt)
    b = ResultStore(tmp_path / "b", {"seed": 2}, fmt=fmt)
    a.put(_key(0), _chunk_value(0, fmt))
    shutil.copyfile(a.path(_key(0)), b.path(_key(0)))
    with pytest.raises(DamagedResult, match="belongs to another store"):
        b.get(_key(0))


@pytest.mark.parametrize("fmt", FORMATS)
def test_an_edited_value_fails_its_checksum(tmp_path, fmt):
    store = ResultStore(tmp_path, fmt=fmt)
    path = store.put(_key(0), _chunk_value(0, fmt))
    if fmt == "npz":
        with np.load(path) as z:
            arrays = {f: z[f] for f in z.files}
        arrays["fuel_kg"] = arrays["fuel_kg"] + 1.0
        np.savez_compressed(path, **arrays)
    else:
        raw = path.read_bytes()
        old, new = ((b"300.0", b"301.0") if fmt == "json"  # a float as pickle writes it:
                    else (struct.pack(">d", 300.0), struct.pack(">d", 301.0)))
        assert old in raw
        path.write_bytes(raw.replace(old, new, 1))
    with pytest.raises(DamagedResult, match="checksum mismatch"):
        store.get(_key(0))


@pytest.mark.parametrize("fmt", FORMATS)
def test_old_format_files_count_as_damaged(tmp_path, fmt):
    """A result written without an envelope (the format before it) is run again."""
    store = ResultStore(tmp_path, fmt=fmt)
    value = _chunk_value(0, fmt)
    path = store.path(_key(0))
    if fmt == "json":
        path.write_text(json.dumps(value))
    elif fmt == "pickle":
        path.write_bytes(pickle.dumps(value))
    else:
        np.savez_compressed(path, **value)
    with pytest.raises(DamagedResult, match="no integrity envelope"):
        store.get(_key(0))
    assert store.load(_key(0)) is MISSING
    assert path.with_name(path.name + ".damaged").exists()


def test_a_pickle_from_elsewhere_is_never_unpickled(tmp_path):
    """The pickle store checks the header before unpickling anything."""
    store = ResultStore(tmp_path, fmt="pickle")
    bomb = tmp_path / "unpickled"
    path = store.path(_key(0))
    path.write_bytes(pickle.dumps(_Bomb(str(bomb))))
    with pytest.raises(DamagedResult, match="no integrity envelope"):
        store.get(_key(0))
    assert not bomb.exists()


class _Bomb:
    def __init__(self, path: str) -> None:
        self.path = path

    def __reduce__(self):
        return (open, (self.path, "w"))


@pytest.mark.parametrize("fmt", FORMATS)
def test_schema_checks_the_cases_a_key_names(tmp_path, capsys, fmt):
    """A chunk whose case list is not the chunk its key names, lists of unequal length, a
    missing field: each is damaged (named, moved aside, flown again)."""
    store = ResultStore(tmp_path, {"campaign": 2}, fmt=fmt, schema=SCHEMA)
    bad = {
        0: _chunk_value(1, fmt),  # chunk 1's cases under key 0 (a consistent envelope)
        1: {**_chunk_value(1, fmt), "fuel_kg": np.arange(3.0) if fmt == "npz" else [1.0] * 3},
        2: {k: v for k, v in _chunk_value(2, fmt).items() if k != "success"},
    }
    for k, v in bad.items():
        store.put(_key(k), v)
    messages = {0: r"field 'case' = \[4, 5, 6, 7\] is not \[0, 1, 2, 3\]",
                1: "per-item fields of different lengths: case 4, fuel_kg 3",
                2: r"lacks the field\(s\) \['success'\]"}
    for k, msg in messages.items():
        with pytest.raises(DamagedResult, match=msg):
            store.get(_key(k))
    res, rep = run_tasks([Task(_key(k), _chunk_task, (k, fmt)) for k in range(3)],
                         LocalExecutor(0), store)
    assert rep.n_done == 3
    assert all(_equal(res[_key(k)], _chunk_value(k, fmt)) for k in range(3))
    assert len(list((tmp_path / "results").glob("*.damaged"))) == 3


# --------------------------------------------------------------------------- the identity


def test_identity_is_created_once_and_compared(tmp_path):
    ResultStore(tmp_path, {"algorithm": "ASAGA", "n": 1})
    assert json.loads((tmp_path / "identity.json").read_text()) == {"algorithm": "ASAGA", "n": 1}
    assert not list(tmp_path.glob(".identity.json.*"))  # no temporary left
    with pytest.raises(StoreIdentityError, match="algorithm: stored 'ASAGA' vs 'GA'"):
        ResultStore(tmp_path, {"algorithm": "GA", "n": 1})
    ResultStore(tmp_path, {"n": 1, "algorithm": "ASAGA"})  # same identity, any key order


@pytest.mark.parametrize("damage", ["deleted", "unreadable"])
def test_a_store_with_results_but_no_identity_refuses_to_open(tmp_path, damage):
    """With identity.json deleted, a resume with other settings adopted the new settings and
    mixed their results with the stored ones; now such a directory refuses to open."""
    store = ResultStore(tmp_path, {"seed": 1})
    store.put(_key(0), {"x": 1})
    ident = tmp_path / "identity.json"
    if damage == "deleted":
        ident.unlink()
    else:
        ident.write_text('{"seed": ')
    for identity in ({"seed": 2}, {"seed": 1}):
        with pytest.raises(StoreIdentityError) as info:
            ResultStore(tmp_path, identity)
        msg = str(info.value)
        assert "\n" not in msg and "holds 1 stored result(s)" in msg
        assert ("is missing" if damage == "deleted" else "is unreadable") in msg
    assert not ident.exists() or ident.read_text() == '{"seed": '  # nothing adopted


def test_an_existing_store_opens_under_its_recorded_identity(tmp_path):
    ResultStore(tmp_path, {"seed": 5}).put(_key(0), {"x": 1})
    reader = ResultStore.existing(tmp_path)
    assert reader.identity == {"seed": 5} and reader.get(_key(0)) == {"x": 1}
    with pytest.raises(StoreIdentityError, match="no.*readable identity.json|not a result"):
        ResultStore.existing(tmp_path / "nothing")


def test_an_empty_store_with_an_unreadable_identity_starts_afresh(tmp_path):
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "x.json.damaged").write_text("{")
    (tmp_path / "identity.json").write_text("{")
    store = ResultStore(tmp_path, {"seed": 3})
    assert json.loads((tmp_path / "identity.json").read_text()) == {"seed": 3}
    assert store.keys() == []


# --------------------------------------------------------------------------- random damage


def _store_with_chunks(directory, fmt, n=3):
    store = ResultStore(directory, {"campaign": "damage", "fmt": fmt}, fmt=fmt, schema=SCHEMA)
    for k in range(n):
        store.put(_key(k), _chunk_value(k, fmt))
    return store


_damage = st.lists(st.tuples(
    st.sampled_from(["truncate", "swap", "flip", "edit_field", "delete_identity",
                     "foreign", "garbage", "nothing"]),
    st.integers(0, 2), st.integers(0, 2), st.floats(0.0, 1.0)), min_size=1, max_size=3)


@pytest.mark.parametrize("fmt", FORMATS)
def test_random_store_damage_is_detected_or_harmless(tmp_path_factory, fmt):
    """Truncations, swapped files, flipped bytes, edited fields, files of another store, a
    deleted identity: after any of them a resume either refuses to open (the identity is
    gone), or ends with exactly the results of an undamaged run, every damaged file moved
    aside and its task run again."""
    reference = {k: _chunk_value(k, fmt) for k in range(3)}

    @settings(max_examples=40, deadline=None, derandomize=True,
              suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(_damage)
    def one(damage):
        d = tmp_path_factory.mktemp("store")
        store = _store_with_chunks(d, fmt)
        before = {k: store.path(_key(k)).read_bytes() for k in range(3)}
        identity_lost = False
        for what, i, j, frac in damage:
            pi, pj = store.path(_key(i)), store.path(_key(j))
            if what == "truncate" and pi.exists():
                pi.write_bytes(pi.read_bytes()[:int(frac * pi.stat().st_size)])
            elif what == "swap" and pi.exists() and pj.exists():
                a, b = pi.read_bytes(), pj.read_bytes()
                pi.write_bytes(b)
                pj.write_bytes(a)
            elif what == "flip" and pi.exists() and pi.stat().st_size:
                raw = bytearray(pi.read_bytes())
                raw[int(frac * (len(raw) - 1))] ^= 0x01 << (j + 1)
                pi.write_bytes(bytes(raw))
            elif what == "edit_field":
                _edit_field(store, _key(i), frac)
            elif what == "delete_identity":
                (d / "identity.json").unlink(missing_ok=True)
                identity_lost = True
            elif what == "foreign":
                other = ResultStore(tmp_path_factory.mktemp("other"), {"campaign": "other"},
                                    fmt=fmt)
                shutil.copyfile(other.put(_key(i), _chunk_value(i, fmt)), pi)
            elif what == "garbage":
                pi.write_bytes(bytes(range(256)) * (1 + j))
        changed = {k for k in range(3) if not store.path(_key(k)).exists()
                   or store.path(_key(k)).read_bytes() != before[k]}
        if identity_lost:
            with pytest.raises(StoreIdentityError, match="identity.json is missing"):
                _store_with_chunks(d, fmt, n=0)
            return
        again = ResultStore(d, {"campaign": "damage", "fmt": fmt}, fmt=fmt, schema=SCHEMA)
        res, rep = run_tasks([Task(_key(k), _chunk_task, (k, fmt)) for k in range(3)],
                             LocalExecutor(0), again)
        # identical: every result read back or re-run equals the undamaged run's
        assert all(_equal(res[_key(k)], reference[k]) for k in range(3)), damage
        assert all(_equal(again.get(_key(k)), reference[k]) for k in range(3)), damage
        # detected: each damaged file was moved aside and its task run again; a file whose
        # bytes changed without changing what it holds (a zip timestamp) may be read back,
        # and an untouched file always is
        aside = {k for k in range(3) if again.path(_key(k)).with_name(
            again.path(_key(k)).name + ".damaged").exists()}
        assert rep.n_done == len(aside) and aside <= changed, (damage, changed, aside)
        if fmt != "npz":  # JSON and pickle have no bytes outside the verified ones
            assert aside == changed, (damage, changed, aside)

    one()


def _edit_field(store: ResultStore, key: TaskKey, frac: float) -> None:
    """Change one value inside the payload and write the file back in its own format (the
    envelope left as it was)."""
    path = store.path(key)
    if not path.exists():
        return
    try:
        if store.fmt == "json":
            doc = json.loads(path.read_bytes())
            doc["value"]["fuel_kg"][0] += 1.0 + frac
            path.write_text(json.dumps(doc))
        elif store.fmt == "pickle":
            head, payload = path.read_bytes().split(b"\n", 1)
            value = pickle.loads(payload)
            value["fuel_kg"][0] += 1.0 + frac
            path.write_bytes(head + b"\n" + pickle.dumps(value))
        else:
            with np.load(path) as z:
                arrays = {f: z[f] for f in z.files}
            arrays["fuel_kg"] = arrays["fuel_kg"] + 1.0 + frac
            with open(path, "wb") as fh:
                np.savez_compressed(fh, **arrays)
    except Exception:  # noqa: BLE001  (an already damaged file: nothing to edit)
        return


def test_store_probe_tasks_still_round_trip(tmp_path):
    """The executor's probe tasks through a verified store (in-process), resumed."""
    store = ResultStore(tmp_path, {"probe": 1})
    tasks = [Task(TaskKey("p", 0, i), pt.noop, ({"i": i},)) for i in range(3)]
    run_tasks(tasks, LocalExecutor(0), store, max_tasks=2)
    res, rep = run_tasks(tasks, LocalExecutor(0), store)
    assert (rep.n_skipped, rep.n_done) == (2, 1)
    assert {k.index: v["i"] for k, v in res.items()} == {0: 0, 1: 1, 2: 2}
