"""The pictures GNC engineers read a campaign by (:func:`plot_campaign`): the touchdown-speed
CDF of each law on one axis, the landing footprint with 3σ ellipses (pinpoint), fuel gap
against touchdown speed, and the robustness curve (success rate against error scale)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from guidance.campaign.statistics import wilson_interval
from optimizers.common.checkpoint import save_figure_atomic

__all__ = ["plot_campaign"]


def plot_campaign(result, out_dir: str | Path, has_target: bool) -> list[Path]:
    """Write the campaign's figures into ``out_dir``; returns their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Ellipse

    out = Path(out_dir)
    cfg = result.config
    title = f"{cfg.env_id}, uncertainty '{cfg.uncertainty.name}', {cfg.cases} cases"
    limit = None
    try:
        import gymnasium as gym

        import lunar_env  # noqa: F401

        env = gym.make(cfg.env_id, **cfg.env_kwargs)
        limit = env.unwrapped.success_thresholds
        env.close()
    except Exception:  # pragma: no cover  (plots without the limit lines)
        limit = None
    paths = []

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for name, rows in result.cases.items():
        v = np.sort(np.where(np.isnan(rows["touchdown_speed_m_s"]), np.inf,
                             rows["touchdown_speed_m_s"]))
        ax.step(v, np.arange(1, len(v) + 1) / len(v), where="post", label=name)
    if limit:
        ax.axvline(limit["speed_m_s"], color="k", ls="--", lw=0.8, label="success limit")
    ax.set_xscale("symlog", linthresh=1.0)
    ax.set_xlim(left=0.0)  # speeds are >= 0
    ax.set_xlabel("touchdown (gate) speed (m/s)")
    ax.set_ylabel("fraction of cases")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    paths.append(save_figure_atomic(fig, out / "touchdown_speed_cdf.png", dpi=120))
    plt.close(fig)

    if has_target:
        fig, ax = plt.subplots(figsize=(6.0, 6.0))
        colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
        for j, (name, rows) in enumerate(result.cases.items()):
            c = colors[j % len(colors)]
            ax.plot(rows["downrange_offset_m"], rows["crossrange_offset_m"], ".", ms=2,
                    color=c, alpha=0.5, label=name)
            ell = result.summary["laws"][name].get("footprint_3sigma")
            if ell:
                ax.add_patch(Ellipse((ell["center_downrange_m"], ell["center_crossrange_m"]),
                                     2 * ell["semi_major_m"], 2 * ell["semi_minor_m"],
                                     angle=ell["angle_deg"], fill=False, color=c, lw=1.2))
        if limit and "miss_m" in limit:
            ax.add_patch(plt.Circle((0, 0), limit["miss_m"], fill=False, ls="--", color="k",
                                    lw=0.8, label="success radius"))
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("downrange from the target (m)")
        ax.set_ylabel("crossrange from the target (m)")
        ax.set_title(f"landing footprint and 3σ ellipses\n{title}", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, markerscale=4)
        paths.append(save_figure_atomic(fig, out / "footprint.png", dpi=120))
        plt.close(fig)

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    ref = result.reference["omniscient_fuel_kg"]
    for name, rows in result.cases.items():
        gap = 100.0 * (rows["fuel_kg"] - ref) / ref
        ax.plot(rows["touchdown_speed_m_s"], gap, ".", ms=3, alpha=0.6, label=name)
    ax.set_xscale("symlog", linthresh=1.0)
    ax.set_xlim(left=0.0)
    ax.set_xlabel("touchdown (gate) speed (m/s)")
    ax.set_ylabel("fuel gap to the omniscient optimum (%)")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, markerscale=3)
    paths.append(save_figure_atomic(fig, out / "fuel_gap_vs_speed.png", dpi=120))
    plt.close(fig)

    if any(result.curve.values()):
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        for name, pts in result.curve.items():
            if not pts:
                continue
            s = [p[0] for p in pts]
            rate = [p[1] / p[2] for p in pts]
            ci = np.array([wilson_interval(p[1], p[2]) for p in pts])
            err = np.clip([np.subtract(rate, ci[:, 0]), ci[:, 1] - rate], 0.0, None)
            ax.errorbar(s, rate, yerr=err,
                        marker="o", capsize=3, label=name)
        ax.set_xlabel(f"error scale (× '{cfg.uncertainty.name}')")
        ax.set_ylabel("success rate")
        ax.set_ylim(-0.02, 1.02)
        ax.set_title(f"robustness curve, {cfg.env_id}", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        paths.append(save_figure_atomic(fig, out / "robustness.png", dpi=120))
        plt.close(fig)
    return paths
