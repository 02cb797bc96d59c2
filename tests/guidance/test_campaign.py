"""Campaigns: the same case k for every law, chunking and worker count; resume after a stop;
the JSON contract; the command line."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from guidance.campaign.cli import format_table, main
from guidance.campaign.run import CampaignConfig, run_campaign
from guidance.campaign.statistics import footprint_ellipse, wilson_interval
from guidance.law import GuidanceLaw
from optimizers.optimum.planar import PONTRYAGIN as PLANAR_PONTRYAGIN

ENV = "LunarSoftLanding-v0"

CONTRACT_KEYS = {"success_rate", "success_ci95", "touchdown_speed_p50_m_s",
                 "touchdown_speed_p99_m_s", "touchdown_speed_max_m_s", "fuel_p50_kg",
                 "fuel_p99_kg", "fuel_gap_p50_pct", "fuel_gap_p99_pct",
                 "propellant_margin_p1_kg", "us_per_decision"}


#: the standard set without its Isp error: every case's omniscient optimum then shares the
#: nominal shooting functions (an Isp error builds its own, ~1.5 s a case)
MODEL = {"base": "standard", "isp_scale": 0.0}


def _config(**kw):
    base = dict(env_id=ENV, uncertainty=MODEL, cases=4, seed=3,
                laws=("open-loop",), chunk=2, scales=(0.0, 1.0), curve_cases=2)
    base.update(kw)
    return CampaignConfig(**base)


@pytest.fixture(scope="module")
def reference_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("camp")
    return run_campaign(_config(), out, workers=0, progress=False, plots=True), out


def test_contract_and_files(reference_run):
    res, out = reference_run
    s = json.loads((out / "campaign.json").read_text())
    assert s["schema"] == 1 and s["env"] == ENV and s["uncertainty"] == "custom"
    assert s["cases"] == 4 and s["seed"] == 3
    law = s["laws"]["open-loop"]
    assert CONTRACT_KEYS <= set(law)
    assert [p["scale"] for p in s["robustness_curve"]["open-loop"]] == [0.0, 1.0]
    # at zero error the open-loop optimum lands every case
    assert s["robustness_curve"]["open-loop"][0]["success_rate"] == 1.0
    rows = (out / "cases.csv").read_text().splitlines()
    assert len(rows) == 1 + 4 and rows[0].startswith("law,case,success")
    # the rate is the share of the cases landed, and its interval the Wilson score interval
    # of that count (z = 1.96), computed here from the per-case rows
    cases = list(csv.DictReader(rows))
    assert [c["law"] for c in cases] == ["open-loop"] * 4
    k = sum(c["success"] == "True" for c in cases)
    assert law["successes"] == k and law["success_rate"] == k / 4
    assert law["success_rate"] == np.mean(res.cases["open-loop"]["success"])
    z, n = 1.959963984540054, 4
    centre = (k / n + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(k / n * (1 - k / n) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    want = (0.0 if k == 0 else centre - half, 1.0 if k == n else centre + half)
    np.testing.assert_allclose(law["success_ci95"], want, rtol=0.0, atol=1e-12)
    # the curve at scale 1 flies the first two cases again: their outcomes
    at_one = s["robustness_curve"]["open-loop"][1]
    assert at_one["cases"] == 2
    assert at_one["success_rate"] == sum(c["success"] == "True" for c in cases[:2]) / 2
    for f in ("touchdown_speed_cdf.png", "fuel_gap_vs_speed.png", "robustness.png"):
        assert (out / f).stat().st_size > 1000
    assert "open-loop" in format_table(s)
    # the omniscient reference: every case solved, each within the propellant budget
    ref = res.reference["omniscient_fuel_kg"]
    assert np.all(np.isfinite(ref)) and np.all((ref > 200) & (ref < 300))
    assert s["reference"]["converged_by"] == {PLANAR_PONTRYAGIN: 4}
    assert all(r.endswith(f",{PLANAR_PONTRYAGIN}") for r in rows[1:])


def test_case_k_is_the_same_whatever_the_chunking_and_workers(reference_run, tmp_path):
    """Two chunks of 2 in this process against one chunk of 4 in a worker process: every
    per-case number is identical, and so is the reference."""
    res, _ = reference_run
    other = run_campaign(_config(chunk=4, scales=()), tmp_path, workers=1, progress=False,
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
    from guidance import flight, registry

    seen = {}
    real_fly = flight.fly

    def spy(env_id, law, n, **kw):
        import gymnasium as gym

        v = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                         **kw["env_kwargs"])
        v.reset(seed=kw["seed"])
        seen[law.name] = v.unwrapped.episode_errors
        return real_fly(env_id, law, n, **kw)

    monkeypatch.setattr(flight, "fly", spy)
    monkeypatch.setattr(registry, "_REGISTRY", dict(registry._REGISTRY))  # undone after
    registry.register_law("brake", _make)
    run_campaign(_config(laws=("open-loop", "brake"), cases=2, scales=()), tmp_path,
                 workers=0, progress=False, plots=False)
    a, b = seen["open-loop"], seen["brake"]
    for key, v in a.as_dict().items():
        np.testing.assert_array_equal(v, getattr(b, key), err_msg=key)


def _make(spec, context):
    return _Brake()


def test_a_stopped_campaign_resumes_to_the_same_table(reference_run, tmp_path):
    """A campaign stopped part-way (its finished tasks stored, as a kill between tasks leaves
    them: each is written atomically) resumes: the rerun flies only the missing tasks and ends
    with the table of the uninterrupted run. Here: the finished run's store with two of its
    five results removed (a reference chunk and a flight chunk), and a run stopped after one
    task."""
    import shutil

    res, out = reference_run
    shutil.copytree(out / "store", tmp_path / "store")
    stored = sorted((tmp_path / "store" / "results").glob("*.json"))
    assert len(stored) == 5
    for f in (stored[0], stored[-1]):
        f.unlink()
    again = run_campaign(_config(), tmp_path, workers=0, progress=False, plots=False)
    assert len(list((tmp_path / "store" / "results").glob("*.json"))) == 5
    with pytest.raises(RuntimeError, match="run it again to resume"):
        run_campaign(_config(), tmp_path / "fresh", workers=0, progress=False, plots=False,
                     max_tasks=1)
    assert len(list((tmp_path / "fresh" / "store" / "results").glob("*.json"))) == 1
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


def test_thrust_error_as_a_mass_change_is_exact():
    """The planar omniscient optimum solves a thrust error k_T as the nominal engine from
    m0 / k_T (fuel × k_T): the same optimum as shooting functions built for k_T·F."""
    import gymnasium as gym

    from guidance.laws.pontryagin_planar import planar_state_si
    from optimizers.indirect.planar import solve_planar_min_fuel
    from optimizers.optimum import optimum_family, plant_scenario

    v = gym.make_vec(ENV, num_envs=1, vectorization_mode="vector_entry_point",
                     uncertainty=MODEL)
    v.reset(seed=0, options={"errors": {"thrust_scale": 0.97}})
    c = v.unwrapped
    got = optimum_family(c).plant_optimum_fuel(c.scenario, c.state_nd, [0.97], [1.0]).fuel_kg[0]
    row = planar_state_si(c.scenario, c.state_nd)[0]
    direct = solve_planar_min_fuel(plant_scenario(c.scenario, 0.97, 1.0), row, check="grid")
    assert direct.success
    assert got == pytest.approx(direct.fuel_kg, rel=1e-10)
    nominal = solve_planar_min_fuel(c.scenario, row, check="grid").fuel_kg
    assert got > nominal + 0.3  # a weaker engine lands on more propellant (gravity losses)


def _pinpoint_campaign_cases(idx):
    """Cases ``idx`` of the pinpoint campaign on ``standard`` (seed 0, dt 2 s, first chunk of
    100): true starts, thrust and Isp scales, and the env's scenario."""
    from guidance.campaign.run import _env_kwargs, _starts
    from lunar_env.uncertainty import resolve_uncertainty

    kw = _env_kwargs({"dt_s": 2.0}, resolve_uncertainty("standard").as_dict(), 1.0)
    truth, _, err, core = _starts("LunarPinpointLanding-v2", kw, 100, 0)
    return truth[idx], err.thrust_scale[idx], err.isp_scale[idx], core


