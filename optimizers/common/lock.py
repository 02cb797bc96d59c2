"""One writer per directory: an advisory lock on a lock file (:class:`DirectoryLock`).

A study, a campaign or a dataset directory is written by one process at a time: two runs of
the same command in the same directory would both find the same tasks missing, run them twice
and interleave their summaries. :class:`DirectoryLock` holds ``fcntl.flock`` on
``<directory>/.lock`` with the holder's PID written in it; a second process refuses at once
with a message naming that PID (:class:`DirectoryBusy`), or waits (``wait=True``).

The lock is the kernel's: it ends with the process holding it, however that process ends
(SIGKILL included), so a lock file left behind never blocks anyone; the PID in it is only for
the message. It is advisory: readers need none, and only code that takes it is kept out.
Within one process the lock is re-entrant (a command that holds it can call a library function
that takes it too). POSIX only (``fcntl``).

::

    with DirectoryLock(out):          # DirectoryBusy if another process writes there
        store = ResultStore(out, identity)
        run_tasks(tasks, executor, store)
"""

from __future__ import annotations

import os
import time
from pathlib import Path

__all__ = ["DirectoryLock", "DirectoryBusy", "LOCK_NAME"]

#: the lock file's name inside the locked directory
LOCK_NAME = ".lock"

# lock files held by this process: real path -> [open file, depth]
_HELD: dict[str, list] = {}


class DirectoryBusy(RuntimeError):
    """Another process holds the directory's lock (its PID is in the message and in ``pid``)."""

    def __init__(self, message: str, pid: int | None = None) -> None:
        super().__init__(message)
        self.pid = pid


class DirectoryLock:
    """Exclusive advisory lock on ``directory`` (created if needed), as a context manager.

    Parameters
    ----------
    directory : path
    wait : bool
        False (default): a directory locked by another process raises :class:`DirectoryBusy`
        at once. True: wait until the holder releases it (or ``timeout_s`` passes).
    timeout_s : float, optional
        Longest wait with ``wait=True`` (default: no limit); then :class:`DirectoryBusy`.
    what : str
        What the directory holds, for the message (``"study"``, ``"campaign"``, ...).

    Raises
    ------
    DirectoryBusy
        (a RuntimeError) on :meth:`acquire` / ``with``: another process holds the lock; the
        message names its PID and the directory.
    """

    def __init__(self, directory: str | os.PathLike, *, wait: bool = False,
                 timeout_s: float | None = None, what: str = "directory") -> None:
        if timeout_s is not None and not timeout_s >= 0:
            raise ValueError(f"timeout_s = {timeout_s!r} must be >= 0 (or None: no limit)")
        self.directory = Path(directory)
        self.wait = bool(wait)
        self.timeout_s = timeout_s
        self.what = what
        self._key: str | None = None

    @property
    def path(self) -> Path:
        """The lock file."""
        return self.directory / LOCK_NAME

    @property
    def held(self) -> bool:
        """True while this object holds the lock."""
        return self._key is not None

    def holder_pid(self) -> int | None:
        """PID written in the lock file (the last holder's; None if unreadable)."""
        try:
            text = self.path.read_text().strip()
            return int(text.split()[0]) if text else None
        except (OSError, ValueError, IndexError):
            return None

    def acquire(self) -> DirectoryLock:
        """Take the lock (see the class docstring); returns self."""
        import fcntl

        if self._key is not None:
            raise RuntimeError(f"this DirectoryLock on {self.directory} is already held")
        self.directory.mkdir(parents=True, exist_ok=True)
        key = os.path.realpath(self.path)
        held = _HELD.get(key)
        if held is not None:  # re-entrant within this process
            held[1] += 1
            self._key = key
            return self
        fh = open(self.path, "a+")  # never truncated before the lock is ours
        try:
            t_end = None if self.timeout_s is None else time.monotonic() + self.timeout_s
            while True:
                try:
                    fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
                    break
                except BlockingIOError:
                    if not self.wait or (t_end is not None and time.monotonic() >= t_end):
                        raise self._busy() from None
                    time.sleep(0.05)
            fh.seek(0)
            fh.truncate()
            fh.write(f"{os.getpid()}\n")
            fh.flush()
            os.fsync(fh.fileno())
        except BaseException:
            fh.close()
            raise
        _HELD[key] = [fh, 1]
        self._key = key
        return self

    def _busy(self) -> DirectoryBusy:
        pid = None
        for _ in range(20):  # the holder writes its PID just after taking the lock
            pid = self.holder_pid()
            if pid is not None:
                break
            time.sleep(0.01)
        who = f"process {pid}" if pid is not None else "another process"
        waited = "" if not self.wait else f" (waited {self.timeout_s:g} s)"
        return DirectoryBusy(
            f"{self.what} {self.directory} is in use by {who}{waited}: one writer per "
            f"directory; wait for it to finish (or stop it), or use another directory", pid)

    def release(self) -> None:
        """Release the lock (the lock file stays; its PID is no longer meaningful)."""
        import fcntl

        key, self._key = self._key, None
        if key is None:
            return
        held = _HELD[key]
        held[1] -= 1
        if held[1] > 0:
            return
        del _HELD[key]
        fh = held[0]
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)
        finally:
            fh.close()

    def __enter__(self) -> DirectoryLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()

    def __repr__(self) -> str:
        return f"DirectoryLock({str(self.directory)!r}, held={self.held})"
