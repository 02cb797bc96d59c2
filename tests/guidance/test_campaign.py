"""Campaigns: the same case k for every law, chunking and worker count; resume after a stop;
the JSON contract; the command line; results that never mix (the store's schema, identity and
keys), one writer per directory, inputs checked before any work, clean interrupts."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from guidance.campaign.cli import format_table, main
from guidance.campaign.run import CampaignConfig, run_campaign, scale_text
from guidance.campaign.statistics import footprint_ellipse, wilson_interval
from guidance.law import GuidanceLaw
from lunar_env.uncertainty import MODEL_VERSION, resolve_uncertainty
from optimizers.common.store import ResultStore, StoreIdentityError, TaskKey
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


_BAD_INPUTS = [
    (["--laws", "nope"], "--laws: unknown law 'nope'"),
    (["--laws", "open-loop", "--uncertainty", "huge"], "--uncertainty: unknown uncertainty set"),
    (["--laws", "open-loop", "--uncertainty", '{"thrust_scale": -1}'],
     "--uncertainty: UncertaintyModel.thrust_scale = -1"),
    (["--laws", "open-loop", "--env", "Nope-v0"], "--env: env 'Nope-v0' is not a registered"),
    (["--laws", "open-loop", "--cases", "0"], "argument --cases: 0 is out of range"),
    ([], "--laws is required"),
    (["--laws", "apollo:kr=abc"], "--laws: law 'apollo:kr=abc': option kr='abc' is not valid"),
    (["--laws", "apollo:kr=-5"], "--laws: law 'apollo:kr=-5': k_r = -5.0 is not allowed"),
    (["--laws", "apollo:bogus=1"], "--laws: law 'apollo:bogus=1': unknown option(s) bogus; "
                                   "allowed: kr,"),
    (["--laws", "ppo:/does/not/exist"], "--laws: law 'ppo:/does/not/exist': run "
                                        "'/does/not/exist' does not exist"),
    (["--laws", "open-loop:x=1"], "--laws: law 'open-loop:x=1': unknown option(s) x"),
    (["--laws", "apollo", "--workers", "-1"], "argument --workers: -1 is out of range; "
                                              "allowed: 0 to"),
    (["--laws", "apollo", "--seed", "-1"], "argument --seed: -1 is out of range; allowed: 0 to "
                                           "2**63 - 1"),
    (["--laws", "apollo", "--seed", str(2**70)], f"argument --seed: {2**70} is out of range"),
    (["--laws", "apollo", "--out", "{file}"], "argument --out: {file} is a file, not a "
                                              "directory"),
    (["--laws", "apollo", "--out", "/dev/null/camp"], "argument --out: /dev/null/camp cannot be "
                                                      "created: /dev/null is a file"),
    (["--laws", "apollo", "--scales", "1.0000001"], "--scales: robustness-curve scale 1.0000001 "
                                                    "is the main run's scale 1 to 6 significant"),
    (["--laws", "apollo", "--scales", "0.5", "0.5000001"], "--scales: robustness-curve scale "
                                                           "0.5000001 is 0.5 to 6 significant"),
    (["--laws", "apollo", "--scales", "0", "10"], "--scales: robustness-curve scale 10 takes the "
                                                  "uncertainty model beyond its limits: "
                                                  "UncertaintyModel.thrust_scale"),
    (["--laws", "apollo", "--scales", "nan"], "argument --scales: nan is out of range"),
    (["--laws", "apollo", "--uncertainty", '{"base": "standard", "mass_kg": 40}', "--scales",
      "2"], "--scales: robustness-curve scale 2: UncertaintyModel.mass_kg = 80 kg (1σ) is not "
            "allowed"),
    (["--laws", "apollo", "--uncertainty", '{"base":"standard","mass_kg":200}'],
     "--uncertainty: UncertaintyModel.mass_kg = 200 kg (1σ) is not allowed for zhu2007"),
    (["--laws", "apollo", "--env-kwargs", "{bad json"], "--env-kwargs: Expecting property name"),
    (["--laws", "apollo", "--env-kwargs", "[1]"], "--env-kwargs: '[1]' is not a JSON dict"),
    (["--laws", "apollo", "--env-kwargs", '{"bogus": 1}'], "--env-kwargs: env "
                                                           "'LunarSoftLanding-v0' refuses"),
    (["--laws", "apollo", "--json", "{tmp}"], "argument --json: {tmp} is a directory; give a "
                                              "file name"),
    (["--laws", "apollo", "--address", "garbage"], "argument --address: 'garbage' is not a Ray"),
    (["--laws", "apollo", "apollo"], "law(s) apollo given twice (--laws)"),
]


@pytest.mark.parametrize("argv, message", _BAD_INPUTS,
                         ids=[" ".join(a)[:50] for a, _ in _BAD_INPUTS])
def test_command_line_errors_exit_2_with_one_line(argv, message, capsys, tmp_path):
    """Every bad input is one argparse-style line naming its option and what is allowed, exit
    2, before any work: nothing is stored in --out."""
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    fill = {"{tmp}": str(tmp_path), "{file}": str(a_file)}
    argv = [fill.get(a, a) for a in argv]
    for k, v in fill.items():
        message = message.replace(k, v)
    out = tmp_path / "out"
    if "--out" not in argv:
        argv += ["--out", str(out)]
    with pytest.raises(SystemExit) as exc:
        main(["--cases", "2", *argv])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    line = err.strip().splitlines()[-1]
    assert line.startswith("python -m guidance.campaign: error: "), line
    assert message in line, line
    assert not (out / "store").exists()


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


# ------------------------------------------------------------------ results that never mix


def _tasks(config):
    from guidance.campaign.run import campaign_tasks, check_laws

    return campaign_tasks(config, check_laws(config))


def _comparable(summary: dict) -> dict:
    s = json.loads(json.dumps(summary))
    s.pop("wall_s", None)
    s["reference"].pop("wall_s", None)
    for law in s["laws"].values():
        law.pop("us_per_decision", None)
    return s


def test_the_schema_refuses_a_chunk_under_another_chunks_key(reference_run):
    """A stored chunk must hold the cases its key names, in lists of one length, with every
    field: chunk 0's cases under chunk 1's key, a list cut short, a missing field are each
    refused (a flight chunk and a reference chunk alike)."""
    from guidance.campaign.run import campaign_schema

    res, out = reference_run
    config = res.config
    tasks, n_cases = _tasks(config)
    schema = campaign_schema(config, n_cases)
    store = ResultStore.existing(out / "store")
    for problem in (_flight_problem(tasks), "reference_v4"):
        k0, k1 = TaskKey(problem, config.seed, 0), TaskKey(problem, config.seed, 1)
        chunk0 = store.get(k0)
        schema(k0, chunk0)
        with pytest.raises(ValueError, match=r"field 'case' = \[0, 1\] is not \[2, 3\]"):
            schema(k1, chunk0)
        short = {**chunk0, "omniscient_fuel_kg" if problem == "reference_v4" else "fuel_kg":
                 chunk0["case"][:1]}
        with pytest.raises(ValueError, match="different lengths"):
            schema(k0, short)
        with pytest.raises(ValueError, match="lacks the field"):
            schema(k0, {k: v for k, v in chunk0.items() if k != "case"})


def _flight_problem(tasks) -> str:
    """The key problem of the main run's flights (scale 1) of the only law."""
    return next(t.key.problem for t in tasks if "@x1/" in t.key.problem)


