"""``python -m optimizers.reproduce zhu2007``: quick version (default run) and the full one."""

import json

import pytest

from optimizers.reproduce.zhu2007 import PUBLISHED, main


def _run(tmp_path, *extra):
    out = tmp_path / "zhu2007.json"
    rc = main([*extra, "--json", str(out), "--out", str(tmp_path / "plots")])
    assert rc == 0
    return json.loads(out.read_text())


def test_quick_reproduction_json_and_plots(tmp_path):
    d = _run(tmp_path, "--quick")
    assert set(d) == {"published", "measured"}
    assert d["published"]["optimum_fuel_kg"] == PUBLISHED["optimum_fuel_kg"]
    m = d["measured"]
    for key in ("n_runs", "n_converged", "mean_speed_m_s", "mean_final_radius_m", "mean_fuel_kg",
                "best_speed_m_s", "best_final_radius_m", "best_fuel_kg", "optimum_fuel_kg",
                "best_gap_kg", "mean_gap_kg", "wall_s_per_run_mean", "runs", "pontryagin",
                "parameterisation_optimum"):
        assert key in m, key
    assert m["n_runs"] == len(m["runs"]) == 2
    v = m["variant"]  # ASAGA's spread-temperature variant on the same seeds
    assert v["temperature_scale"] == "spread" and len(v["runs"]) == 2
    # physically sane: fuel is ṁ·tf with tf in the bounds [500, 700] s (capped by the dry mass)
    mdot = 1350.0 / (300 * 9.8)
    for r in m["runs"]:
        assert 500 * mdot - 1e-9 <= r["fuel_kg"] <= 300.0
        assert r["fuel_kg"] == pytest.approx(min(mdot * r["tf_s"], 300.0), rel=1e-9)
        assert abs(r["terminal_errors"]["radius_m"]) < 2e5
    # certification: Pontryagin and SLSQP on the cubic are two methods; they agree to 0.01 kg
    p = m["pontryagin"]
    assert p["success"] and abs(p["terminal_errors"]["speed_m_s"]) < 1e-6
    assert abs(p["terminal_errors"]["radius_m"]) < 1e-6
    c = m["parameterisation_optimum"]
    assert c["success"] and c["fuel_kg"] >= p["fuel_kg"] - 1e-3
    assert abs(c["fuel_kg"] - p["fuel_kg"]) < 0.01
    assert m["optimum_fuel_kg"] == pytest.approx(p["fuel_kg"])
    assert m["best_gap_kg"] == pytest.approx(m["best_fuel_kg"] - p["fuel_kg"])
    assert len(m["plots"]) == 5
    for path in m["plots"]:
        assert (tmp_path / "plots").joinpath(path.split("/")[-1]).stat().st_size > 1000


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=(
    "Does not reproduce (measured, see the ASAGA docstring): with the "
    "paper's settings ASAGA's final moves are too coarse and, in the paper's normalised units, "
    "its Metropolis rule accepts ~100% of moves, so runs end metres/km and m/s off target; our "
    "optimum (Pontryagin and SLSQP on the cubic agree) is 277.5852 kg, not 277.5765 kg."))
def test_full_reproduction_targets(tmp_path):
    """The reproduction's targets at the paper's settings (10 runs × 300 generations)."""
    m = _run(tmp_path, "--no-plots")["measured"]
    assert m["n_converged"] == 10
    assert m["mean_fuel_kg"] <= PUBLISHED["mean_fuel_kg"] + 0.05
    assert m["best_fuel_kg"] <= 277.63
    assert m["optimum_fuel_kg"] == pytest.approx(PUBLISHED["optimum_fuel_kg"], abs=0.001)
