"""The pinpoint env family: what :class:`~agents.experts.family.EnvFamily` asks, answered for
the pinpoint landing."""

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
from agents.experts.pinpoint.data import pinpoint_dagger_iteration, pinpoint_dataset_recipe
from agents.experts.pinpoint.expert import PinpointPontryaginExpert
from agents.experts.pinpoint.features import (
    PINPOINT_FEATURE_WIDTHS,
    augment_pinpoint,
    pinpoint_feature_bounds,
    pinpoint_feature_constants,
)
from agents.experts.pinpoint.optimum import PinpointOpenLoopLaw, pinpoint_optima
from lunar_env.scenarios import PinpointScenario
from lunar_env.validation import require_number, require_option_keys
from optimizers.indirect.pinpoint_feedback import (
    TARGET_REACHED_M,
    PinpointFeedback,
    extremal_path,
    solve_extremal,
)

#: the methods of the pinpoint omniscient reference (:meth:`PinpointFamily.plant_optimum_fuel`)
PONTRYAGIN = "Pontryagin extremal (optimizers.indirect.pinpoint_feedback)"
DIRECT = "direct, GPM + shooting (optimizers.transcription.batch.solve_case)"


class PinpointFamily(EnvFamily):
    """The 3D pinpoint family (:class:`~lunar_env.scenarios.PinpointScenario`)."""

    name = "pinpoint"
    #: the feedback expert costs ~1 ms a decision and lands every case at the optimum's fuel:
    #: 200 cases are enough for its row
    default_expert_cases = 200
    plot_labels = ("time (s)", "altitude (km)", "action")

    def handles(self, scenario) -> bool:
        return isinstance(scenario, PinpointScenario)

    def per_case_optimum(self, scenario, states_nd: np.ndarray, *, progress: bool = True,
                         workers: int = 1, executor=None) -> PerCaseOptimum:
        """[001]'s serial GPM + direct shooting from each drawn state (cached on disk)."""
        if progress:
            print(f"Per-case optimum of {len(states_nd)} states (GPM + direct shooting, "
                  "cached)...", flush=True)
        t0 = time.perf_counter()
        sols = pinpoint_optima(scenario, states_nd, workers=workers, progress=progress,
                               executor=executor)
        return PerCaseOptimum.from_solutions(
            sols, "agents.experts.pinpoint.optimum (serial GPM + direct shooting)",
            time.perf_counter() - t0)

    def plant_optimum_fuel(self, scenario, states_nd: np.ndarray, thrust_scale: np.ndarray,
                           isp_scale: np.ndarray, *, progress: bool = False
                           ) -> PlantOptimumFuel:
        """The minimum-fuel landing of each case with its true engine.

        First the minimum-fuel extremal (compiled Pontryagin shooting, ~10 ms a case; the same
        optima as the GPM + shooting of :meth:`per_case_optimum` within 0.01 kg,
        tests/optimizers/test_pinpoint_feedback.py). The engine has constant thrust, so the
        minimum-fuel landing is the minimum-time one: propellant = ṁ · t_go with the true
        ṁ = k_T T / (k_c c).

        Where the shooting finds no extremal, the direct optimum of the true plant
        (:func:`optimizers.transcription.batch.solve_case`: GPM collocation, then direct
        shooting, with the env's gate constraint and propellant bound, replayed to the target;
        ~8 s a case, ~40 s where none exists). Decision (issue 31): on 1000 ``standard`` cases
        the shooting found no extremal for 52, 49 of them with engines 0.6–6 % stronger than
        nominal; the direct method landed all 49 in the env and matched the extremal's fuel
        within 0.06 kg on 5 control cases (docs/notes/issue-31-pinpoint-feasibility.json).
        Without it those cases had no reference and the fuel gaps leaned towards weaker
        engines. No case is warm-started from another, so a case's reference does not depend on
        which cases share its chunk. NaN where neither method finds a landing."""
        from optimizers.transcription.batch import solve_case

        fuel = np.full(len(states_nd), np.nan)
        solver = [""] * len(states_nd)
        veh = scenario.vehicle
        mdot = veh.thrust_n / veh.exhaust_velocity_m_s
        nominal = PinpointFeedback(scenario)
        it = range(len(states_nd))
        if progress:
            from tqdm.auto import tqdm

            it = tqdm(it, desc="omniscient optimum (Pontryagin, direct fallback)", unit="case")
        for k in it:
            kt, kc = float(thrust_scale[k]), float(isp_scale[k])
            x0 = np.asarray(states_nd[k], dtype=np.float64)
            sc = plant_scenario(scenario, kt, kc)
            # continuation in the plant: the nominal engine's extremal from the same start is
            # the guess for the true engine's (a few per cent away)
            start = nominal.solve(x0)
            sol = None
            if start is not None:
                plant = PinpointFeedback(sc)
                sol = solve_extremal(plant.k, x0, start.z, step_s=plant.step_s)
                if not sol.converged:
                    try:
                        sol = plant.solve(x0, start.z)
                    except RuntimeError:  # no extremal of this plant from its crude guesses
                        sol = None
            if sol is not None and sol.converged and abs(sol.beyond_m) < TARGET_REACHED_M:
                fuel[k] = mdot * kt / kc * sol.tgo_s
                solver[k] = PONTRYAGIN
                continue
            direct = solve_case(sc, x0)
            if direct.success:
                fuel[k] = direct.fuel_kg
                solver[k] = DIRECT
        return PlantOptimumFuel(fuel, tuple(solver))

    def open_loop_law(self, optimum: PerCaseOptimum) -> GuidanceLaw:
        return PinpointOpenLoopLaw(optimum.solutions)

    def expert_law(self, scenario) -> GuidanceLaw:
        return PinpointPontryaginExpert(scenario)

    def start_pool(self, scenario, n_trajectories: int, seed: int, n_points: int = 101,
                   progress: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """States along the minimum-fuel extremal of each dispersed start (compiled Pontryagin
        shooting, ~10 ms a case, warm-started along the draw), ``n_points`` per extremal (the
        gate excluded), shape (n_ok, n_points, 7), and their times (s).

        Decision (issue 16): before, the pool was the per-case optima of [001]'s serial GPM +
        shooting (~1 s a case, 4 min for 256 on a fresh machine); the extremals are the same
        optima (fuel within 0.01 kg, tests/optimizers/test_pinpoint_feedback.py) and cost
        seconds.
        """
        rows = scenario.sample_initial(np.random.default_rng(seed), int(n_trajectories))
        fb = PinpointFeedback(scenario)
        s = scenario.scaling()
        states, times = [], []
        guess = None
        it = rows
        if progress:
            from tqdm.auto import tqdm

            it = tqdm(rows, desc=f"optimal start pool {scenario.name}", unit="case")
        for r in it:
            x0 = scenario.state_nd(r, scaling=s)
            sol = fb.solve(x0, guess)
            if sol is None or abs(sol.beyond_m) >= TARGET_REACHED_M:
                continue
            guess = sol.z
            # re-solved on the grid it is sampled on (the endpoint depends on the grid)
            step = sol.tgo_s / (4 * n_points)
            fine = solve_extremal(fb.k, x0, sol.z, step_s=step, min_steps=1)
            if not fine.converged:
                continue
            t, path = extremal_path(fb.k, x0, fine.z, step_s=step, min_steps=1)
            keep = np.arange(n_points) * 4  # n_points states, the last (the gate) excluded
            states.append(path[keep, :7])
            times.append(t[keep])
        if not states:
            raise RuntimeError("no optimal trajectory converged; cannot build the curriculum")
        return np.asarray(states), np.asarray(times)

    def start_noise_nd(self, scenario, noise: dict[str, float]) -> tuple[float, float]:
        """Validated ``{position_m, velocity_m_s}`` start perturbation, as standard deviations
        in the scenario's normalised units."""
        require_option_keys("start_noise", noise, ("position_m", "velocity_m_s"))
        pos, vel = (require_number(f"start_noise {k}", noise.get(k, 0.0))
                    for k in ("position_m", "velocity_m_s"))
        for key, v in (("position_m", pos), ("velocity_m_s", vel)):
            if not (np.isfinite(v) and v >= 0.0):
                raise ValueError(f"start_noise {key}={v!r} must be finite and >= 0")
        s = scenario.scaling()
        return pos / s.length_m, vel / s.velocity_m_s

    def perturb_starts(self, states_nd: np.ndarray, sigma_nd: tuple[float, float],
                       rng: np.random.Generator) -> np.ndarray:
        """Gaussian position and velocity errors (σ from :meth:`start_noise_nd`) added to
        curriculum starts (M, 7); a copy."""
        y = np.array(states_nd, dtype=np.float64, copy=True)
        sig_r, sig_v = sigma_nd
        y[:, 0:3] += rng.normal(0.0, sig_r, (len(y), 3))
        y[:, 3:6] += rng.normal(0.0, sig_v, (len(y), 3))
        return y

    def dataset_recipe(self, scenario, n: int, seed: int, *, n_steps: int, check: str,
                       tol_radius_m: float | None, tol_speed_m_s: float | None,
                       action_noise: float | None) -> DatasetRecipe:
        """See :func:`agents.experts.pinpoint.data.pinpoint_dataset_recipe`."""
        return pinpoint_dataset_recipe(scenario, n, seed, n_steps=n_steps, check=check,
                                       tol_radius_m=tol_radius_m, tol_speed_m_s=tol_speed_m_s,
                                       action_noise=action_noise)

    def dagger_iteration(self, scenario, request: DaggerRequest
                         ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
        """See :func:`agents.experts.pinpoint.data.pinpoint_dagger_iteration`."""
        return pinpoint_dagger_iteration(scenario, request)

    def feature_widths(self) -> dict[str, int]:
        """See :func:`agents.experts.pinpoint.features.augment_pinpoint`."""
        return dict(PINPOINT_FEATURE_WIDTHS)

    def feature_constants(self, env) -> dict:
        """The scenario and the observation map (the ``reference_profile`` feature)."""
        return pinpoint_feature_constants(env)

    def augment_observation(self, obs, consts, names) -> np.ndarray:
        """See :func:`agents.experts.pinpoint.features.augment_pinpoint`."""
        return augment_pinpoint(obs, consts, names)

    def feature_bounds(self, names) -> tuple[list[float], list[float]]:
        return pinpoint_feature_bounds(names)

    def shaping_potentials(self) -> tuple[str, ...]:
        return ("gate_speed_and_range",)

    def plot_optimum(self, ax_trajectory, ax_control, solution, scenario) -> None:
        s = scenario.scaling()
        opt_r = np.linalg.norm(solution.states_nd[:, :3], axis=1) * s.length_m
        ax_trajectory.plot(solution.t_nodes_s, (opt_r - scenario.body.radius_m) / 1e3, "k--",
                           lw=2, label="optimum")

    def plot_flight(self, ax_trajectory, ax_control, trace, scenario, label: str) -> None:
        rad = np.linalg.norm(trace["state_nd"][:, :3], axis=1) * scenario.scaling().length_m
        ax_trajectory.plot(trace["t_s"], (rad - scenario.body.radius_m) / 1e3, label=label)
        for j in range(trace["action"].shape[1] if len(trace["action"]) else 0):
            ax_control.step(trace["t_s"][:len(trace["action"])], trace["action"][:, j],
                            where="post", label=f"{label} a{j}")