def test_a_chunk_copied_over_another_is_flown_again(reference_run, tmp_path):
    """Chunk 0 stored again under chunk 1's key, envelope and all (what a copy of
    ``…__000000.json`` over ``…__000001.json`` becomes once re-sealed), and a reference chunk
    copied over its neighbour as it is: both are refused when read, moved aside and computed
    again; the campaign's figures are those of the untouched run."""
    import shutil

    res, out = reference_run
    shutil.copytree(out / "store", tmp_path / "store")
    config = res.config
    tasks, _ = _tasks(config)
    store = ResultStore.existing(tmp_path / "store")
    flight = _flight_problem(tasks)
    store.put(TaskKey(flight, config.seed, 1), store.get(TaskKey(flight, config.seed, 0)))
    ref0 = store.path(TaskKey("reference_v4", config.seed, 0))
    shutil.copyfile(ref0, store.path(TaskKey("reference_v4", config.seed, 1)))
    again = run_campaign(config, tmp_path, workers=0, progress=False, plots=False)
    assert len(list((tmp_path / "store" / "results").glob("*.damaged"))) == 2
    assert _comparable(again.summary) == _comparable(res.summary)
    assert (tmp_path / "cases.csv").read_bytes() == (out / "cases.csv").read_bytes()


def test_the_curve_is_flown_again_when_its_case_count_changes(tmp_path):
    """The robustness curve over 2 cases, then over 3 in the same directory (one chunk of 4
    holds either): the second curve is flown on 3 cases, not read back from the first."""
    kw = dict(laws=("apollo",), cases=4, chunk=4, scales=(0.0,))
    first = run_campaign(_config(curve_cases=2, **kw), tmp_path, workers=0, progress=False,
                         plots=False)
    second = run_campaign(_config(curve_cases=3, **kw), tmp_path, workers=0, progress=False,
                          plots=False)
    assert first.curve["apollo"][0][2] == 2
    assert second.curve["apollo"][0][2] == 3
    fresh = run_campaign(_config(curve_cases=3, **kw), tmp_path / "fresh", workers=0,
                         progress=False, plots=False)
    assert second.curve == fresh.curve


