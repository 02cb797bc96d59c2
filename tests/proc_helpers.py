"""Helpers of the kill-and-resume and concurrency tests: child Python processes, waiting, the
process tree, and the seeded kill point (``LUNAR_KILL_SEED`` replays a failed default-run kill).

Imported as ``proc_helpers`` (the directory of ``tests/conftest.py`` is on ``sys.path``).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from contextlib import contextmanager
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
KILL_SEED_ENV = "LUNAR_KILL_SEED"


def python(code: str, *args: str, **kw) -> subprocess.Popen:
    """``python -c code args`` from the repository root, output piped (stderr merged)."""
    env = dict(os.environ, PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1")
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(code), *args], cwd=REPO,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, **kw)


def wait_for(pred, timeout_s: float, proc: subprocess.Popen | None = None) -> None:
    t0 = time.monotonic()
    while not pred():
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"process ended early:\n{proc.stdout.read().decode()[-3000:]}")
        if time.monotonic() - t0 > timeout_s:
            raise AssertionError("timed out")
        time.sleep(0.05)


def sigkill_when(proc: subprocess.Popen, ready, delay_s: float, timeout_s: float = 300,
                 before_kill=None) -> None:
    """Wait until ``ready()`` (failing if ``proc`` ends first), sleep ``delay_s``, call
    ``before_kill()`` if given, SIGKILL ``proc``; the process is always reaped."""
    try:
        wait_for(ready, timeout_s, proc)
        time.sleep(delay_s)
        if before_kill is not None:
            before_kill()
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()


def children(pid: int) -> list[int]:
    """Every descendant pid of ``pid`` (Linux /proc)."""
    kids = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            if ppid == pid:
                kids.append(int(d.name))
    return kids + [g for k in kids for g in children(k)]


def alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def kill_seed(default: int) -> int:
    """The seed of a default-run kill point: fixed, or ``LUNAR_KILL_SEED`` to replay another."""
    return int(os.environ.get(KILL_SEED_ENV, default))


def kill_point(what: str, seed: int, delay_s: float) -> str:
    """Print (shown with a failure's captured output) and return the kill point's description."""
    msg = (f"kill point: SIGKILL {delay_s:.3f} s after {what} (seed {seed}; replay with "
           f"{KILL_SEED_ENV}={seed})")
    print(msg)
    return msg


@contextmanager
def noted(msg: str):
    """Add ``msg`` to any exception (an assertion) raised in the block: the kill point."""
    try:
        yield
    except BaseException as exc:
        exc.add_note(msg)
        raise
