"""Evaluation plots of the planar family: altitude against downrange, thrust angle φ."""

from __future__ import annotations

import numpy as np

from guidance.evaluation.plots import PlotFamily
from lunar_env.envs.soft_landing import thrust_angle_from_action

__all__ = ["PlanarPlots"]


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
