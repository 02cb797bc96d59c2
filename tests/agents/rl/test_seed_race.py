"""Seed race (agents.rl.race): candidates side by side to the end as executor tasks, the
winner's selected policy is the run's."""

import pytest
import yaml

from agents import train as tr
from agents.rl import race as rc

ENV_ID = "LunarPinpointLanding-v2"


def test_race_settings_are_validated():
    assert rc.race_settings({}) is None
    assert rc.race_settings({"seed_race": {"candidates": 3}}) == 3
    assert rc.race_settings({"seed_race": {}}) is None  # an empty entry is no race
    assert rc.race_settings({"seed_race": {"candidates": 2.0}}) == 2
    for bad, match in (({"candidates": 1}, "candidates=1"), ({"candidates": 2.5}, "candidates"),
                       ({"candidates": "two"}, "candidates"),
                       ({"candidates": 2, "decide_at": 0.7}, r"unknown key.*'decide_at'"),
                       ({"decide_at": 1}, r"unknown key.*'decide_at'"),
                       ({"seeds": 2}, "seeds")):
        with pytest.raises(ValueError, match=match):
            rc.race_settings({"seed_race": bad})


@pytest.mark.parametrize("source", ["override", "yaml"])
def test_a_race_key_of_no_meaning_fails_the_run_as_unknown(tmp_path, source):
    """``decide_at`` is no key of a race: set by ``--hyperparams`` or in a YAML entry, the run
    fails naming it as an unknown key, before any candidate trains."""
    args = ["--quick", "--env", ENV_ID, "--seed", "3", "--run-dir", str(tmp_path / "run"),
            "--no-progress", "--no-eval", "--no-tensorboard"]
    race = "{candidates: 2, decide_at: 0.7}"
    if source == "override":
        args += ["--hyperparams", f"seed_race={race}"]
    else:
        f = tmp_path / "ppo.yml"
        f.write_text(yaml.safe_dump({ENV_ID: {"n_envs": 1, "n_timesteps": 64,
                                              "seed_race": yaml.safe_load(race)}}))
        args = [a for a in args if a != "--quick"] + ["--hyperparams-file", str(f)]
    with pytest.raises(ValueError, match=r"seed_race: unknown key\(s\) \['decide_at'\]"):
        tr.main(args)
    assert not (tmp_path / "run" / "race").exists()


def _fake_candidates(run_dir, seeds, steps):
    for s in seeds:
        ck = run_dir / "race" / f"seed_{s}" / "checkpoints"
        ck.mkdir(parents=True)
        (ck / f"rl_model_{steps}_steps.zip").write_bytes(f"model of seed {s}".encode())


@pytest.mark.parametrize("rates, chosen", [((0.0, 0.49), 1), ((0.3, 0.1), 0), ((0.0, 0.0), 0)])
def test_the_seed_whose_final_policy_lands_more_wins(tmp_path, monkeypatch, rates, chosen):
    """Without the candidates' own selection, their final checkpoints are scored here; the
    decision is the env's verdict on the validation cases; a tie keeps the user's seed."""
    import agents.rl.selection as sel

    hp = {"n_timesteps": 352, "seed_race": {"candidates": 2},
          "select_checkpoint": {"states": 7}, "history": 3}
    run = {"env": ENV_ID, "seed": 15}
    _fake_candidates(tmp_path, (15, 16), 352)
    monkeypatch.setattr(rc, "_train_candidates", lambda *a, **k: None)
    seen = {}

    def score(found, env_id, env_kwargs, obs_features, n_states, seed, device, label,
              history=None):
        seen.update(n_states=n_states, seed=seed, keys=[k for k, _ in found], history=history)
        return [{"key": k, "success_rate": r} for (k, _), r in zip(found, rates, strict=True)]

    monkeypatch.setattr(sel, "score_candidates", score)
    out = rc.seed_race(hp, run, tmp_path)
    want = (15, 16)[chosen]
    # the candidates fly with the run's inputs (its history)
    assert seen == {"n_states": 7, "seed": sel.VALIDATION_SEED, "keys": [15, 16], "history": 3}
    assert out["seed"] == want and out["race_seed"] == 15
    assert yaml.safe_load((tmp_path / "args.yml").read_text())["seed"] == want
    decision = yaml.safe_load((tmp_path / "race.yml").read_text())
    assert decision["chosen_seed"] == want and decision["decide_at_steps"] == 352
    assert [s["success_rate"] for s in decision["scores"]] == list(rates)
    # the winner's checkpoints are the run's; a second call (a resume) changes nothing
    assert (tmp_path / "checkpoints" / "rl_model_352_steps.zip").read_bytes() == \
        f"model of seed {want}".encode()
    assert rc.race_done(tmp_path)
    monkeypatch.setattr(sel, "score_candidates", None)  # decided: never scored again
    assert rc.seed_race(hp, out, tmp_path)["seed"] == want


