"""One executor for many independent tasks: a local process pool by default, Ray on a cluster.

Four jobs outgrow one process: many-seed optimiser studies (:mod:`optimizers.study`),
certified datasets (:mod:`agents.dataset`), per-case optima of large evaluations
(:mod:`agents.evaluate`) and hyperparameter searches (``train.py --optimize``). They all hand
:func:`run_tasks` a list of :class:`Task` s and an :class:`Executor`:

- :class:`LocalExecutor` (default): a spawned ``concurrent.futures`` process pool with
  ``n_workers`` processes (``n_workers=0`` runs the tasks in this process, for debugging);
- :class:`RayExecutor`: Ray tasks on the cluster at ``address`` (``--address`` or the
  ``RAY_ADDRESS`` environment variable; ``"local"`` starts a private local instance). Ray is an
  optional extra (``pip install -e ".[ray]"``); nothing imports it unless asked.

:func:`get_executor` picks one from the command-line style arguments.

Contract of a task. A :class:`Task` is a *module-level* function and picklable arguments,
keyed by a :class:`TaskKey` ``(problem, seed, index)``. Nothing pickles a closure or a lambda
(:class:`Task` refuses them with a message naming the function): a task is what a spawned
process or a Ray worker on another machine can import and run by name.

Streaming, resume, exactly-once results. :func:`run_tasks` skips the keys its
:class:`ResultStore` already holds, submits the rest, and writes each result atomically
(temporary file, fsync, ``os.replace``) **as it finishes**, before the next one is awaited.
A study killed at any point therefore loses only the tasks in flight, and a rerun with the same
store does only the missing keys. A key is stored at most once (a result that arrives for a key
already stored is dropped, so a task re-run after a worker death cannot duplicate a row).

Faults. A worker process that dies in the middle of a task (killed, out of memory, segfault):

- Ray re-runs the task elsewhere (``max_retries``, system failures only; an exception raised
  *by the task* is not retried and propagates to the caller);
- the local pool, which ``concurrent.futures`` marks broken, is rebuilt and the unfinished tasks
  are resubmitted, at most ``max_retries`` times in a row without progress.

Either way the study completes with every task's result stored exactly once (tested on a real
local Ray cluster in ``tests/optimizers/test_executor.py``).

Verified results. The :class:`~optimizers.common.store.ResultStore` (re-exported here) checks
every result it reads (its key, the store's identity, a checksum, the caller's schema) and
moves a result that fails aside and runs its task again. One process writes a store's
directory at a time (:class:`~optimizers.common.lock.DirectoryLock`), and an interrupted
command stops its workers and keeps what is stored
(:func:`~optimizers.common.cli.clean_interrupts`).
"""

from __future__ import annotations

import os
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

from .store import MISSING, ResultSchema, ResultStore, TaskKey

__all__ = ["TaskKey", "Task", "Executor", "LocalExecutor", "RayExecutor", "ResultStore",
           "ResultSchema", "run_chunks",
           "get_executor", "run_tasks", "check_importable", "RAY_ADDRESS_ENV"]

RAY_ADDRESS_ENV = "RAY_ADDRESS"


def check_importable(fn: Callable) -> Callable:
    """Return ``fn`` if a worker can import it by name, else raise.

    Raises
    ------
    TypeError
        ``fn`` is a lambda, a closure (defined inside a function) or not a plain function /
        class (e.g. a bound method of a local object): the message names it and says what to do.
    """
    qual = getattr(fn, "__qualname__", None)
    mod = getattr(fn, "__module__", None)
    if qual is None or mod is None or not callable(fn):
        raise TypeError(f"task function {fn!r} must be a module-level function (got "
                        f"{type(fn).__name__})")
    if "<lambda>" in qual or "<locals>" in qual:
        raise TypeError(f"task function {mod}.{qual} is a lambda or a closure; executors send "
                        "tasks by name to other processes and machines, so define it at module "
                        "level and pass its data as arguments")
    if mod == "__main__":
        raise TypeError(f"task function {qual} is defined in __main__; spawned workers and Ray "
                        "workers cannot import it: move it into a module")
    return fn


