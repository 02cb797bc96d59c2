"""Many Pontryagin solves: a dispersion of initial states, warm-started along a chain.

:func:`solve_many` orders the initial states by :func:`nearest_neighbour_order` and solves each
from its neighbour's extremal (:func:`optimizers.indirect.planar.solve_planar_min_fuel`), in
this process or on an executor (:mod:`optimizers.common.executor`: a spawned local pool, or
Ray) over chunks of the chain.
"""

from __future__ import annotations

import numpy as np

from lunar_env import dynamics as dyn
from lunar_env.scenarios import PlanarScenario
from lunar_env.states import check_planar_states_si

from ..problems.planar_ocp import PlanarOCP, as_planar_ocp
from .planar import PontryaginGuess, PontryaginSolution, nominal_guess, solve_planar_min_fuel

__all__ = ["solve_many", "nearest_neighbour_order"]


def nearest_neighbour_order(problem: PlanarOCP | PlanarScenario | str, initial_states_si
                            ) -> np.ndarray:
    """Order rows so that each is close to the previous one (greedy chain).

    Distance: normalised (r, v, r·ω, m); θ is ignored because the solution does not depend on
    it (θ is cyclic). The chain starts at the row nearest the scenario's nominal state.

    Returns
    -------
    ndarray of int, shape (N,)
    """
    scenario = as_planar_ocp(problem).scenario
    states = check_planar_states_si(initial_states_si, dry_mass_kg=0.0)
    nd = scenario.si_to_nd(states)
    feat = np.stack([nd[:, dyn.R], nd[:, dyn.VR], nd[:, dyn.R] * nd[:, dyn.OMEGA],
                     nd[:, dyn.M]], axis=1)
    x_nom = scenario.state_nd()
    nom = np.array([x_nom[dyn.R], x_nom[dyn.VR], x_nom[dyn.R] * x_nom[dyn.OMEGA], x_nom[dyn.M]])
    n = len(feat)
    order = np.empty(n, dtype=np.int64)
    left = np.ones(n, dtype=bool)
    cur = int(np.argmin(np.sum((feat - nom) ** 2, axis=1)))
    for i in range(n):
        order[i] = cur
        left[cur] = False
        if i == n - 1:
            break
        d = np.sum((feat - feat[cur]) ** 2, axis=1)
        d[~left] = np.inf
        cur = int(np.argmin(d))
    return order


def _solve_chain(scenario, states_si, start: PontryaginGuess | None, kwargs) -> list:
    """Solve rows in the given order, each warm-started from the previous success."""
    out = []
    g = start
    for row in states_si:
        sol = solve_planar_min_fuel(scenario, row, guess=g, **kwargs)
        out.append(sol)
        if sol.success:
            g = sol.guess
    return out


def solve_many(
    problem: PlanarOCP | PlanarScenario | str,
    initial_states_si,
    *,
    n_workers: int = 1,
    executor=None,
    progress: bool = True,
    chunk_size: int = 50,
    n_steps: int = 400,
    check: str = "grid",
    **kwargs,
) -> list[PontryaginSolution]:
    """Solve the minimum-fuel landing from many initial states (e.g. a dispersion).

    The rows are chained by :func:`nearest_neighbour_order`; each solve is warm-started from
    the previous success in the chain (the first from the nominal optimum), with the
    continuation and collocation fallbacks of :func:`solve_planar_min_fuel`.

    Parameters
    ----------
    problem : PlanarOCP, PlanarScenario or scenario name
        The problem family (vehicle, target); each row is its initial state.
    initial_states_si : array_like, shape (N, 5)
        SI rows (r m, vr m/s, θ rad, v_t m/s, m kg), e.g. ``scenario.sample_initial(rng, N)``.
    n_workers : int
        1 solves in this process; more uses a process pool (spawned; each worker builds its
        CasADi functions once, ~0.5 s) over contiguous chunks of the chain. Spawned workers
        re-import the main module: in a script, call from under ``if __name__ == "__main__":``.
        On a busy 2-core machine one worker is usually as fast.
    executor : optimizers.common.executor.Executor, optional
        Run the chunks on this executor instead (a Ray cluster, a shared local pool); the
        caller keeps ownership (it is not closed here). Overrides ``n_workers``.
    progress : bool
        Show a tqdm progress bar.
    chunk_size : int
        Rows per pool task (each chunk restarts from the nominal guess).
    n_steps, check, **kwargs
        Passed to :func:`solve_planar_min_fuel` (default ``check="grid"``: the terminal errors
        are the shooting residual; use ``"doubling"`` for an RK4 error estimate).

    Returns
    -------
    list of PontryaginSolution, in the order of the input rows.

    Raises
    ------
    ValueError
        Bad shape, non-finite rows, ``n_workers < 1`` or ``chunk_size < 1``.
    """
    scenario = as_planar_ocp(problem).scenario
    states = check_planar_states_si(initial_states_si, dry_mass_kg=scenario.vehicle.dry_mass_kg)
    n_workers = int(n_workers)
    if n_workers < 1:
        raise ValueError(f"n_workers = {n_workers} must be >= 1")
    if int(chunk_size) < 1:
        raise ValueError(f"chunk_size = {chunk_size!r} must be >= 1")
    n = len(states)
    if n == 0:
        return []
    order = nearest_neighbour_order(scenario, states)
    kwargs = dict(kwargs, n_steps=n_steps, check=check)
    start = nominal_guess(scenario, n_steps)
    results: list[PontryaginSolution | None] = [None] * n
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=n, desc=f"Pontryagin {scenario.name}", unit="state")
    try:
        if n_workers == 1 and executor is None:
            g = start
            for idx in order:
                sol = solve_planar_min_fuel(scenario, states[idx], guess=g, **kwargs)
                results[idx] = sol
                if sol.success:
                    g = sol.guess
                if bar is not None:
                    bar.update(1)
        else:
            from ..common.executor import run_chunks

            chunks = [order[i:i + int(chunk_size)] for i in range(0, n, int(chunk_size))]

            def _collect(c, sols):
                for idx, sol in zip(c, sols, strict=True):
                    results[idx] = sol
                if bar is not None:
                    bar.update(len(c))

            run_chunks(f"pontryagin-{scenario.name}", chunks, _solve_chain,
                       lambda c: (scenario, states[c], start, kwargs), executor=executor,
                       n_workers=n_workers, on_chunk=_collect)
    finally:
        if bar is not None:
            bar.close()
    return results  # type: ignore[return-value]
