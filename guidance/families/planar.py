"""The planar soft-landing family of guidance (``LunarSoftLanding-v0``): its (downrange, up)
frame, the encoder of thrust commands into the thrust-angle action, and its optimiser
baselines (the Pontryagin open-loop replay and re-planning expert)."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import numpy as np

from guidance.evaluation.plots import PlotFamily
from guidance.families import GuidanceFamily
from guidance.frames import LocalFrame, planar_frame
from guidance.law import GuidanceLaw, Navigation
from lunar_env.envs.soft_landing import action_from_thrust_angle, thrust_angle_from_action

__all__ = ["PlanarGuidance", "PlanarOpenLoopLaw", "PlanarPlots", "encode_planar"]


def encode_planar(direction: np.ndarray, throttle: np.ndarray | None, throttled: bool
                  ) -> np.ndarray:
    """Actions (N, n_act) float32 of thrust directions (N, 2) (downrange, up): the thrust angle
    φ from the local horizontal (cos φ > 0 brakes, thrusting against +downrange motion), and
    with a throttle channel 2·throttle − 1 (throttle clipped to [0, 1]; None: full thrust)."""
    d = np.asarray(direction, dtype=np.float64)
    act = action_from_thrust_angle(np.arctan2(d[:, 1], -d[:, 0]))[:, None]
    if throttled:
        thr = np.ones(len(d)) if throttle is None else np.clip(throttle, 0.0, 1.0)
        act = np.concatenate([act, (2.0 * thr - 1.0)[:, None]], axis=1)
    return act.astype(np.float32)


class PlanarGuidance(GuidanceFamily):
    """The planar family (``scenario.family == "planar"``)."""

    n_axes = 2
    #: the re-planning expert costs a Pontryagin solve per decision (~5 ms): 20 cases by default
    default_expert_cases = 20

    def frame_function(self, scenario) -> Callable[[np.ndarray], LocalFrame]:
        return partial(planar_frame, scaling=scenario.scaling(),
                       surface_radius_m=float(scenario.surface_radius_m))

    def encoder(self, scenario, throttled: bool) -> Callable:
        return partial(encode_planar, throttled=bool(throttled))

    def target_radius_m(self, scenario) -> float:
        """The landing surface's radius (m)."""
        return float(scenario.surface_radius_m)

    def expert_law(self, scenario) -> GuidanceLaw:
        from guidance.laws.pontryagin_planar import PlanarReplanningLaw

        return PlanarReplanningLaw(scenario)

    def open_loop_law(self, optimum) -> GuidanceLaw:
        return PlanarOpenLoopLaw(optimum.solutions)


class PlanarOpenLoopLaw(GuidanceLaw):
    """Replay of per-case optimal thrust-angle histories φ(t).

    The env holds each action for ``dt_s``; the replay samples φ at the middle of the step
    (a second-order accurate hold of a smooth control). After the optimal final time the last
    value is held. A law of the clock alone: it reads nothing of the navigation solution.

    Parameters
    ----------
    solutions : sequence of PontryaginSolution
        One per case (indexed by case id), with ``thrust_angle_at(t_s)``. Cases whose solve
        failed fly φ = 0 (a braking burn) and are reported like any other case.
    """

    name = "Pontryagin open loop"

    def __init__(self, solutions) -> None:
        self.solutions = list(solutions)
        self._ids = np.zeros(0, dtype=int)

    def reset(self, computer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self._ids = np.asarray(case_ids)

    def act(self, nav: Navigation) -> np.ndarray:
        t_mid = nav.t_s + 0.5 * self.computer.dt_s
        phi = np.zeros(len(self._ids))
        for k, cid in enumerate(self._ids):
            sol = self.solutions[cid]
            if sol.success:
                phi[k] = sol.thrust_angle_at(float(t_mid[k]))
        return self.computer.actions_from_controls(np.stack([phi, np.ones(len(phi))], axis=1))


class PlanarPlots(PlotFamily):
    """Evaluation plots of the planar family: altitude against downrange, thrust angle φ."""

    labels = ("downrange (km)", "altitude (km)", "thrust angle φ (deg)")

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
