"""Evaluation plots of the pinpoint family: altitude and actions against time."""

from __future__ import annotations

import numpy as np

from guidance.evaluation.plots import PlotFamily

__all__ = ["PinpointPlots"]


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
