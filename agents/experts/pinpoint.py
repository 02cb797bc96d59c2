"""The 3D pinpoint family (``LunarPinpointLanding-v*``): its expert, laws and optimum.

- :class:`PinpointPontryaginExpert`: the optimal feedback of
  :mod:`optimizers.indirect.pinpoint_feedback` as a guidance law, and the labeller of the
  pinpoint datasets and of DAgger;
- :class:`PinpointFamily` answers the family's questions (:mod:`agents.experts.family`): the
  per-case optimum ([001]'s serial GPM + shooting, :mod:`agents.experts.pinpoint_optimum`), the
  open-loop replay, curriculum starts along the extremals, start perturbations, plots.
"""

from __future__ import annotations

import time

import numpy as np

from agents.common.law import FlightComputer, GuidanceLaw, Navigation
from agents.experts.family import DaggerRequest, DatasetRecipe, EnvFamily, PerCaseOptimum
from agents.experts.pinpoint_optimum import PinpointOpenLoopLaw, pinpoint_optima
from lunar_env.envs.pinpoint_landing import action_from_angles
from lunar_env.scenarios import PinpointScenario
from lunar_env.validation import require_number, require_option_keys
from optimizers.indirect.pinpoint_feedback import (
    TARGET_REACHED_M,
    PinpointFeedback,
    extremal_path,
    solve_extremal,
)

__all__ = ["PinpointPontryaginExpert", "PinpointFamily", "PINPOINT_LABEL_STATUSES"]

#: statuses of :class:`PinpointPontryaginExpert` decisions that are the extremal's law, hence
#: labels; "stale" and "fallback" (no converged solve) are guesses and are not
PINPOINT_LABEL_STATUSES = ("optimal", "nearest", "hold")


class PinpointPontryaginExpert(GuidanceLaw):
    """Closed-loop optimal feedback for ``LunarPinpointLanding-v*``: at every decision the
    minimum-time extremal from the lander's current state (:class:`optimizers.indirect.
    pinpoint_feedback.PinpointFeedback`, compiled Pontryagin shooting warm-started from the
    previous decision's extremal, ~1-15 ms), flown over the env step as its mean angle.

    A guidance law on the navigation solution (:meth:`act`), and the labeller of the pinpoint
    datasets and of DAgger (:meth:`labels`, which the privileged teachers call with the truth).
    Where the target is out of reach (a lander too
    fast to stop at it), the extremal to the nearest reachable stop on the track is flown;
    the per-decision statuses are counted in :attr:`status_counts`.

    Parameters
    ----------
    scenario : PinpointScenario
    feedback_kwargs : forwarded to :class:`PinpointFeedback` (``step_s``, ``hold_s``, ...).
    """

    name = "Pontryagin feedback expert"

    def __init__(self, scenario, **feedback_kwargs) -> None:
        self.scenario = scenario
        self.feedback = PinpointFeedback(scenario, **feedback_kwargs)
        self.status_counts: dict[str, int] = {}

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        """New flights: forget the previous extremals, and keep them above the gate where the
        env counts it (its ``gate_range_m``: near the target in v2, everywhere in v0/v1)."""
        super().reset(computer, case_ids)
        self.feedback.reset()
        self.feedback.gate_floor_range_m = computer.gate_range_m

    def angles(self, states_nd: np.ndarray, t_s: np.ndarray, dt_s: float,
               active: np.ndarray | None = None) -> np.ndarray:
        """(α, β) (rad), (B, 2), of the extremals from states (B, 7) at episode times (B,)."""
        ang = self.feedback(states_nd, t_s, dt_s, active)
        act = np.ones(len(ang), dtype=bool) if active is None else np.asarray(active, bool)
        for st, a in zip(self.feedback.last_status, act, strict=True):
            if a:
                self.status_counts[st] = self.status_counts.get(st, 0) + 1
        return ang

    def labels(self, state_nd: np.ndarray, t_s: np.ndarray, active: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The expert's decision at normalised states (B, 7) and episode times (B,) (s).

        Returns ``(angles, actions, is_label)``: (α, β) (rad) and the env actions (float32),
        both (B, 2), and (B,) bool: the row is active (``active``; None: all) and its status is
        one of :data:`PINPOINT_LABEL_STATUSES`. Call :meth:`reset` first.
        """
        ang = self.angles(state_nd, t_s, self.computer.dt_s, active)
        sc = self.scenario
        actions = action_from_angles(ang[:, 0], ang[:, 1], sc.alpha_bounds_rad,
                                     sc.beta_bounds_rad).astype(np.float32)
        is_label = np.isin(np.asarray(self.last_status), PINPOINT_LABEL_STATUSES)
        if active is not None:
            is_label &= np.asarray(active, dtype=bool)
        return ang, actions, is_label

    def act(self, nav: Navigation) -> np.ndarray:
        return self.labels(nav.state_nd, nav.t_s, nav.active)[1]

    @property
    def last_status(self) -> list[str]:
        return self.feedback.last_status


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
            sols, "agents.experts.pinpoint_optimum (serial GPM + direct shooting)",
            time.perf_counter() - t0)

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
        """See :func:`agents.experts.pinpoint_data.pinpoint_dataset_recipe`."""
        from agents.experts.pinpoint_data import pinpoint_dataset_recipe

        return pinpoint_dataset_recipe(scenario, n, seed, n_steps=n_steps, check=check,
                                       tol_radius_m=tol_radius_m, tol_speed_m_s=tol_speed_m_s,
                                       action_noise=action_noise)

    def dagger_iteration(self, scenario, request: DaggerRequest
                         ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
        """See :func:`agents.experts.pinpoint_data.pinpoint_dagger_iteration`."""
        from agents.experts.pinpoint_data import pinpoint_dagger_iteration

        return pinpoint_dagger_iteration(scenario, request)

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
