"""Worker processes that do not outlive their parent.

A ``ProcessPoolExecutor`` worker is not told when its parent is SIGKILLed: it finishes its task
and then waits for the next one for ever (without this, ``agents.dataset`` workers keep running
after a kill). :func:`exit_with_parent`, used as the pool's initializer, starts a daemon thread
in each worker that ends the worker within ``period_s`` of the parent's death.
"""

from __future__ import annotations

import os
import threading
import time

__all__ = ["exit_with_parent"]


def _watch_parent(parent_pid: int, period_s: float) -> None:
    while True:
        if os.getppid() != parent_pid:
            os._exit(1)  # the parent died (re-parented to init or a subreaper): stop now
        time.sleep(period_s)


def exit_with_parent(parent_pid: int, period_s: float = 0.5) -> None:
    """Pool initializer: end this worker when process ``parent_pid`` (its parent) ends.

    Use as ``ProcessPoolExecutor(..., initializer=exit_with_parent, initargs=(os.getpid(),))``.
    """
    if os.getppid() != int(parent_pid):
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(int(parent_pid), float(period_s)),
                     daemon=True, name="exit-with-parent").start()