def test_a_race_decided_at_the_end_keeps_the_best_selected_policy(tmp_path, monkeypatch):
    """Each candidate's own checkpoint selection scores it (nothing is scored again), and the
    winner's final policy, not its last checkpoint, becomes the run's."""
    import agents.rl.selection as sel

    hp = {"n_timesteps": 1000, "seed_race": {"candidates": 2},
          "select_checkpoint": {"states": 7}}
    _fake_candidates(tmp_path, (15, 16), 1000)
    for s, rates in ((15, (0.9, 0.97)), (16, (0.98, 0.2))):
        d = tmp_path / "race" / f"seed_{s}"
        (d / "model.zip").write_bytes(f"selected policy of seed {s}".encode())
        (d / "vecnormalize.pkl").write_bytes(f"statistics of seed {s}".encode())
        sel.write_selection(d, sel.VALIDATION_SEED, 7, "steps",
                            [{"key": 900, "success_rate": rates[0], "fuel_mean_kg": 1.0},
                             {"key": 1000, "success_rate": rates[1], "fuel_mean_kg": 1.0}],
                            {"key": 900 if rates[0] > rates[1] else 1000})
    monkeypatch.setattr(rc, "_train_candidates", lambda *a, **k: None)
    monkeypatch.setattr(sel, "score_candidates", None)
    out = rc.seed_race(hp, {"env": ENV_ID, "seed": 15}, tmp_path)
    assert out["seed"] == 16
    decision = yaml.safe_load((tmp_path / "race.yml").read_text())
    assert [c["success_rate"] for c in decision["scores"]] == [0.97, 0.98]
    assert (tmp_path / "model.zip").read_bytes() == b"selected policy of seed 16"
    assert (tmp_path / "vecnormalize.pkl").read_bytes() == b"statistics of seed 16"
    assert yaml.safe_load((tmp_path / "selection.yml").read_text())["chosen_steps"] == 900
    assert rc.race_trained_to_end(hp, tmp_path)
    assert not rc.race_trained_to_end(dict(hp, n_timesteps=2000), tmp_path)  # -n extends it


def _quick_race(tmp_path, n_timesteps: int, extra=()):
    """``train.py --quick`` on the pinpoint env with a race of seeds 3 and 4; the run dir."""
    run_dir = tmp_path / "run"
    assert tr.main(["--quick", "--env", ENV_ID, "--seed", "3", "--run-dir", str(run_dir),
                    "--no-progress", "--no-eval", "--no-tensorboard",
                    "--hyperparams", "seed_race={candidates: 2}",
                    f"n_timesteps={n_timesteps}", *extra]) == 0
    return run_dir


@pytest.mark.slow
def test_quick_race_end_to_end_and_its_resume(tmp_path, capfd):
    """(``slow``: its quick twin in the default run is ``tests/agents/
    test_run_dirs_and_resume.py::test_seed_race_stopped_by_sigterm_checkpoints_every_candidate_
    and_resumes``, a race stopped, resumed, decided and adopted.)

    Both quick candidates train to the end and select their checkpoints in executor worker
    processes; the run adopts the winner's selected policy without training again. Resuming a
    race interrupted after one candidate finished trains only the other one (from its own
    checkpoint), and the race is decided again."""
    run_dir = _quick_race(tmp_path, 2048)
    out = capfd.readouterr().out
    assert "[seed 3] selection: the checkpoint" in out and "[seed 4] selection" in out
    assert "[seed 3] step" in out and "[seed 4] step" in out
    assert "Trained" not in out.replace("[seed 3] Trained", "").replace("[seed 4] Trained", "")
    decision = yaml.safe_load((run_dir / "race.yml").read_text())
    assert decision["seeds"] == [3, 4] and decision["decide_at_steps"] == 2048
    winner = run_dir / "race" / f"seed_{decision['chosen_seed']}"
    for name in ("model.zip", "vecnormalize.pkl", "selection.yml"):
        assert (run_dir / name).read_bytes() == (winner / name).read_bytes()
    model, _, _ = tr.load_trained(run_dir)
    assert model.num_timesteps == 2048
    args = yaml.safe_load((run_dir / "args.yml").read_text())
    assert args["seed"] == decision["chosen_seed"] and args["race_seed"] == 3
    for s in (3, 4):  # a candidate is an ordinary run
        cand_hp = yaml.safe_load((run_dir / "race" / f"seed_{s}" / "config.yml").read_text())
        assert "seed_race" not in cand_hp and cand_hp["select_checkpoint"]
    # back to "seed 4 interrupted after its first checkpoint, race not decided": --resume
    # trains seed 4 from that checkpoint to the end, not seed 3, and decides again
    import shutil

    cand4 = run_dir / "race" / "seed_4"
    first = sorted((cand4 / "checkpoints").glob("rl_model_*_steps.zip"),
                   key=lambda p: int(p.stem.split("_")[2]))[0]
    kept = int(first.stem.split("_")[2])
    assert kept < 2048
    for f in (cand4 / "checkpoints").iterdir():
        if f.suffix in (".zip", ".pkl") and int(f.stem.rsplit("_", 2)[1]) > kept:
            f.unlink()
    for name in ("model.zip", "vecnormalize.pkl", "selection.yml"):
        (cand4 / name).unlink()
        (run_dir / name).unlink(missing_ok=True)
    shutil.rmtree(run_dir / "checkpoints")
    (run_dir / "race.yml").unlink()
    (run_dir / "args.yml").write_text(yaml.safe_dump(dict(args, seed=3)))
    assert tr.main(["--resume", str(run_dir), "--no-progress"]) == 0
    out = capfd.readouterr().out
    assert "[seed 3]" not in out  # finished before the interruption: not trained again
    assert f"[seed 4] Resuming {cand4} from step {kept} of 2048" in out
    again = yaml.safe_load((run_dir / "race.yml").read_text())
    assert again["scores"][0] == decision["scores"][0]  # seed 3's own selection, kept
    assert yaml.safe_load((run_dir / "args.yml").read_text())["seed"] == again["chosen_seed"]
    model, _, _ = tr.load_trained(run_dir)
    assert model.num_timesteps == 2048