@dataclass(frozen=True)
class Task:
    """``fn(*args, **kwargs)`` under ``key``; ``fn`` module-level, the arguments picklable."""

    key: TaskKey
    fn: Callable
    args: tuple = ()
    kwargs: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.key, TaskKey):
            raise TypeError(f"Task.key = {self.key!r} must be a TaskKey")
        check_importable(self.fn)

    def run(self) -> Any:
        return self.fn(*self.args, **self.kwargs)


def _call(fn: Callable, args: tuple, kwargs: dict) -> Any:
    """What a worker runs (module level, so the pool pickles it by name)."""
    return fn(*args, **kwargs)


# ----------------------------------------------------------------------------- executors


class Executor(ABC):
    """Runs tasks and yields ``(task, result)`` pairs in the order they finish.

    Use as a context manager (``with get_executor(...) as ex:``) or call :meth:`close`.
    """

    n_workers: int
    kind: str

    @abstractmethod
    def imap_unordered(self, tasks: Iterable[Task]) -> Iterator[tuple[Task, Any]]:
        """Run ``tasks``; yield each with its result as soon as it finishes.

        Raises the first exception a task raises (the other tasks are cancelled where possible).
        """

    def close(self) -> None:  # noqa: B027 (an executor without resources needs no close)
        """Release the workers."""

    def terminate(self) -> None:
        """Stop now, without waiting for the tasks in flight (an interrupt); default
        :meth:`close`."""
        self.close()

    def describe(self) -> str:
        return f"{self.kind} ({self.n_workers} workers)"

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class LocalExecutor(Executor):
    """A spawned process pool on this machine (the default executor).

    Parameters
    ----------
    n_workers : int, optional
        Worker processes; default ``os.cpu_count()``. ``0`` runs every task in this process
        (no pickling; for debugging and for tasks too small to ship).
    max_retries : int
        Times the pool is rebuilt after a worker death without any task finishing in between
        (a task that kills its worker every time then fails instead of looping).

    Notes
    -----
    Workers are *spawned*, not forked (numba, torch and CasADi state is not fork-safe); the
    pool starts lazily and is reused across :meth:`imap_unordered` calls until :meth:`close`.
    Spawned workers import the caller's main module: in a script, run under
    ``if __name__ == "__main__":``.
    """

    kind = "local"

    def __init__(self, n_workers: int | None = None, *, max_retries: int = 3) -> None:
        n = (os.cpu_count() or 1) if n_workers is None else n_workers
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise ValueError(f"n_workers = {n_workers!r} must be an int >= 0 (0: in-process)")
        if int(max_retries) < 0:
            raise ValueError(f"max_retries = {max_retries!r} must be >= 0")
        self.n_workers = int(n)
        self.max_retries = int(max_retries)
        self._pool = None
        # worker processes of pools shut down without waiting (after an exception): they may
        # still be finishing a task; terminate() stops them too
        self._released: list = []
        self.n_pool_restarts = 0

    def describe(self) -> str:
        return ("in-process (no workers)" if self.n_workers == 0
                else f"local process pool ({self.n_workers} workers)")

    def _new_pool(self):
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        return ProcessPoolExecutor(max_workers=self.n_workers,
                                   mp_context=mp.get_context("spawn"),
                                   initializer=_init_worker, initargs=(os.getpid(),))

    def imap_unordered(self, tasks: Iterable[Task]) -> Iterator[tuple[Task, Any]]:
        tasks = list(tasks)
        if self.n_workers == 0:
            for t in tasks:
                yield t, t.run()
            return
        from concurrent.futures import FIRST_COMPLETED, wait
        from concurrent.futures.process import BrokenProcessPool

        pending = list(tasks)
        failures_without_progress = 0
        while pending:
            if self._pool is None:
                self._pool = self._new_pool()
            futs = {self._pool.submit(_call, t.fn, t.args, t.kwargs): t for t in pending}
            broken = False
            try:
                while futs:
                    done, _ = wait(list(futs), return_when=FIRST_COMPLETED)
                    for fut in done:
                        t = futs[fut]
                        try:
                            res = fut.result()
                        except BrokenProcessPool:
                            broken = True
                            continue
                        del futs[fut]
                        pending.remove(t)
                        failures_without_progress = 0
                        yield t, res
                    if broken:
                        # results that finished before the pool broke are kept, not re-run
                        for fut in [f for f in futs if f.done() and not f.cancelled()]:
                            if fut.exception() is None:
                                t = futs.pop(fut)
                                pending.remove(t)
                                yield t, fut.result()
                        break
            except BaseException:
                # the futures not started are cancelled by the pool's own thread (shutdown's
                # cancel_futures): cancelling them here as well races with that thread when the
                # workers die at the same time (a SIGTERM to the process group), and Python
                # 3.11's pool then fails on the cancelled futures
                self._shutdown(wait=False)
                raise
            if broken:
                # a worker died mid-task: the pool is unusable; rebuild it and resubmit what
                # has not finished (those tasks never returned, so none is done twice)
                self._shutdown(wait=False)
                self.n_pool_restarts += 1
                failures_without_progress += 1
                if failures_without_progress > self.max_retries:
                    raise RuntimeError(
                        f"a worker process died {failures_without_progress} times in a row "
                        f"without any task finishing ({len(pending)} tasks left, e.g. "
                        f"{pending[0].key}); giving up after max_retries = {self.max_retries}")

    def _shutdown(self, wait: bool = True) -> None:
        if self._pool is not None:
            if not wait:  # the pool forgets its processes on shutdown: keep them
                self._released.append((_workers(self._pool),
                                       getattr(self._pool, "_executor_manager_thread", None)))
            self._pool.shutdown(wait=wait, cancel_futures=True)
            self._pool = None

    def close(self) -> None:
        self._shutdown(wait=True)
        self._released = []

    def terminate(self) -> None:
        """Stop now: kill the worker processes (the tasks in flight are lost; nothing they
        would have returned is stored) and release the pool. The executor stays usable: the
        next :meth:`imap_unordered` starts a new pool."""
        pool, self._pool = self._pool, None
        released, self._released = self._released, []
        procs = [p for ps, _ in released for p in ps] + _workers(pool)
        for p in procs:
            try:
                p.kill()
            except (OSError, ValueError, AttributeError):  # already gone
                pass
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
        # the pools' own threads end once their workers are gone; wait for them here, so the
        # interpreter's exit does not wake a thread that is closing its pipe
        for _, thread in released:
            if thread is not None:
                thread.join(timeout=10.0)
        for p in procs:
            try:
                p.join(timeout=5.0)
            except (OSError, ValueError, AttributeError, AssertionError):
                pass


