"""The planar family's optimum (``LunarSoftLanding-v0``): Pontryagin indirect shooting."""

from __future__ import annotations

import time

import numpy as np

from lunar_env.states import planar_nd_to_si
from optimizers.indirect.batch import solve_many
from optimizers.indirect.planar import nominal_guess, release_solvers, solve_planar_min_fuel
from optimizers.optimum import OptimumFamily, PerCaseOptimum, PlantOptimumFuel, plant_scenario

__all__ = ["PlanarOptimum", "PONTRYAGIN"]

#: the planar omniscient reference's method
PONTRYAGIN = "Pontryagin (optimizers.indirect.planar.solve_planar_min_fuel)"


class PlanarOptimum(OptimumFamily):
    """The planar soft-landing optimum (``scenario.family == "planar"``)."""

    def per_case_optimum(self, scenario, states_nd: np.ndarray, *, progress: bool = True,
                         workers: int = 1, executor=None) -> PerCaseOptimum:
        """Pontryagin indirect shooting from each state (:func:`optimizers.indirect.batch.
        solve_many`, warm-started along the cases; ``executor`` solves chunks in parallel)."""
        if progress:
            print(f"Solving {len(states_nd)} per-case optimal controls (Pontryagin)...",
                  flush=True)
        t0 = time.perf_counter()
        sols = solve_many(scenario, planar_nd_to_si(states_nd, scenario.scaling()),
                          progress=progress, executor=executor)
        return PerCaseOptimum.from_solutions(list(sols), "optimizers.indirect.batch.solve_many",
                                             time.perf_counter() - t0)

    def plant_optimum_fuel(self, scenario, states_nd: np.ndarray, thrust_scale: np.ndarray,
                           isp_scale: np.ndarray, *, progress: bool = False
                           ) -> PlantOptimumFuel:
        """Pontryagin's minimum-fuel optimum of each case with its true engine (the states' SI
        rows come from the nominal scaling, which the plant does not change). NaN where it did
        not converge.

        A thrust error is solved exactly as a mass change: with thrust k_T·F the equations of
        motion in m are those with thrust F in m / k_T (acceleration F k_T / m, mass flow
        k_T F / c), so the case is solved with the nominal thrust from m0 / k_T and its fuel
        multiplied by k_T. Only an Isp error needs its own shooting functions (built per Isp,
        ~1.5 s, the solve itself ~0.1 s, measured; released after each case so memory stays
        flat). Every case is warm-started from the nominal optimum, never from a neighbour, so
        its reference does not depend on which cases share its chunk."""
        rows = planar_nd_to_si(states_nd, scenario.scaling())
        fuel = np.full(len(rows), np.nan)
        guess = nominal_guess(scenario)
        it = range(len(rows))
        if progress:
            from tqdm.auto import tqdm

            it = tqdm(it, desc="omniscient optimum (Pontryagin)", unit="case")
        for k in it:
            kt = float(thrust_scale[k])
            sc = plant_scenario(scenario, 1.0, float(isp_scale[k]))
            row = rows[k].copy()
            row[4] /= kt
            sol = solve_planar_min_fuel(sc, row, guess=guess, check="grid")
            if sol.success:
                fuel[k] = kt * sol.fuel_kg
            if sc is not scenario:
                release_solvers()
        solver = tuple(PONTRYAGIN if np.isfinite(f) else "" for f in fuel)
        return PlantOptimumFuel(fuel, solver)

    def replan_ocp(self, scenario):
        """The planar landing OCP (:class:`optimizers.problems.planar_ocp.PlanarOCP`)."""
        from optimizers.problems.planar_ocp import PlanarOCP

        return PlanarOCP(scenario)