def test_pinpoint_reference_falls_back_to_the_direct_optimum_only_where_pontryagin_fails(
        monkeypatch):
    """Case 27 of the pinpoint campaign (an engine 1.3 % stronger than nominal) has
    no extremal the shooting finds; case 31 has one. The direct optimum is asked for case 27
    only (stood in for here: the slow twin below solves it), its fuel becomes the reference,
    each case names its method, and a case neither method lands stays NaN with no method."""
    from optimizers.optimum import optimum_family
    from optimizers.optimum import pinpoint as pin

    x0, kt, kc, core = _pinpoint_campaign_cases([27, 31])
    asked = []
    direct_lands = [True]

    class Direct:
        def __init__(self, success):
            self.success, self.fuel_kg = success, 123.0

    def fake_solve_case(scenario, x, warm=None):
        asked.append((scenario.vehicle.thrust_n, x.copy(), warm))
        return Direct(direct_lands[0])

    monkeypatch.setattr("optimizers.transcription.batch.solve_case", fake_solve_case)
    fam = optimum_family(core)
    ref = fam.plant_optimum_fuel(core.scenario, x0, kt, kc)
    assert ref.solver == (pin.DIRECT, pin.PONTRYAGIN)
    assert ref.fuel_kg[0] == 123.0 and 270.0 < ref.fuel_kg[1] < 290.0
    assert len(asked) == 1
    thrust, x, warm = asked[0]
    # the true plant from the true start, never warm-started from another case
    assert thrust == pytest.approx(core.scenario.vehicle.thrust_n * kt[0], rel=1e-12)
    assert np.array_equal(x, x0[0]) and warm is None
    direct_lands[0] = False
    ref = fam.plant_optimum_fuel(core.scenario, x0[:1], kt[:1], kc[:1])
    assert np.isnan(ref.fuel_kg[0]) and ref.solver == ("",)


@pytest.mark.slow
def test_pinpoint_reference_of_a_pontryagin_failure_is_the_direct_optimum():
    """Slow twin (~10 s): case 27's reference solved for real. The direct optimum is 276.92 kg
    (flown in the env, it lands); case 31, solved by both
    methods there, agrees within 0.01 kg."""
    from optimizers.optimum import optimum_family
    from optimizers.optimum import pinpoint as pin

    x0, kt, kc, core = _pinpoint_campaign_cases([27, 31])
    ref = optimum_family(core).plant_optimum_fuel(core.scenario, x0, kt, kc)
    assert ref.solver == (pin.DIRECT, pin.PONTRYAGIN)
    assert ref.fuel_kg[0] == pytest.approx(276.917, abs=0.05)
    assert ref.fuel_kg[1] == pytest.approx(277.862, abs=0.01)
