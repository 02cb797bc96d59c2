"""Tasks that measure and test the executor (:mod:`optimizers.common.executor`).

Module-level and dependency-free, so a spawned process or a Ray worker imports them by name:
``spin`` burns CPU for a given time (a CPU-bound study with a known cost), ``noop`` returns at
once (per-task overhead), ``record`` leaves a completion mark per execution (exactly-once
checks) and ``kill_worker_once`` kills its own worker process the first time it runs (fault
injection: a worker dying in the middle of a study).
"""

from __future__ import annotations

import os
import signal
import time
import uuid
from pathlib import Path

__all__ = ["noop", "spin", "record", "kill_worker_once"]


def noop(x=None):
    """Return ``x`` (the cost of a task is then the executor's alone)."""
    return x


def spin(cpu_s: float, index: int = 0) -> dict:
    """Busy-loop on the CPU for ``cpu_s`` seconds of this process's CPU time.

    Returns ``{"index", "pid", "iterations"}``. CPU time, not wall time: with other processes
    on the cores the work per task stays the same, so throughput ratios measure the executor,
    not the clock.
    """
    t_end = time.process_time() + float(cpu_s)
    n = 0
    acc = 0.0
    while time.process_time() < t_end:
        for i in range(1000):
            acc += i * 1e-9
        n += 1
    return {"index": int(index), "pid": os.getpid(), "iterations": n}


def record(directory: str, index: int, cpu_s: float = 0.0) -> dict:
    """Spin ``cpu_s``, then leave the mark ``<directory>/done_<index>_<uuid>`` (one file per
    completed execution) and return ``{"index", "pid", "square"}``."""
    if cpu_s > 0:
        spin(cpu_s, index)
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    (d / f"done_{int(index):06d}_{uuid.uuid4().hex}").write_text(str(os.getpid()))
    return {"index": int(index), "pid": os.getpid(), "square": int(index) ** 2}


def kill_worker_once(directory: str, index: int, cpu_s: float = 0.0) -> dict:
    """Like :func:`record`, but the first execution (no ``<directory>/killed_<index>`` mark
    yet) leaves that mark and SIGKILLs its own worker process half-way through."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    mark = d / f"killed_{int(index):06d}"
    if not mark.exists():
        if cpu_s > 0:
            spin(cpu_s / 2, index)
        mark.write_text(str(os.getpid()))
        os.kill(os.getpid(), signal.SIGKILL)
    return record(directory, index, cpu_s)