def test_a_candidate_short_of_the_end_is_an_error(tmp_path, monkeypatch):
    hp = {"n_timesteps": 1000, "seed_race": {"candidates": 2}}
    _fake_candidates(tmp_path, (1, 2), 256)
    monkeypatch.setattr(rc, "_train_candidates", lambda *a, **k: None)
    with pytest.raises(RuntimeError, match="no checkpoint at step >= 1000"):
        rc.seed_race(hp, {"env": ENV_ID, "seed": 1}, tmp_path)


def test_candidates_run_as_keyed_executor_tasks(tmp_path, monkeypatch):
    """The race hands its candidates to optimizers.common.executor.run_tasks as module-level
    tasks keyed ("seed_race", first seed, index), one worker per candidate; finished candidates
    are not submitted again."""
    import optimizers.common.executor as ex

    seen = {}

    def fake_run_tasks(tasks, executor):
        seen.update(keys=[t.key for t in tasks], fn=[t.fn for t in tasks],
                    workers=executor.n_workers)
        return {}, None

    monkeypatch.setattr(ex, "run_tasks", fake_run_tasks)
    hp = {"n_timesteps": 352, "seed_race": {"candidates": 3}}
    _fake_candidates(tmp_path, (8,), 352)  # seed 8 is done
    dirs = [tmp_path / "race" / f"seed_{s}" for s in (7, 8, 9)]
    rc._train_candidates(hp, {"env": ENV_ID, "seed": 7, "race_seed": 7}, [7, 8, 9], dirs)
    assert seen == {"keys": [ex.TaskKey("seed_race", 7, 0), ex.TaskKey("seed_race", 7, 2)],
                    "fn": [rc.train_candidate] * 2, "workers": 2}
    args = yaml.safe_load((dirs[2] / "args.yml").read_text())
    assert args["seed"] == 9 and "race_seed" not in args and args["no_eval"]


def test_a_worker_whose_candidate_returned_survives_the_race_s_sigterm(tmp_path):
    """The race stops its workers by SIGTERM. A candidate's worker whose task has returned
    (here a candidate that fails at once) ignores it and stays in the pool until the pool's
    shutdown; with SIGTERM's default action it died idle and broke the pool under the
    candidates still checkpointing. The end-to-end case is the ``slow`` test
    ``tests/agents/test_run_dirs_and_resume.py::
    test_seed_race_stopped_after_one_candidate_finished_checkpoints_the_other``."""
    import multiprocessing as mp
    import os
    import signal
    import time
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) as pool:
        with pytest.raises(RuntimeError, match="candidate seed 5 failed"):
            pool.submit(rc.train_candidate, {}, {"seed": 5}, str(tmp_path / "c5")).result(120)
        worker = pool.submit(os.getpid).result(60)
        os.kill(worker, signal.SIGTERM)
        time.sleep(0.5)
        assert pool.submit(os.getpid).result(60) == worker  # the same worker, alive
