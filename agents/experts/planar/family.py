"""The planar env family: what :class:`~agents.experts.family.EnvFamily` asks, answered for
the planar landing."""

from __future__ import annotations

import time

import numpy as np

from agents.common.law import GuidanceLaw
from agents.experts.family import (
    DaggerRequest,
    DatasetRecipe,
    EnvFamily,
    PerCaseOptimum,
    PlantOptimumFuel,
    plant_scenario,
)
from agents.experts.planar.data import planar_dagger_iteration, planar_dataset_recipe
from agents.experts.planar.expert import PlanarOpenLoopLaw, PlanarReplanningLaw, planar_state_si
from agents.experts.planar.features import (
    PLANAR_FEATURE_WIDTHS,
    augment_planar,
    planar_feature_bounds,
)
from lunar_env.envs.soft_landing import thrust_angle_from_action
from lunar_env.scenarios import PlanarScenario
from optimizers.indirect.batch import solve_many
from optimizers.indirect.planar import nominal_guess, release_solvers, solve_planar_min_fuel

#: the planar omniscient reference's method
PONTRYAGIN = "Pontryagin (optimizers.indirect.planar.solve_planar_min_fuel)"


class PlanarFamily(EnvFamily):
    """The planar soft-landing family (:class:`~lunar_env.scenarios.PlanarScenario`)."""

    name = "planar"
    #: the re-planning expert costs a Pontryagin solve per decision (~5 ms): 20 cases by default
    default_expert_cases = 20
    plot_labels = ("downrange (km)", "altitude (km)", "thrust angle φ (deg)")

    def handles(self, scenario) -> bool:
        return isinstance(scenario, PlanarScenario)

    def per_case_optimum(self, scenario, states_nd: np.ndarray, *, progress: bool = True,
                         workers: int = 1, executor=None) -> PerCaseOptimum:
        """Pontryagin indirect shooting from each state (:func:`optimizers.indirect.batch.
        solve_many`, warm-started along the cases; ``executor`` solves chunks in parallel)."""
        if progress:
            print(f"Solving {len(states_nd)} per-case optimal controls (Pontryagin)...",
                  flush=True)
        t0 = time.perf_counter()
        sols = solve_many(scenario, planar_state_si(scenario, states_nd), progress=progress,
                          executor=executor)
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
        rows = planar_state_si(scenario, states_nd)
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

    def open_loop_law(self, optimum: PerCaseOptimum) -> GuidanceLaw:
        return PlanarOpenLoopLaw(optimum.solutions)

    def expert_law(self, scenario) -> GuidanceLaw:
        return PlanarReplanningLaw(scenario)

    def start_pool(self, scenario, n_trajectories: int, seed: int, n_points: int = 101,
                   progress: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """States at ``n_points`` equal times along the Pontryagin optimum of each dispersed
        start (touchdown excluded), shape (n_ok, n_points, 5), and their times (s)."""
        rows = scenario.sample_initial(np.random.default_rng(seed), int(n_trajectories))
        sols = [s for s in solve_many(scenario, rows, progress=progress) if s.success]
        if not sols:
            raise RuntimeError("no optimal trajectory converged; cannot build the curriculum")
        states, times = [], []
        for sol in sols:
            t = np.linspace(0.0, sol.tf_s, n_points + 1)[:-1]
            states.append(sol.state_costate_at(t)[:, :5])
            times.append(t)
        return np.asarray(states), np.asarray(times)

    def dataset_recipe(self, scenario, n: int, seed: int, *, n_steps: int, check: str,
                       tol_radius_m: float | None, tol_speed_m_s: float | None,
                       action_noise: float | None) -> DatasetRecipe:
        """See :func:`agents.experts.planar.data.planar_dataset_recipe`."""
        return planar_dataset_recipe(scenario, n, seed, n_steps=n_steps, check=check,
                                     tol_radius_m=tol_radius_m, tol_speed_m_s=tol_speed_m_s,
                                     action_noise=action_noise)

    def dagger_iteration(self, scenario, request: DaggerRequest
                         ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
        """See :func:`agents.experts.planar.data.planar_dagger_iteration`."""
        return planar_dagger_iteration(scenario, request)

    def feature_widths(self) -> dict[str, int]:
        """See :mod:`agents.experts.planar.features`."""
        return dict(PLANAR_FEATURE_WIDTHS)

    def augment_observation(self, obs, consts, names) -> np.ndarray:
        """See :func:`agents.experts.planar.features.augment_planar`."""
        return augment_planar(obs, consts, names)

    def feature_bounds(self, names) -> tuple[list[float], list[float]]:
        return planar_feature_bounds(names)

    def shaping_potentials(self) -> tuple[str, ...]:
        return ("surface_speed",)

    def plot_optimum(self, ax_trajectory, ax_control, solution, scenario) -> None:
        r_surf = scenario.surface_radius_m
        tr = solution.sample(n=301)
        st = tr.states
        ax_trajectory.plot(st["theta_rad"] * r_surf / 1e3, (st["radius_m"] - r_surf) / 1e3,
                           "k--", lw=2, label="optimum")
        ax_control.plot(tr.t_s, np.degrees(tr.controls["phi_rad"]), "k--", lw=2,
                        label="optimum")

    def plot_flight(self, ax_trajectory, ax_control, trace, scenario, label: str) -> None:
        r_surf = scenario.surface_radius_m
        y = trace["state_nd"]
        ax_trajectory.plot(y[:, 2] * r_surf / 1e3,
                           (y[:, 0] * scenario.scaling().length_m - r_surf) / 1e3, label=label)
        if len(trace["action"]):
            phi = thrust_angle_from_action(trace["action"][:, 0])
            ax_control.step(trace["t_s"][:len(phi)], np.degrees(phi), where="post", label=label)
