"""Per-case optima solved along a warm-started chain of start states.

Neighbouring start states have neighbouring optima, so each case is solved from the previous
solved one: :func:`solve_along_chain` orders the states by a nearest-neighbour chain, solves
them in one process (a progress bar per case) or cuts the chain into chunks run as keyed
executor tasks (:func:`optimizers.common.executor.run_chunks`), each chunk a chain of its own
(:func:`solve_warm_chain`). A ``store(key, optimum)`` callback runs in the solving process as
each case is solved, so an interrupted run keeps what it solved.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

__all__ = ["solve_warm_chain", "solve_along_chain"]


def _warm_chain(solve_one: Callable, scenario, states: np.ndarray,
                store: Callable[[Any, Any], None] | None, store_keys: Sequence | None):
    """Yield ``solve_one(scenario, x0, warm)`` for the rows of ``states`` in order, each
    warm-started from the last success (``.success``), after ``store(store_keys[k], optimum)``."""
    warm = None
    for k, x0 in enumerate(states):
        opt = solve_one(scenario, x0, warm)
        if opt.success:
            warm = opt
        if store is not None:
            store(store_keys[k], opt)
        yield opt


def solve_warm_chain(solve_one: Callable, scenario, states: np.ndarray,
                     store: Callable[[Any, Any], None] | None,
                     store_keys: Sequence | None) -> list:
    """Executor task: the optima of the rows of ``states`` solved in order, each warm-started
    from the last success; ``store(store_keys[k], optimum)`` as soon as row k is solved.
    ``solve_one(scenario, x0, warm)`` and ``store`` are module-level functions (they travel
    to worker processes)."""
    return list(_warm_chain(solve_one, scenario, states, store, store_keys))


def solve_along_chain(tag: str, solve_one: Callable, scenario, states: np.ndarray,
                      chain_order: Callable[[np.ndarray], np.ndarray], *,
                      n_workers: int = 1, executor=None, progress: bool = True,
                      desc: str = "per-case optimum",
                      store: Callable[[Any, Any], None] | None = None,
                      store_keys: Sequence | None = None) -> list:
    """The optima of the rows of ``states``, in input order, solved along the chain
    ``chain_order(states)`` (a permutation of the rows, e.g. a nearest-neighbour chain): in
    this process where ``n_workers`` leaves one worker and no ``executor`` is given, else as
    chunks of the chain (four per worker) run as tasks named ``tag``. ``desc`` labels the
    progress bar.

    Raises
    ------
    ValueError
        ``n_workers < 1``, or ``store`` without one key per row.
    """
    if int(n_workers) < 1:
        raise ValueError(f"n_workers = {n_workers!r} must be >= 1")
    n = len(states)
    if store is not None and (store_keys is None or len(store_keys) != n):
        raise ValueError("store needs store_keys with one key per row of states_nd")
    if n == 0:
        return []
    order = chain_order(states)
    keys = list(store_keys) if store is not None else [None] * n
    results: list = [None] * n
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=n, desc=desc, unit="case")

    def _collect(c, opts):
        for i, opt in zip(c, opts, strict=True):
            results[i] = opt
        if bar is not None:
            bar.update(len(c))

    try:
        n_work = min(int(n_workers), max(n // 8, 1))
        if n_work == 1 and executor is None:
            # one case at a time so the bar moves; the warm start carries over
            chain = _warm_chain(solve_one, scenario, states[order], store,
                                [keys[i] for i in order])
            for i, opt in zip(order, chain, strict=True):
                _collect([i], [opt])
        else:
            from .executor import run_chunks

            n_split = max(executor.n_workers if executor is not None else n_work, 1) * 4
            chunks = [c for c in np.array_split(order, min(n_split, n)) if len(c)]
            run_chunks(tag, chunks, solve_warm_chain,
                       lambda c: (solve_one, scenario, states[c], store, [keys[i] for i in c]),
                       executor=executor, n_workers=n_work, on_chunk=_collect)
    finally:
        if bar is not None:
            bar.close()
    return results
