"""One writer per directory (optimizers.common.lock.DirectoryLock), across real processes."""

from __future__ import annotations

import time

import pytest
from proc_helpers import python, wait_for

from optimizers.common.lock import DirectoryBusy, DirectoryLock

_HOLD = """
    import sys, time
    from pathlib import Path
    from optimizers.common.lock import DirectoryLock

    with DirectoryLock(sys.argv[1], what="study"):
        Path(sys.argv[2]).write_text("held")
        time.sleep(float(sys.argv[3]))
    print("released", flush=True)
"""


def _holder(tmp_path, hold_s: float):
    ready = tmp_path / "ready"
    proc = python(_HOLD, str(tmp_path / "study"), str(ready), str(hold_s))
    wait_for(ready.exists, 120, proc)
    return proc


def test_a_second_process_is_refused_at_once_naming_the_holder(tmp_path):
    proc = _holder(tmp_path, 60.0)
    try:
        t0 = time.monotonic()
        with pytest.raises(DirectoryBusy) as info:
            DirectoryLock(tmp_path / "study", what="study").acquire()
        assert time.monotonic() - t0 < 2.0  # at once, not after a wait
        assert info.value.pid == proc.pid
        msg = str(info.value)
        assert f"is in use by process {proc.pid}" in msg and "\n" not in msg
        assert str(tmp_path / "study") in msg
    finally:
        proc.kill()
        proc.wait()
    # the kernel released the lock with the killed holder: the directory is free again
    with DirectoryLock(tmp_path / "study") as lock:
        assert lock.held and lock.holder_pid() != proc.pid


def test_wait_true_waits_for_the_holder(tmp_path):
    proc = _holder(tmp_path, 1.5)
    try:
        with pytest.raises(DirectoryBusy, match=r"waited 0\.2 s"):
            DirectoryLock(tmp_path / "study", wait=True, timeout_s=0.2).acquire()
        t0 = time.monotonic()
        with DirectoryLock(tmp_path / "study", wait=True, timeout_s=60):
            waited = time.monotonic() - t0
        assert 0.3 < waited < 30
        assert proc.wait(timeout=60) == 0 and b"released" in proc.stdout.read()
    finally:
        proc.kill()
        proc.wait()


def test_the_lock_is_reentrant_within_a_process(tmp_path):
    outer = DirectoryLock(tmp_path).acquire()
    with DirectoryLock(tmp_path) as inner:  # e.g. a command, then the library it calls
        assert inner.held
    assert outer.held
    outer.release()
    assert not outer.held
    with pytest.raises(ValueError, match="timeout_s"):
        DirectoryLock(tmp_path, timeout_s=-1)
