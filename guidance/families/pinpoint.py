"""The 3D pinpoint family of guidance (``LunarPinpointLanding-v*``): its (along-track,
cross-track, up) frame, the encoder of thrust commands into the elevation and azimuth actions,
and its optimiser baselines (the replay of the per-case GPM optimum and the Pontryagin
feedback expert)."""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial

import numpy as np

from guidance.evaluation.plots import PlotFamily
from guidance.families import GuidanceFamily
from guidance.frames import LocalFrame, pinpoint_frame
from guidance.law import GuidanceLaw, Navigation
from lunar_env.envs.pinpoint_landing import action_from_angles

__all__ = ["PinpointGuidance", "PinpointOpenLoopLaw", "PinpointPlots", "encode_pinpoint"]


def encode_pinpoint(direction: np.ndarray, throttle: np.ndarray | None, throttled: bool,
                    alpha_bounds_rad: tuple[float, float],
                    beta_bounds_rad: tuple[float, float]) -> np.ndarray:
    """Actions (N, n_act) float32 of thrust directions (N, 3) (along-track, cross-track, up):
    the elevation α above the local horizontal and the azimuth β from +along-track, centred on
    π (braking) so that the bounds' wrap is harmless, clipped to the bounds
    (:func:`lunar_env.envs.pinpoint_landing.action_from_angles`); with a throttle channel
    2·throttle − 1 (throttle clipped to [0, 1]; None: full thrust)."""
    d = np.asarray(direction, dtype=np.float64)
    mag = np.linalg.norm(d, axis=1)
    alpha = np.arcsin(np.clip(d[:, 2] / np.maximum(mag, 1e-300), -1.0, 1.0))
    beta = math.pi + np.arctan2(-d[:, 1], -d[:, 0])
    act = action_from_angles(alpha, beta, alpha_bounds_rad, beta_bounds_rad)
    if throttled:
        thr = np.ones(len(d)) if throttle is None else np.clip(throttle, 0.0, 1.0)
        act = np.concatenate([act, (2.0 * thr - 1.0)[:, None]], axis=1)
    return act.astype(np.float32)


class PinpointGuidance(GuidanceFamily):
    """The pinpoint family (``scenario.family == "pinpoint"``)."""

    n_axes = 3
    #: the feedback expert costs ~1 ms a decision and lands every case at the optimum's fuel:
    #: 200 cases are enough for its row
    default_expert_cases = 200

    def frame_function(self, scenario) -> Callable[[np.ndarray], LocalFrame]:
        return partial(pinpoint_frame, scaling=scenario.scaling(),
                       plane_normal=np.asarray(scenario.plane_normal()),
                       target_m=np.asarray(scenario.target_position_m()),
                       spin_rate_rad_s=float(scenario.body.spin_rate_rad_s))

    def encoder(self, scenario, throttled: bool) -> Callable:
        return partial(encode_pinpoint, throttled=bool(throttled),
                       alpha_bounds_rad=scenario.alpha_bounds_rad,
                       beta_bounds_rad=scenario.beta_bounds_rad)

    def target_radius_m(self, scenario) -> float:
        """The radius of the gate sphere through the target (m)."""
        return float(np.linalg.norm(np.asarray(scenario.target_position_m())))

    def thrust_elevation_bounds_rad(self, scenario) -> tuple[float, float]:
        return tuple(scenario.alpha_bounds_rad)

    def expert_law(self, scenario) -> GuidanceLaw:
        from guidance.laws.pontryagin_pinpoint import PinpointPontryaginExpert

        return PinpointPontryaginExpert(scenario)

    def open_loop_law(self, optimum) -> GuidanceLaw:
        return PinpointOpenLoopLaw(optimum.solutions)


class PinpointOpenLoopLaw(GuidanceLaw):
    """Replay of each case's optimal (α, β)(t), averaged over every env step (held after tf).
    A law of the clock alone: it reads nothing of the navigation solution.

    Cases whose solve failed fly the nominal braking attitude (α = 0, β = 180°) and are
    reported like any other case.

    Parameters
    ----------
    optima : list of PinpointOptimum
        One per case (indexed by case id; :class:`optimizers.transcription.batch.
        PinpointOptimum`).
    t_offset_s : array_like, optional
        Per-case episode time at which each plan starts (mid-flight plans; default 0).
    """

    name = "optimum, open loop"

    def __init__(self, optima: list, t_offset_s=None) -> None:
        self.optima = list(optima)
        self.t_offset_s = (np.zeros(len(self.optima)) if t_offset_s is None
                           else np.asarray(t_offset_s, dtype=np.float64).reshape(-1))
        self._ids = np.zeros(0, dtype=int)

    def reset(self, computer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self._ids = np.asarray(case_ids)

    def act(self, nav: Navigation) -> np.ndarray:
        dt = self.computer.dt_s
        ang = np.tile([0.0, np.pi], (len(self._ids), 1))
        for k, cid in enumerate(self._ids):
            opt = self.optima[cid]
            if opt.success:
                ang[k] = opt.mean_angles(float(nav.t_s[k]) - self.t_offset_s[cid], dt)
        return self.computer.actions_from_controls(np.c_[ang, np.ones(len(ang))])


class PinpointPlots(PlotFamily):
    """Evaluation plots of the pinpoint family: altitude and actions against time."""

    labels = ("time (s)", "altitude (km)", "action")

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