def _ppo_run(run_dir, seed: int) -> None:
    """An untrained PPO model of the planar env (its actions depend on ``seed``)."""
    import gymnasium as gym
    import yaml
    from stable_baselines3 import PPO

    run_dir.mkdir(parents=True, exist_ok=True)
    env = gym.make(ENV, dt_s=2.5)
    PPO("MlpPolicy", env, n_steps=64, batch_size=64, seed=seed,
        device="cpu").save(run_dir / "model.zip")
    (run_dir / "args.yml").write_text(yaml.safe_dump({"algo": "ppo", "env": ENV}))
    (run_dir / "config.yml").write_text(yaml.safe_dump({"env_kwargs": {"dt_s": 2.5}}))


def test_a_learned_law_is_its_run_path_and_its_model_bytes(tmp_path):
    """``ppo:runsB/X_1`` resumed into the directory of ``ppo:runsA/X_1`` (one label, two runs),
    and runsA retrained in place: each is flown, never read back from the other's flights."""
    run_a = tmp_path / "runsA" / "LunarSoftLanding-v0_1"
    run_b = tmp_path / "runsB" / "LunarSoftLanding-v0_1"
    _ppo_run(run_a, seed=0)
    _ppo_run(run_b, seed=1)
    out = tmp_path / "camp"

    def fly(run):
        cfg = _config(laws=(f"ppo:{run}",), cases=2, scales=(), env_kwargs={"dt_s": 2.5})
        res = run_campaign(cfg, out, workers=0, progress=False, plots=False)
        (rows,) = res.cases.values()
        return rows["fuel_kg"], res.summary["law_identity"]

    fuel_a, ident_a = fly(run_a)
    fuel_b, ident_b = fly(run_b)
    assert list(ident_a) == list(ident_b) == ["ppo:LunarSoftLanding-v0_1"]
    (ident_a,), (ident_b,) = ident_a.values(), ident_b.values()
    assert ident_a["spec"] == f"ppo:{run_a}" and ident_b["spec"] == f"ppo:{run_b}"
    assert ident_a["fingerprint"] != ident_b["fingerprint"]
    assert not np.array_equal(fuel_a, fuel_b)  # runsB flown, not runsA's flights read back
    _ppo_run(run_a, seed=2)  # retrained in place
    fuel_a2, ident_a2 = fly(run_a)
    (ident_a2,) = ident_a2.values()
    assert ident_a2["model_sha256"] != ident_a["model_sha256"]
    assert not np.array_equal(fuel_a2, fuel_a)
    assert len(list((out / "store" / "results").glob("ppo*.json"))) == 3


