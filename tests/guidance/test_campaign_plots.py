"""Campaign figures a GNC engineer can read: each frame drawn around the success limits, not
around one far outlier; outliers on the frame's edge and counted in the legend; the 3σ
ellipses of the successful landings; legends outside the data; long law specs keyed."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from guidance.campaign.plots import (  # noqa: E402
    FOOTPRINT_RADII,
    SPEED_LIMITS,
    footprint_figure,
    fuel_gap_figure,
    law_labels,
    plot_campaign,
    robustness_figure,
    speed_cdf_figure,
)
from guidance.campaign.run import CampaignConfig, CampaignResult  # noqa: E402

LONG = "apollo:kr=10,tgo_margin=0.02,lead=2.2,terminal=3"
LIMIT = {"speed_m_s": 5.0, "miss_m": 500.0}
#: the outlier: a crash 1,452 km downrange at 618 m/s on 60 % of the optimum's propellant
OUTLIER = 7


@pytest.fixture(scope="module")
def result():
    """A pinpoint campaign of two laws over 200 cases, landings within ~300 m of the target at
    ~2 m/s, but for case 7 of each law."""
    cfg = CampaignConfig(env_id="LunarPinpointLanding-v2", uncertainty="standard", cases=200,
                         seed=0, laws=("apollo", LONG), scales=(0.0, 1.0), curve_cases=50)
    rng = np.random.default_rng(0)
    n = 200
    ref = 280.0 + rng.normal(0.0, 2.0, n)
    cases = {}
    for j, name in enumerate(cfg.laws):
        off = rng.normal(0.0, [100.0, 50.0], (n, 2)) + [30.0 * j, 0.0]
        speed = np.abs(rng.normal(2.0, 0.6, n))
        fuel = ref * (1.02 + 0.005 * rng.normal(size=n))
        ok = np.ones(n, dtype=bool)
        off[OUTLIER] = [1.452e6, 3.0e3]
        speed[OUTLIER], fuel[OUTLIER], ok[OUTLIER] = 618.0, 0.6 * ref[OUTLIER], False
        cases[name] = {"success": ok, "touchdown_speed_m_s": speed,
                       "miss_distance_m": np.hypot(off[:, 0], off[:, 1]), "fuel_kg": fuel,
                       "downrange_offset_m": off[:, 0], "crossrange_offset_m": off[:, 1]}
    curve = {name: [(0.0, 50, 50), (1.0, 49, 50)] for name in cases}
    return CampaignResult(cfg, cases, {"omniscient_fuel_kg": ref}, curve, {}, 1.0)


def _legend_outside(fig, ax) -> None:
    fig.canvas.draw()
    legend = ax.get_legend().get_window_extent()
    assert legend.x0 >= ax.get_window_extent().x1  # right of the axes, over no data


def _texts(ax) -> list[str]:
    return [t.get_text() for t in ax.get_legend().get_texts()]


def test_the_footprint_is_framed_by_the_success_radius(result):
    """±3 success radii, not ±1.5e6 m; the outlier on the edge, counted; each ellipse over the
    199 successful landings (semi-axes ~3 × 100 m and 3 × 50 m), not a line drawn by the
    outlier."""
    from matplotlib.patches import Circle, Ellipse

    fig = footprint_figure(result, LIMIT)
    (ax,) = fig.axes[:1]
    half = FOOTPRINT_RADII * LIMIT["miss_m"]
    assert ax.get_xlim() == pytest.approx((-half, half))
    assert ax.get_ylim() == pytest.approx((-half, half))
    texts = _texts(ax)
    assert "apollo (1 beyond the frame, on its edge)" in texts[0]
    ellipses = [p for p in ax.patches if isinstance(p, Ellipse) and not isinstance(p, Circle)]
    assert len(ellipses) == 2
    for e in ellipses:
        assert 500.0 < e.width < 700.0 and 250.0 < e.height < 350.0  # 2 × 3σ
    assert sum("its 199 successful landings" in t for t in texts) == 2
    # the outlier drawn on the frame's right edge, in its direction
    edge = [ln for ln in ax.lines if ln.get_marker() == "o"]
    assert len(edge) == 2
    for ln in edge:
        assert ln.get_xdata()[0] == pytest.approx(half)
        assert ln.get_ydata()[0] == pytest.approx(3.0e3 * half / 1.452e6)
    _legend_outside(fig, ax)


def test_the_speed_cdf_and_the_fuel_gap_are_framed_by_the_success_limits(result):
    vmax = SPEED_LIMITS * LIMIT["speed_m_s"]
    cdf = speed_cdf_figure(result, LIMIT)
    ax = cdf.axes[0]
    assert ax.get_xlim() == pytest.approx((0.0, vmax))
    assert ax.get_ylim() == pytest.approx((0.0, 1.02))
    assert any(t.endswith(f"(1 beyond {vmax:g} m/s)") for t in _texts(ax))
    curve = ax.lines[0]
    assert curve.get_ydata()[-1] == pytest.approx(199 / 200)  # the outlier is beyond the frame
    _legend_outside(cdf, ax)
    gap = fuel_gap_figure(result, LIMIT)
    ax = gap.axes[0]
    assert ax.get_xlim() == pytest.approx((0.0, vmax))
    lo, hi = ax.get_ylim()
    assert -2.0 < lo <= 0.0 and 2.0 < hi < 6.0  # the bulk's ~2 % gap, not the -40 % crash
    assert any("1 beyond the frame, on its edge" in t for t in _texts(ax))
    _legend_outside(gap, ax)


def test_long_law_specs_are_numbered_with_a_key(result):
    labels, key = law_labels(result.cases)
    assert labels["apollo"] == "1: apollo"
    assert labels[LONG].startswith("2: apollo:kr=10") and labels[LONG].endswith("…")
    assert key == f"2: {LONG}"
    fig = robustness_figure(result)
    assert [t.get_text() for t in fig.texts] == [key]
    assert law_labels(["apollo", "zem-zev"]) == ({"apollo": "apollo", "zem-zev": "zem-zev"},
                                                  None)


def test_plot_campaign_writes_every_figure(result, tmp_path):
    paths = plot_campaign(result, tmp_path, has_target=True)
    assert [p.name for p in paths] == ["touchdown_speed_cdf.png", "footprint.png",
                                       "fuel_gap_vs_speed.png", "robustness.png"]
    assert all(p.stat().st_size > 1000 for p in paths)
