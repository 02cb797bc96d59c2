"""Campaigns: the same case k for every law, chunking and worker count; resume after a stop;
the JSON contract; the command line."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from agents.campaign import format_table, main
from agents.common.law import GuidanceLaw
from agents.evaluation.campaign import (
    CampaignConfig,
    footprint_ellipse,
    run_campaign,
    wilson_interval,
)

ENV = "LunarSoftLanding-v0"

CONTRACT_KEYS = {"success_rate", "success_ci95", "touchdown_speed_p50_m_s",
                 "touchdown_speed_p99_m_s", "touchdown_speed_max_m_s", "fuel_p50_kg",
                 "fuel_p99_kg", "fuel_gap_p50_pct", "fuel_gap_p99_pct",
                 "propellant_margin_p1_kg", "us_per_decision"}


def _config(**kw):
    base = dict(env_id=ENV, uncertainty="standard", cases=6, seed=3,
                laws=("open-loop",), chunk=3, scales=(0.0, 1.0), curve_cases=3)
    base.update(kw)
    return CampaignConfig(**base)


@pytest.fixture(scope="module")
def reference_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("camp")
    return run_campaign(_config(), out, workers=0, progress=False, plots=True), out


def test_contract_and_files(reference_run):
    res, out = reference_run
    s = json.loads((out / "campaign.json").read_text())
    assert s["schema"] == 1 and s["env"] == ENV and s["uncertainty"] == "standard"
    assert s["cases"] == 6 and s["seed"] == 3
    law = s["laws"]["open-loop"]
    assert CONTRACT_KEYS <= set(law)
    assert 0.0 <= law["success_rate"] <= 1.0
    lo, hi = law["success_ci95"]
    assert lo <= law["success_rate"] <= hi
    assert [p["scale"] for p in s["robustness_curve"]["open-loop"]] == [0.0, 1.0]
    # at zero error the open-loop optimum lands every case
    assert s["robustness_curve"]["open-loop"][0]["success_rate"] == 1.0
    rows = (out / "cases.csv").read_text().splitlines()
    assert len(rows) == 1 + 6 and rows[0].startswith("law,case,success")
    for f in ("touchdown_speed_cdf.png", "fuel_gap_vs_speed.png", "robustness.png"):
        assert (out / f).stat().st_size > 1000
    assert "open-loop" in format_table(s)
    # the omniscient reference: every case solved, each within the propellant budget
    ref = res.reference["omniscient_fuel_kg"]
    assert np.all(np.isfinite(ref)) and np.all((ref > 200) & (ref < 300))


def test_case_k_is_the_same_whatever_the_chunking_and_workers(reference_run, tmp_path):
    """Two chunks of 3 in this process against one chunk of 6 in a worker process: every
    per-case number is identical, and so is the reference."""
    res, _ = reference_run
    other = run_campaign(_config(chunk=6, scales=()), tmp_path, workers=1, progress=False,
                         plots=False)
    for key, a in res.cases["open-loop"].items():
        if key != "us_per_decision":
            np.testing.assert_array_equal(a, other.cases["open-loop"][key], err_msg=key)
    for key, a in res.reference.items():
        np.testing.assert_array_equal(a, other.reference[key], err_msg=key)


class _Brake(GuidanceLaw):
    """Full braking against the navigated velocity (a law that lands nothing softly)."""

    name = "brake"

    def act(self, nav):
        return np.zeros((nav.n, 1), dtype=np.float32)


def test_every_law_flies_the_same_cases(tmp_path, monkeypatch):
    """The flights of two different laws see identical plant errors: their episode errors,
    read back from the env of each task, are equal (common random numbers across laws)."""
    from agents.common import law_specs, rollout

    seen = {}
    real_fly = rollout.fly

    def spy(env_id, law, n, **kw):
        import gymnasium as gym

        v = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                         **kw["env_kwargs"])
        v.reset(seed=kw["seed"])
        seen[law.name] = v.unwrapped.episode_errors
        return real_fly(env_id, law, n, **kw)

    monkeypatch.setattr(rollout, "fly", spy)
    monkeypatch.setitem(law_specs.LAW_ENTRY_POINTS, "brake", "tests.agents.test_campaign:_make")
    run_campaign(_config(laws=("open-loop", "brake"), cases=3, scales=()), tmp_path,
                 workers=0, progress=False, plots=False)
    a, b = seen["open-loop"], seen["brake"]
    for key, v in a.as_dict().items():
        np.testing.assert_array_equal(v, getattr(b, key), err_msg=key)


def _make(spec, context):
    return _Brake()


def test_a_stopped_campaign_resumes_to_the_same_table(reference_run, tmp_path):
    """Stopped after 2 of its tasks (as a kill between tasks leaves it: finished tasks are
    stored atomically), the rerun does the rest and ends with the table of the uninterrupted
    run."""
    res, _ = reference_run
    with pytest.raises(RuntimeError, match="run it again to resume"):
        run_campaign(_config(), tmp_path, workers=0, progress=False, plots=False, max_tasks=2)
    stored = list((tmp_path / "store" / "results").glob("*.json"))
    assert len(stored) == 2
    again = run_campaign(_config(), tmp_path, workers=0, progress=False, plots=False)
    a = dict(res.summary)
    b = dict(again.summary)
    for s in (a, b):
        s.pop("wall_s")
        s["reference"].pop("wall_s")
        for law in s["laws"].values():
            law.pop("us_per_decision")
    assert a == b


def test_a_store_of_other_settings_is_refused(reference_run):
    _, out = reference_run
    with pytest.raises(ValueError, match="another study"):
        run_campaign(_config(seed=4), out, workers=0, progress=False, plots=False)


def test_statistics():
    lo, hi = wilson_interval(95, 100)
    assert lo == pytest.approx(0.8882, abs=1e-3) and hi == pytest.approx(0.9785, abs=1e-3)
    assert wilson_interval(0, 10)[0] == 0.0 and wilson_interval(10, 10)[1] == 1.0
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(20000, 2)) * [30.0, 10.0]
    e = footprint_ellipse(pts)
    assert e["semi_major_m"] == pytest.approx(90.0, rel=0.03)
    assert e["semi_minor_m"] == pytest.approx(30.0, rel=0.03)
    assert math.cos(math.radians(e["angle_deg"])) ** 2 == pytest.approx(1.0, abs=1e-3)


@pytest.mark.parametrize("argv, message", [
    (["--laws", "nope"], "unknown law 'nope'"),
    (["--laws", "open-loop", "--uncertainty", "huge"], "unknown uncertainty set"),
    (["--laws", "open-loop", "--uncertainty", '{"thrust_scale": -1}'], "thrust_scale"),
    (["--laws", "open-loop", "--env", "Nope-v0"], "Nope-v0"),
    (["--laws", "open-loop", "--cases", "0"], "cases"),
    ([], "--laws is required"),
])
def test_command_line_errors_exit_2_with_one_line(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_bad_configs_are_refused():
    with pytest.raises(ValueError, match="given twice"):
        _config(laws=("open-loop", "open-loop"))
    with pytest.raises(ValueError, match="scale"):
        _config(scales=(-1.0,))
    with pytest.raises(ValueError, match="--uncertainty"):
        _config(env_kwargs={"uncertainty": "none"})