def test_a_law_whose_files_change_during_the_campaign_is_refused(tmp_path):
    """A worker refuses to fly a law whose files differ from those the campaign's keys name."""
    from guidance.campaign.run import fly_chunk

    run = tmp_path / "run"
    _ppo_run(run, seed=0)
    with pytest.raises(RuntimeError, match="its files changed after the campaign started"):
        fly_chunk(f"ppo:{run}", ENV, {"dt_s": 2.5}, resolve_uncertainty(MODEL).as_dict(), 1.0,
                  0, 1, 0, (), {"model_sha256": "0" * 64})


def test_the_identity_records_the_uncertainty_model_version(reference_run, monkeypatch):
    """Results flown under another version of the uncertainty model are another campaign's."""
    from guidance.campaign import run as campaign_run

    res, out = reference_run
    assert res.config.identity()["uncertainty_model_version"] == MODEL_VERSION
    assert res.summary["uncertainty_model_version"] == MODEL_VERSION
    monkeypatch.setattr(campaign_run, "MODEL_VERSION", MODEL_VERSION + 1)
    with pytest.raises(StoreIdentityError, match="uncertainty_model_version"):
        run_campaign(_config(), out, workers=0, progress=False, plots=False)


def test_laws_are_checked_before_any_work(tmp_path):
    """A law that cannot be built stops the campaign before the reference is computed."""
    with pytest.raises(ValueError, match="option kr='abc' is not valid"):
        run_campaign(_config(laws=("open-loop", "apollo:kr=abc")), tmp_path, workers=0,
                     progress=False, plots=False)
    assert not list(tmp_path.rglob("*.json"))


def test_scales_are_checked_and_keyed_exactly():
    assert _config(scales=(0.5, 0.5, 0.0)).scales == (0.5, 0.0)
    with pytest.raises(ValueError, match="main run's scale 1 to 6 significant digits"):
        _config(scales=(1.0000001,))
    with pytest.raises(ValueError, match="thrust_scale"):
        _config(scales=(0.0, 10.0))
    assert scale_text(0.5) == "0.5" and scale_text(0.1234567) == "0.1234567"
    tasks, n_cases = _tasks(_config(scales=(0.0, 0.1234567), laws=("apollo",)))
    assert len({t.key for t in tasks}) == len(tasks)
    assert sorted(n_cases.values()) == [2, 2, 4, 4]


def _cli_args(out) -> list[str]:
    """The command line of the reference run's campaign."""
    return ["--env", ENV, "--uncertainty", json.dumps(MODEL), "--cases", "4", "--seed", "3",
            "--laws", "open-loop", "--chunk", "2", "--scales", "0", "1", "--curve-cases", "2",
            "--workers", "0", "--no-plots", "--no-progress", "--out", str(out)]


@pytest.mark.parametrize("damage", ["missing", "damaged"])
def test_a_lost_identity_refuses_to_resume_in_one_line(reference_run, tmp_path, capsys,
                                                       damage):
    import shutil

    _, out = reference_run
    shutil.copytree(out / "store", tmp_path / "store")
    ident = tmp_path / "store" / "identity.json"
    if damage == "missing":
        ident.unlink()
    else:
        ident.write_text('{"env": ')
    with pytest.raises(SystemExit) as exc:
        main(_cli_args(tmp_path))
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    line = err.strip().splitlines()[-1]
    assert line.startswith(f"python -m guidance.campaign: error: --out {tmp_path}: ")
    assert f"identity.json {'is missing' if damage == 'missing' else 'is unreadable'}" in line
    assert not (tmp_path / "cases.csv").exists()


_HOLD_LOCK = """
    import sys, time
    from optimizers.common.lock import DirectoryLock
    with DirectoryLock(sys.argv[1], what="campaign"):
        print("held", flush=True)
        time.sleep(float(sys.argv[2]))
        open(sys.argv[3], "w").close()  # written before the lock is released
"""


