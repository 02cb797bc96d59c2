"""The pictures GNC engineers read a campaign by (:func:`plot_campaign`): the touchdown-speed
CDF of each law on one axis, the landing footprint with 3σ ellipses (pinpoint), fuel gap
against touchdown speed, and the robustness curve (success rate against error scale).

Every frame is drawn around the success limits, not around the worst case: one far outlier
(a crash 1,000 km downrange) would otherwise set the scale, squash every landing into a dot
at the origin and flatten the ellipses into lines. So the footprint spans
:data:`FOOTPRINT_RADII` success radii either side of the target, and the speed axes
:data:`SPEED_LIMITS` success speeds; a value beyond a frame is drawn on its edge (an open
marker) and counted in its law's legend entry. The 3σ ellipses are those of the successful
landings (a failure's landing point says how it failed, not how the law disperses), and are
labelled so. Legends sit outside the axes, and law specs too long for a legend get a number
and a key under the figure.

Each figure has its own function, returning the figure (:func:`speed_cdf_figure`,
:func:`footprint_figure`, :func:`fuel_gap_figure`, :func:`robustness_figure`), so a
notebook can show or restyle one; :func:`plot_campaign` writes them all.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np

from guidance.campaign.statistics import footprint_ellipse, wilson_interval
from optimizers.common.checkpoint import save_figure_atomic

__all__ = ["plot_campaign", "speed_cdf_figure", "footprint_figure", "fuel_gap_figure",
           "robustness_figure", "law_labels", "FOOTPRINT_RADII", "SPEED_LIMITS",
           "LABEL_WIDTH"]

#: half-width of the footprint's frame, in success radii
FOOTPRINT_RADII = 3.0
#: extent of the speed axes, in success speeds
SPEED_LIMITS = 4.0
#: longest law spec shown whole in a legend (characters); longer ones are numbered and keyed
LABEL_WIDTH = 28


def law_labels(names, width: int = LABEL_WIDTH) -> tuple[dict[str, str], str | None]:
    """Legend labels of law specs: the specs themselves when every one fits in ``width``
    characters; otherwise ``"k: <spec shortened>"`` for the k-th law, and a key (text) giving
    the numbered specs in full.

    >>> law_labels(["apollo", "zem-zev"])
    ({'apollo': 'apollo', 'zem-zev': 'zem-zev'}, None)
    """
    names = list(names)
    if all(len(n) <= width for n in names):
        return {n: n for n in names}, None
    labels = {n: f"{i}: {n if len(n) <= width else n[:width - 1] + '…'}"
              for i, n in enumerate(names, 1)}
    key = "\n".join(textwrap.fill(f"{i}: {n}", 110, subsequent_indent="   ")
                    for i, n in enumerate(names, 1) if len(n) > width)
    return labels, key


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _title(result) -> str:
    cfg = result.config
    return f"{cfg.env_id}, uncertainty '{cfg.uncertainty.name}', {cfg.cases} cases"


def _finish(fig, ax, key: str | None, markerscale: float = 1.0) -> None:
    """Legend outside the axes (right), the key of shortened labels under them."""
    ax.legend(fontsize=8, markerscale=markerscale, loc="upper left",
              bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    if key:
        fig.text(0.01, -0.01, key, fontsize=7, va="top", ha="left", family="monospace")
    fig.tight_layout()


def _speed_frame(result, limit: dict | None) -> float:
    """The speed axes' upper end (m/s): :data:`SPEED_LIMITS` success speeds, else a little
    above the 95th percentile of the finite speeds."""
    if limit and limit.get("speed_m_s"):
        return SPEED_LIMITS * float(limit["speed_m_s"])
    v = np.concatenate([np.asarray(r["touchdown_speed_m_s"], dtype=np.float64)
                        for r in result.cases.values()])
    v = v[np.isfinite(v)]
    return 1.1 * float(np.percentile(v, 95)) if len(v) and np.percentile(v, 95) > 0 else 1.0


def _beyond(n: int, where: str) -> str:
    return f" ({n} {where})" if n else ""


def speed_cdf_figure(result, limit: dict | None = None):
    """Touchdown-speed CDF of every law on one axis, from 0 to :data:`SPEED_LIMITS` success
    speeds; a case beyond (or without a touchdown) is counted in the legend, its law's curve
    ending below 1 at the frame's edge."""
    plt = _pyplot()
    labels, key = law_labels(result.cases)
    vmax = _speed_frame(result, limit)
    fig, ax = plt.subplots(figsize=(8.4, 4.2))
    for name, rows in result.cases.items():
        v = np.asarray(rows["touchdown_speed_m_s"], dtype=np.float64)
        n = len(v)
        v_in = np.sort(v[np.isfinite(v) & (v <= vmax)])
        k = len(v_in)
        xs = np.concatenate([[0.0], v_in, [vmax]])
        ys = np.concatenate([[0.0], np.arange(1, k + 1) / max(n, 1), [k / max(n, 1)]])
        ax.step(xs, ys, where="post",
                label=labels[name] + _beyond(n - k, f"beyond {vmax:g} m/s"))
    if limit and limit.get("speed_m_s"):
        ax.axvline(limit["speed_m_s"], color="k", ls="--", lw=0.8,
                   label=f"success limit {limit['speed_m_s']:g} m/s")
    ax.set_xlim(0.0, vmax)
    ax.set_ylim(0.0, 1.02)
    ax.set_xlabel("touchdown (gate) speed (m/s)")
    ax.set_ylabel("fraction of cases")
    ax.set_title(_title(result), fontsize=9)
    ax.grid(alpha=0.3)
    _finish(fig, ax, key)
    return fig


