"""``python -m optimizers.reproduce wang2003``: quick version (default run) and the full one."""

import json

import pytest

from optimizers.reproduce.wang2003 import PUBLISHED, main


def _run(tmp_path, *extra):
    out = tmp_path / "wang2003.json"
    assert main([*extra, "--json", str(out), "--out", str(tmp_path / "plots")]) == 0
    return json.loads(out.read_text())


def test_quick_reproduction(tmp_path):
    # 2 runs: the best-run selection must work when the best is not the first run
    d = _run(tmp_path, "--quick", "--runs", "2", "--generations", "20", "--seed", "2")
    assert set(d) == {"published", "measured"}
    assert d["published"]["thrust_n"] == PUBLISHED["thrust_n"]
    m = d["measured"]
    assert m["n_runs"] == len(m["runs"]) == 2
    # fuel of a run is T·tf/(Isp g0) until the propellant above the dry mass (350 kg) is gone
    for r in m["runs"]:
        assert r["fuel_kg"] == pytest.approx(min(r["thrust_n"] * r["tf_s"] / 2940.0, 350.0),
                                             rel=1e-9)
    assert m["fga_best"] in m["runs"]
    # two independent certifiers agree along the curve
    assert m["max_method_disagreement_kg"] < 1e-3
    for c in m["curve"]:
        assert c["indirect"]["success"] and c["collocation"]["success"]
    # the curve has an interior minimum near the paper's T; the optimum over T by both methods
    opt = m["optimum_over_T"]
    assert 2500 < opt["indirect"]["thrust_n"] < 3500
    assert abs(opt["indirect"]["thrust_n"] - opt["collocation"]["thrust_n"]) < 50
    assert abs(opt["indirect"]["fuel_kg"] - opt["collocation"]["fuel_kg"]) < 1e-3
    # the optimum at the published T is a certified landing; its tf exceeds the published one
    at = m["optimum_at_published_T"]
    assert at["indirect"]["success"] and at["tf_s"] > PUBLISHED["tf_s"]
    assert at["radial_speed_peak_m_s"] > 100.0
    assert m["published_tf_terminal_error"]["min_speed_error_m_s"] > 1.0
    assert len(m["plots"]) == 3


@pytest.mark.slow
def test_full_reproduction(tmp_path):
    m = _run(tmp_path)["measured"]
    assert m["n_runs"] == 10 and len(m["curve"]) == 15