def test_one_writer_per_campaign_directory(reference_run, tmp_path, capsys):
    """While another process holds the campaign directory, the command refuses at once naming
    that process's PID; with --wait it waits for it, then finishes from the stored results."""
    import shutil
    import time

    from proc_helpers import python

    _, out = reference_run
    shutil.copytree(out / "store", tmp_path / "store")
    released = tmp_path.parent / f"{tmp_path.name}.released"
    holder = python(_HOLD_LOCK, str(tmp_path), "3", str(released))
    try:
        assert holder.stdout.readline().decode().strip() == "held"
        t0 = time.monotonic()
        with pytest.raises(SystemExit) as exc:
            main(_cli_args(tmp_path))
        assert exc.value.code == 2 and time.monotonic() - t0 < 3.0  # at once
        line = capsys.readouterr().err.strip().splitlines()[-1]
        assert line.startswith(f"python -m guidance.campaign: error: --out {tmp_path}: ")
        assert f"is in use by process {holder.pid}" in line
        assert main([*_cli_args(tmp_path), "--wait"]) == 0
        assert released.exists()  # it waited for the holder to release the directory
    finally:
        holder.kill()
        holder.wait()
    assert (tmp_path / "cases.csv").read_bytes() == (out / "cases.csv").read_bytes()


# ------------------------------------------------------------------ interrupts and kills

#: a small planar campaign of apollo, long enough to be stopped part-way
_SMALL = ["--env", ENV, "--uncertainty", json.dumps(MODEL), "--cases", "24", "--chunk", "2",
          "--laws", "apollo", "--scales", "--workers", "1", "--no-plots", "--no-progress"]
_CAMPAIGN_CLI = """
    import sys
    from guidance.campaign.cli import main
    sys.exit(main(sys.argv[1:]))
"""


@pytest.fixture(scope="module")
def small_campaign(tmp_path_factory):
    """``cases.csv`` of the small campaign run without interruption."""
    out = tmp_path_factory.mktemp("small") / "out"
    assert main([*_SMALL, "--workers", "0", "--out", str(out)]) == 0
    return (out / "cases.csv").read_bytes()


@pytest.mark.parametrize("sig, status", [("SIGTERM", 143), ("SIGINT", 130), ("SIGKILL", -9)])
def test_an_interrupted_campaign_stops_cleanly_and_resumes_to_the_same_rows(
        small_campaign, tmp_path, sig, status):
    """SIGTERM or SIGINT to a running campaign: its worker stops, the finished tasks stay
    stored, one line is printed, exit 143 / 130; no traceback, no leaked semaphore. SIGKILL:
    nothing printed, the worker ends with it, and the kernel frees the directory's lock. Either
    way the same command then resumes, and ``cases.csv`` is byte for byte that of the
    uninterrupted campaign."""
    import os
    import signal
    import subprocess
    import sys
    import textwrap

    from proc_helpers import REPO, alive, children, wait_for

    out = tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, "-W", "error::UserWarning", "-c",
                             textwrap.dedent(_CAMPAIGN_CLI), *_SMALL, "--out", str(out)],
                            cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    results = out / "store" / "results"
    workers: set[int] = set()

    def started():
        workers.update(children(proc.pid))
        return results.is_dir() and len(list(results.glob("*.json"))) >= 2

    try:
        wait_for(started, 300, proc)
        workers.update(children(proc.pid))
        proc.send_signal(getattr(signal, sig))
        _, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
        proc.wait()
    err = stderr.decode()
    assert proc.returncode == status, err
    if sig != "SIGKILL":
        assert err.strip().splitlines() == ["interrupted; run the same command to resume"], err
    wait_for(lambda: not any(alive(p) for p in workers), 30)  # the worker stopped too
    assert not (out / "cases.csv").exists()  # stopped part-way
    if sig != "SIGKILL":  # a kill may leave a temporary file (ignored), never a damaged one
        assert not list(results.glob(".*tmp"))
    assert not list(results.glob("*.damaged"))
    n_stored = len(list(results.glob("*.json")))
    assert 2 <= n_stored < 24
    assert main([*_SMALL, "--out", str(out)]) == 0
    assert (out / "cases.csv").read_bytes() == small_campaign
