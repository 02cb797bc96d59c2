"""Evaluation plots of the touchdown family (``LunarPinpointLanding-v3``): altitude and actions
against time, the certified optimum drawn through its collocation points."""

from __future__ import annotations

import numpy as np

from guidance.evaluation.plots.pinpoint import PinpointPlots

__all__ = ["TouchdownPlots"]


class TouchdownPlots(PinpointPlots):
    """The pinpoint family's plots, with the touchdown optimum
    (:class:`optimizers.optimum.touchdown.TouchdownOptimum`: each throttle arc's start and
    Legendre-Gauss points)."""

    def plot_optimum(self, ax_trajectory, ax_control, solution, scenario) -> None:
        from optimizers.common.quadrature import legendre_gauss

        edges = np.concatenate([[0.0], np.cumsum(solution.durations_s)])
        t = np.concatenate([
            edges[p] + 0.5 * (np.concatenate([[-1.0], legendre_gauss(int(n))[0]]) + 1.0)
            * solution.durations_s[p] for p, n in enumerate(solution.nodes)])
        r = np.linalg.norm(solution.states_nd[:, :3], axis=1) * scenario.scaling().length_m
        ax_trajectory.plot(t, (r - scenario.body.radius_m) / 1e3, "k--", lw=2, label="optimum")