def _footprint_frame(result, limit: dict | None) -> float:
    """The footprint's half-width (m): :data:`FOOTPRINT_RADII` success radii, else a little
    beyond the successful landings (all landings if none succeeded)."""
    if limit and limit.get("miss_m"):
        return FOOTPRINT_RADII * float(limit["miss_m"])
    pts = []
    for rows in result.cases.values():
        off = np.stack([rows["downrange_offset_m"], rows["crossrange_offset_m"]], 1)
        ok = np.asarray(rows["success"], dtype=bool)
        pts.append(off[ok] if ok.any() else off)
    r = np.abs(np.concatenate(pts)).max(axis=1)
    r = r[np.isfinite(r)]
    return 1.2 * float(np.percentile(r, 95)) if len(r) and np.percentile(r, 95) > 0 else 1.0


def footprint_figure(result, limit: dict | None = None, n_sigma: float = 3.0):
    """Landing points of every law around the target, :data:`FOOTPRINT_RADII` success radii
    either side; points beyond are drawn on the frame's edge in their direction (open
    markers) and counted in the legend; the ``n_sigma`` ellipse of each law's successful
    landings (:func:`~guidance.campaign.statistics.footprint_ellipse`)."""
    plt = _pyplot()
    from matplotlib.patches import Ellipse

    labels, key = law_labels(result.cases)
    half = _footprint_frame(result, limit)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    fig, ax = plt.subplots(figsize=(8.6, 6.0))
    for j, (name, rows) in enumerate(result.cases.items()):
        c = colors[j % len(colors)]
        off = np.stack([np.asarray(rows["downrange_offset_m"], dtype=np.float64),
                        np.asarray(rows["crossrange_offset_m"], dtype=np.float64)], 1)
        ok = np.asarray(rows["success"], dtype=bool)
        found = np.all(np.isfinite(off), axis=1)
        reach = np.abs(off).max(axis=1)
        inside = found & (reach <= half)
        out = found & ~inside
        ax.plot(off[inside, 0], off[inside, 1], ".", ms=3, color=c, alpha=0.6,
                label=labels[name] + _beyond(int(out.sum()), "beyond the frame, on its edge")
                + _beyond(int((~found).sum()), "without a landing point"))
        if out.any():
            edge = off[out] * (half / reach[out])[:, None]
            ax.plot(edge[:, 0], edge[:, 1], "o", ms=5, mfc="none", color=c, clip_on=False)
        tag = labels[name].split(":", 1)[0] if key else name
        ell = footprint_ellipse(off[ok], n_sigma=n_sigma)
        if ell:
            ax.add_patch(Ellipse((ell["center_downrange_m"], ell["center_crossrange_m"]),
                                 2 * ell["semi_major_m"], 2 * ell["semi_minor_m"],
                                 angle=ell["angle_deg"], fill=False, color=c, lw=1.4,
                                 label=f"{n_sigma:g}σ ellipse of {tag}: its "
                                       f"{ell['points']} successful landings"))
    if limit and limit.get("miss_m"):
        ax.add_patch(plt.Circle((0, 0), limit["miss_m"], fill=False, ls="--", color="k",
                                lw=0.8, label=f"success radius {limit['miss_m']:g} m"))
    ax.set_xlim(-half, half)
    ax.set_ylim(-half, half)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("downrange from the target (m)")
    ax.set_ylabel("crossrange from the target (m)")
    ax.set_title(f"landing footprint, {n_sigma:g}σ ellipses of the successful landings\n"
                 f"{_title(result)}", fontsize=9)
    ax.grid(alpha=0.3)
    _finish(fig, ax, key, markerscale=2.0)
    return fig


