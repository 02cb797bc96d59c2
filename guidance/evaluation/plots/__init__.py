"""Evaluation plots: each law's traced flights beside the optimum, per env family.

A :class:`PlotFamily` per env family draws one case's optimum and one flown case on a
trajectory axis and a control axis; :data:`PLOT_FAMILIES` holds them by ``scenario.family``
(``planar``, ``pinpoint`` and ``pinpoint_touchdown``: :mod:`.planar`, :mod:`.pinpoint`,
:mod:`.touchdown`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from lunar_env.families import FamilyRegistry
from optimizers.common.checkpoint import save_figure_atomic

if TYPE_CHECKING:
    from guidance.flight import PolicyResult

__all__ = ["PlotFamily", "PLOT_FAMILIES", "plot_comparison"]


class PlotFamily(ABC):
    """How an env family's flights are drawn."""

    #: axis labels: (trajectory x, trajectory y, control y)
    labels: tuple[str, str, str] = ("", "altitude (km)", "")

    @abstractmethod
    def plot_optimum(self, ax_trajectory, ax_control, solution, scenario) -> None:
        """Draw one case's optimum (dashed) on the trajectory and control axes."""

    @abstractmethod
    def plot_flight(self, ax_trajectory, ax_control, trace: dict[str, np.ndarray], scenario,
                    label: str) -> None:
        """Draw one flown case (``trace``: ``t_s``, ``state_nd``, ``action``)."""


#: the evaluation plots of each env family, by ``scenario.family``
PLOT_FAMILIES: FamilyRegistry[PlotFamily] = FamilyRegistry(
    "plot", entry_point_group="lunar_env.plot_families")
PLOT_FAMILIES.register("planar", "guidance.evaluation.plots.planar:PlanarPlots")
PLOT_FAMILIES.register("pinpoint", "guidance.evaluation.plots.pinpoint:PinpointPlots")
PLOT_FAMILIES.register("pinpoint_touchdown", "guidance.evaluation.plots.touchdown:TouchdownPlots")


def plot_comparison(report: dict[str, Any], path: str | Path) -> Path:
    """Trajectory (altitude vs downrange) and thrust angle vs time of each policy and the optimum
    for the traced cases; saved as a PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenario = report["scenario"]
    family = PLOT_FAMILIES.of(scenario)
    results: list[PolicyResult] = report["results"]
    cases = sorted(set().union(*[set(r.traces) for r in results])) if results else []
    if not cases:
        raise ValueError("no traced cases to plot")
    fig, axes = plt.subplots(len(cases), 2, figsize=(12, 3.6 * len(cases)), squeeze=False)
    sols = report.get("optimal_solutions")
    for row, cid in enumerate(cases):
        ax_tr, ax_u = axes[row]
        if sols is not None and getattr(sols[cid], "success", False):
            family.plot_optimum(ax_tr, ax_u, sols[cid], scenario)
        for res in results:
            trace = res.traces.get(cid)
            if trace is None or len(trace["state_nd"]) == 0:
                continue
            family.plot_flight(ax_tr, ax_u, trace, scenario, res.name)
        # a trajectory that passed below the surface (an env failure, reported in the table as
        # no touchdown) must not squash the others: clip the view just below the surface
        tops = [ln.get_ydata().max() for ln in ax_tr.get_lines() if len(ln.get_ydata())]
        if tops:
            hi = 1.05 * max(max(tops), 1e-3)
            ax_tr.set_ylim(-0.05 * hi, hi)
        x_label, y_label, u_label = family.labels
        ax_tr.set_xlabel(x_label)
        ax_tr.set_ylabel(y_label)
        ax_tr.set_title(f"case {cid}: trajectory")
        ax_u.set_xlabel("time (s)")
        ax_u.set_ylabel(u_label)
        ax_u.set_title(f"case {cid}: control")
        ax_tr.grid(alpha=0.3)
        ax_u.grid(alpha=0.3)
        ax_u.legend(fontsize=8)
    fig.tight_layout()
    path = save_figure_atomic(fig, path, dpi=110)
    plt.close(fig)
    return path