def _workers(pool) -> list:
    """The worker processes of a ``ProcessPoolExecutor`` (its ``_processes``, there since
    Python 3.2; None once the pool is shut down)."""
    if pool is None:
        return []
    return list((getattr(pool, "_processes", None) or {}).values())


def _init_worker(parent_pid: int) -> None:
    """Initializer of a local pool's workers: end with the parent, even after a SIGKILL of
    the parent (:func:`~optimizers.common.processes.exit_with_parent`: no orphans), and ignore
    SIGINT: a Ctrl-C at a terminal reaches every process of the foreground group, and the
    parent decides what happens (:func:`optimizers.common.cli.clean_interrupts` stops the
    workers and keeps what is stored). A task that wants Ctrl-C itself sets its own
    handler."""
    import signal

    from .processes import exit_with_parent

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    exit_with_parent(parent_pid)


class RayExecutor(Executor):
    """Ray tasks on a cluster (or a private local instance).

    Parameters
    ----------
    address : str, optional
        Cluster address (``"127.0.0.1:6379"``, ``"ray://host:10001"``), ``"auto"`` (the cluster
        this machine belongs to) or ``"local"`` (start a private instance). Default: the
        ``RAY_ADDRESS`` environment variable, else ``"local"``. Ignored when Ray is already
        initialised in this process (that connection is used).
    max_retries : int
        Ray re-runs a task whose worker died this many times (system failures only; an
        exception raised by the task is not retried).
    num_cpus_per_task : float
        CPUs a task reserves (1: one task per core).
    max_in_flight : int, optional
        Tasks submitted ahead of the results (default: 4 per cluster CPU): bounds the object
        store's load for very long task lists.
    init_kwargs :
        Passed to ``ray.init`` (e.g. ``num_cpus`` for a local instance).

    Raises
    ------
    ImportError
        Ray is not installed (the message gives the extra to install).
    """

    kind = "ray"

    def __init__(self, address: str | None = None, *, max_retries: int = 3,
                 num_cpus_per_task: float = 1.0, max_in_flight: int | None = None,
                 **init_kwargs) -> None:
        try:
            import ray
        except ImportError:
            raise ImportError("the Ray executor needs Ray: pip install -e \".[ray]\" (or pip "
                              "install 'ray>=2.9'); without --address the local process pool "
                              "is used") from None
        self._ray = ray
        if int(max_retries) < 0:
            raise ValueError(f"max_retries = {max_retries!r} must be >= 0")
        if not num_cpus_per_task > 0:
            raise ValueError(f"num_cpus_per_task = {num_cpus_per_task!r} must be > 0")
        self.address = address or os.environ.get(RAY_ADDRESS_ENV) or "local"
        self._owns = False
        if not ray.is_initialized():
            kw = dict(include_dashboard=False, log_to_driver=True, logging_level="WARNING")
            kw.update(init_kwargs)
            ray.init(address=self.address, **kw)  # Ray's "local": a new instance
            self._owns = True
        self.n_workers = max(1, int(ray.cluster_resources().get("CPU", 1) // num_cpus_per_task))
        self.max_in_flight = int(max_in_flight or 4 * self.n_workers)
        self._remote = ray.remote(_call).options(max_retries=int(max_retries),
                                                  num_cpus=num_cpus_per_task,
                                                  retry_exceptions=False)

    def describe(self) -> str:
        return f"Ray at {self.address} ({self.n_workers} CPUs)"

    def imap_unordered(self, tasks: Iterable[Task]) -> Iterator[tuple[Task, Any]]:
        ray = self._ray
        todo = list(tasks)[::-1]
        refs: dict = {}
        try:
            while todo or refs:
                while todo and len(refs) < self.max_in_flight:
                    t = todo.pop()
                    refs[self._remote.remote(t.fn, t.args, t.kwargs)] = t
                ready, _ = ray.wait(list(refs), num_returns=1)
                for ref in ready:
                    t = refs.pop(ref)
                    try:
                        res = ray.get(ref)
                    except ray.exceptions.RayTaskError as exc:
                        cause = exc.cause if getattr(exc, "cause", None) is not None else exc
                        raise cause from None
                    yield t, res
        finally:
            for ref in refs:
                try:
                    ray.cancel(ref)
                except Exception:  # noqa: BLE001 (best effort on the way out)
                    pass

    def terminate(self) -> None:
        """Stop now (cancel what is in flight, disconnect): as :meth:`close`."""
        self.close()

    def close(self) -> None:
        if self._owns and self._ray.is_initialized():
            self._ray.shutdown()
        self._owns = False


def get_executor(address: str | None = None, n_workers: int | None = None, **kwargs
                 ) -> Executor:
    """The executor a command line asks for.

    ``address`` (``--address``) or the ``RAY_ADDRESS`` environment variable selects
    :class:`RayExecutor`; otherwise :class:`LocalExecutor` with ``n_workers`` processes
    (``--workers``; default all cores, 0 in-process). ``address="local"`` starts a private Ray
    instance on this machine (with ``num_cpus=n_workers`` when given).

    Raises
    ------
    ValueError
        The address is none of ``local``, ``auto``, ``host:port`` (port 1–65535) or
        ``ray://…`` (checked before Ray is imported or contacted).
    """
    source = "--address"
    if not address and os.environ.get(RAY_ADDRESS_ENV):
        address, source = os.environ[RAY_ADDRESS_ENV], f"${RAY_ADDRESS_ENV}"
    if address:
        _check_ray_address(address, source)
        if address == "local" and n_workers:
            kwargs.setdefault("num_cpus", int(n_workers))
        return RayExecutor(address, **kwargs)
    return LocalExecutor(n_workers, **{k: v for k, v in kwargs.items() if k == "max_retries"})


def _check_ray_address(address: str, source: str) -> None:
    if address in ("local", "auto") or address.startswith("ray://"):
        return
    host, sep, port = address.rpartition(":")
    if sep and host and port.isdigit() and 0 < int(port) < 65536:
        return
    raise ValueError(f"{source} = {address!r} is not a Ray address: use 'local' (a private "
                     "instance on this machine), 'auto' (the cluster this machine belongs to), "
                     "'host:port' or 'ray://host:port'; without an address the local process "
                     "pool is used")


# ----------------------------------------------------------------------------- results
# ResultStore lives in optimizers.common.store (verified results on disk); re-exported here.


@dataclass
class RunReport:
    """What :func:`run_tasks` did: ``skipped`` (already stored), ``done`` (run now), wall time."""

    n_tasks: int
    n_skipped: int
    n_done: int
    wall_s: float
    executor: str


def run_tasks(tasks: Iterable[Task], executor: Executor | None = None,
              store: ResultStore | None = None, *, on_result: Callable | None = None,
              is_done: Callable[[TaskKey], bool] | None = None, progress: bool | str = False,
              max_tasks: int | None = None) -> tuple[dict[TaskKey, Any], RunReport]:
    """Run ``tasks`` on ``executor``, streaming each result to ``store`` as it finishes.

    Parameters
    ----------
    tasks : iterable of Task
        Keys must be unique.
    executor : Executor, optional
        Default: ``LocalExecutor(0)`` (this process).
    store : ResultStore, optional
        Keys already in it are skipped (resume) and new results are written to it atomically,
        one by one, as they arrive; a damaged stored file is moved aside and its task run
        again (:meth:`ResultStore.readable`).
    on_result : callable, optional
        ``on_result(task, result)`` after the result is stored (progress, timing; runs in this
        process).
    is_done : callable, optional
        ``is_done(key) -> bool``: extra resume test for callers with their own files.
    progress : bool or str
        A tqdm bar (a string is its description).
    max_tasks : int, optional
        Submit at most this many of the missing tasks (simulates an interruption in tests).

    Returns
    -------
    results : dict TaskKey -> result
        Every task's result: stored ones read back from ``store``, new ones as returned (tasks
        skipped by ``is_done`` only are absent).
    report : RunReport

    Raises
    ------
    ValueError
        Duplicate keys.
    Exception
        The first exception a task raised (results finished before it are stored).
    """
    tasks = list(tasks)
    keys = [t.key for t in tasks]
    if len(set(keys)) != len(keys):
        dup = sorted({k for k in keys if keys.count(k) > 1})[:3]
        raise ValueError(f"task keys must be unique; duplicated: {dup}")
    own = executor is None
    executor = executor or LocalExecutor(0)
    results: dict[TaskKey, Any] = {}
    todo = []
    for t in tasks:
        stored = MISSING if store is None else store.load(t.key)
        if stored is not MISSING:
            results[t.key] = stored
        elif is_done is not None and is_done(t.key):
            continue
        else:
            todo.append(t)
    n_skipped = len(tasks) - len(todo)
    if max_tasks is not None:
        todo = todo[:int(max_tasks)]
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(tasks), initial=n_skipped, unit="task",
                   desc=progress if isinstance(progress, str) else executor.describe())
    t0 = time.perf_counter()
    n_done = 0
    try:
        for task, res in executor.imap_unordered(todo):
            if task.key in results:  # a re-run after a worker death: keep the first result
                continue
            if store is not None:
                store.put(task.key, res)
            results[task.key] = res
            n_done += 1
            if on_result is not None:
                on_result(task, res)
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
        if own:
            executor.close()
    wall = time.perf_counter() - t0
    return results, RunReport(len(tasks), n_skipped, n_done, wall, executor.describe())


def run_chunks(name: str, chunks: list, fn: Callable, args_of: Callable, *,
               executor: Executor | None = None, n_workers: int = 1,
               on_chunk: Callable | None = None) -> None:
    """Run ``fn(*args_of(chunk))`` for every chunk as keyed tasks ``(name, 0, k)``.

    The batch solvers (per-case optima along a warm-started chain) split their cases into chunks
    and hand them here; each chunk's result reaches ``on_chunk(chunk, result)`` as it arrives.

    Parameters
    ----------
    name : str
        Problem part of the task keys.
    chunks : list of index arrays
    fn : module-level callable
    args_of : callable
        ``args_of(chunk) -> tuple`` of ``fn``'s positional arguments.
    executor : Executor, optional
        Default: a ``LocalExecutor(n_workers)`` made here and closed afterwards.
    """
    tasks = [Task(TaskKey(name, 0, k), fn, tuple(args_of(c))) for k, c in enumerate(chunks)]

    def _collect(task, result):
        if on_chunk is not None:
            on_chunk(chunks[task.key.index], result)

    ex = executor if executor is not None else LocalExecutor(n_workers)
    try:
        run_tasks(tasks, ex, on_result=_collect)
    finally:
        if executor is None:
            ex.close()