def fuel_gap_figure(result, limit: dict | None = None):
    """Fuel gap to the omniscient optimum (%) against touchdown speed, per case: speeds from
    0 to :data:`SPEED_LIMITS` success speeds, gaps over the bulk of the cases shown
    (:func:`_gap_frame`); points beyond are drawn on the frame's edge (open markers) and
    counted in the legend."""
    plt = _pyplot()
    labels, key = law_labels(result.cases)
    vmax = _speed_frame(result, limit)
    ref = np.asarray(result.reference["omniscient_fuel_kg"], dtype=np.float64)
    gaps = {name: 100.0 * (np.asarray(rows["fuel_kg"], dtype=np.float64) - ref) / ref
            for name, rows in result.cases.items()}
    lo, hi = _gap_frame(result, gaps, vmax)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    fig, ax = plt.subplots(figsize=(8.4, 4.2))
    for j, (name, rows) in enumerate(result.cases.items()):
        c = colors[j % len(colors)]
        v = np.asarray(rows["touchdown_speed_m_s"], dtype=np.float64)
        g = gaps[name]
        both = np.isfinite(v) & np.isfinite(g)
        inside = both & (v <= vmax) & (g >= lo) & (g <= hi)
        out = both & ~inside
        ax.plot(v[inside], g[inside], ".", ms=3, alpha=0.6, color=c,
                label=labels[name] + _beyond(int(out.sum()), "beyond the frame, on its edge"))
        if out.any():
            ax.plot(np.clip(v[out], 0.0, vmax), np.clip(g[out], lo, hi), "o", ms=5,
                    mfc="none", color=c, clip_on=False)
    if limit and limit.get("speed_m_s"):
        ax.axvline(limit["speed_m_s"], color="k", ls="--", lw=0.8,
                   label=f"success limit {limit['speed_m_s']:g} m/s")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlim(0.0, vmax)
    ax.set_ylim(lo, hi)
    ax.set_xlabel("touchdown (gate) speed (m/s)")
    ax.set_ylabel("fuel gap to the omniscient optimum (%)")
    ax.set_title(_title(result), fontsize=9)
    ax.grid(alpha=0.3)
    _finish(fig, ax, key, markerscale=2.0)
    return fig


def _gap_frame(result, gaps: dict[str, np.ndarray], vmax: float) -> tuple[float, float]:
    """The fuel-gap axis (%): the 5th to 95th percentile of the gaps of the cases inside the
    speed frame, 0 included, widened by half their range each way (a few far cases, such as
    a crash on little propellant, do not set it)."""
    shown = np.concatenate([g[np.asarray(result.cases[n]["touchdown_speed_m_s"],
                                         dtype=np.float64) <= vmax]
                            for n, g in gaps.items()])
    shown = shown[np.isfinite(shown)]
    if not len(shown):
        return -1.0, 1.0
    lo = min(float(np.percentile(shown, 5)), 0.0)
    hi = max(float(np.percentile(shown, 95)), 0.0)
    pad = 0.5 * (hi - lo) if hi > lo else 1.0
    return lo - pad, hi + pad


def robustness_figure(result):
    """Success rate (with its 95 % Wilson interval) against error scale, per law; None
    without a curve."""
    if not any(result.curve.values()):
        return None
    plt = _pyplot()
    labels, key = law_labels(result.curve)
    cfg = result.config
    fig, ax = plt.subplots(figsize=(8.4, 4.2))
    for name, pts in result.curve.items():
        if not pts:
            continue
        s = [p[0] for p in pts]
        rate = [p[1] / p[2] for p in pts]
        ci = np.array([wilson_interval(p[1], p[2]) for p in pts])
        err = np.clip([np.subtract(rate, ci[:, 0]), ci[:, 1] - rate], 0.0, None)
        ax.errorbar(s, rate, yerr=err, marker="o", capsize=3, label=labels[name])
    ax.set_xlabel(f"error scale (× '{cfg.uncertainty.name}')")
    ax.set_ylabel("success rate")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(f"robustness curve, {cfg.env_id} ({cfg.curve_n} cases a point)", fontsize=9)
    ax.grid(alpha=0.3)
    _finish(fig, ax, key)
    return fig


def _success_limits(cfg) -> dict | None:
    """The env's success thresholds (``speed_m_s``, ``miss_m``), or None if it has none."""
    try:
        import gymnasium as gym

        import lunar_env  # noqa: F401

        env = gym.make(cfg.env_id, **cfg.env_kwargs)
        limit = env.unwrapped.success_thresholds
        env.close()
    except Exception:  # noqa: BLE001  (plots without the limit lines)
        return None
    return limit if all(math.isfinite(float(v)) for v in limit.values()) else None


def plot_campaign(result, out_dir: str | Path, has_target: bool) -> list[Path]:
    """Write the campaign's figures into ``out_dir``; returns their paths."""
    plt = _pyplot()
    out = Path(out_dir)
    limit = _success_limits(result.config)
    figures = [("touchdown_speed_cdf.png", speed_cdf_figure(result, limit))]
    if has_target:
        figures.append(("footprint.png", footprint_figure(result, limit)))
    figures.append(("fuel_gap_vs_speed.png", fuel_gap_figure(result, limit)))
    figures.append(("robustness.png", robustness_figure(result)))
    paths = []
    for name, fig in figures:
        if fig is None:
            continue
        paths.append(save_figure_atomic(fig, out / name, dpi=120, bbox_inches="tight"))
        plt.close(fig)
    return paths
