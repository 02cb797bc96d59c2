"""Evaluation plots of the touchdown family (``LunarPinpointLanding-v3``): altitude and throttle
against time."""

from __future__ import annotations

import numpy as np

from guidance.evaluation.plots import PlotFamily

__all__ = ["TouchdownPlots", "optimum_altitude_track"]


def optimum_altitude_track(solution, scenario) -> tuple[np.ndarray, np.ndarray]:
    """Times (s) and altitudes (m) of a certified touchdown optimum
    (:class:`optimizers.optimum.touchdown.TouchdownOptimum`): each phase's start and its
    Legendre–Gauss points, in time order, then touchdown at the surface."""
    from optimizers.common.quadrature import legendre_gauss

    s = scenario.scaling()
    edges = np.concatenate([[0.0], np.cumsum(solution.durations_s)])
    ts, rs = [], []
    start = 0
    for p, n in enumerate(np.asarray(solution.nodes, dtype=int)):
        tau = legendre_gauss(int(n))[0]
        ts.append(np.concatenate([[edges[p]], edges[p] + (tau + 1.0) / 2.0
                                  * solution.durations_s[p]]))
        rs.append(np.linalg.norm(solution.states_nd[start:start + n + 1, :3], axis=1))
        start += n + 1
    t = np.concatenate([*ts, [edges[-1]]])
    r_m = np.concatenate(rs) * s.length_m
    alt = np.concatenate([r_m - scenario.body.radius_m, [0.0]])
    return t, alt


class TouchdownPlots(PlotFamily):
    """Altitude against time (km) and the throttle (fraction of full thrust) against time."""

    labels = ("time (s)", "altitude (km)", "throttle")

    def plot_optimum(self, ax_trajectory, ax_control, solution, scenario) -> None:
        t, alt = optimum_altitude_track(solution, scenario)
        ax_trajectory.plot(t, alt / 1e3, "k--", lw=2, label="optimum")
        edges = np.concatenate([[0.0], np.cumsum(solution.durations_s)])
        levels = np.asarray(solution.levels, dtype=float)
        ax_control.step(edges, np.append(levels, levels[-1]), "k--", where="post", lw=2,
                        label="optimum")

    def plot_flight(self, ax_trajectory, ax_control, trace, scenario, label: str) -> None:
        from lunar_env.envs.pinpoint_touchdown import throttle_from_action

        rad = np.linalg.norm(trace["state_nd"][:, :3], axis=1) * scenario.scaling().length_m
        ax_trajectory.plot(trace["t_s"], (rad - scenario.body.radius_m) / 1e3, label=label)
        act = np.asarray(trace["action"])
        if len(act):
            ax_control.step(trace["t_s"][:len(act)],
                            throttle_from_action(act[:, 2], float(scenario.throttle_min)),
                            where="post", label=label)
