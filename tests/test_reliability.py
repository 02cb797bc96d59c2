"""Reliability (issue 18): nothing lost under concurrent runs, kills and damaged files; no
"success" that is not one; every bad input named.

Sections: env and scenario inputs (items 8, 9, 10), a hypothesis fuzz of env construction
arguments, reset options and actions, run directories under concurrency (item 1), damaged and
missing checkpoint files (items 2, 3), datasets (item 3, 10) and kill-and-resume tests (SIGKILL
at a random point, resume, compare with an uninterrupted run). Long variants are marked
``slow``; each has a quick version in the default run.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import random
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import lunar_env  # noqa: F401  (registers the ids)
from lunar_env.scenarios import (
    PinpointDispersion,
    PinpointTarget,
    PlanarDispersion,
    get_scenario,
)

SOFT, PIN = "LunarSoftLanding-v0", "LunarPinpointLanding-v0"


def _vec(env_id, n, **kw):
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kw)


# ----------------------------------------------------------------------------- item 8


def test_vector_env_refuses_transposed_actions():
    """(2, 4) actions for 4 pinpoint landers of 2 channels were reshaped and mixed up."""
    env = _vec(PIN, 4)
    env.reset(seed=0)
    y0 = env.state_nd.copy()
    with pytest.raises(ValueError, match=r"action has shape \(2, 4\); expected \(4, 2\)"):
        env.step(np.zeros((2, 4), dtype=np.float32))
    np.testing.assert_array_equal(env.state_nd, y0)
    # axes of length 1 are still accepted: (N,) for a one-channel env of N landers
    soft = _vec(SOFT, 3)
    soft.reset(seed=0)
    soft.step(np.zeros(3))


def test_vector_env_step_before_reset_is_a_clear_error():
    env = _vec(PIN, 2)
    with pytest.raises(RuntimeError, match="before reset"):
        env.step(np.zeros((2, 2)))
    with pytest.raises(RuntimeError, match="before reset"):
        env.step_landers(np.zeros((2, 2)))


@pytest.mark.parametrize("key", ["state_nd", "state_si"])
def test_vector_env_failed_reset_changes_nothing_and_names_the_row(key):
    env = _vec(SOFT, 4)
    env.reset(seed=3)
    env.step(np.zeros((4, 1)))
    y, t = env.state_nd.copy(), env.t_s.copy()
    sc = env.scenario
    rows = sc.sample_initial(np.random.default_rng(0), 4)
    rows[2, 4] = 1.0  # mass below the dry mass
    if key == "state_nd":
        rows = sc.si_to_nd(rows)
    with pytest.raises(ValueError, match="sub-env 2"):
        env.reset(options={key: rows})
    np.testing.assert_array_equal(env.state_nd, y)
    np.testing.assert_array_equal(env.t_s, t)
    # the generators did not advance either: the next episode is the one it would have been
    ref = _vec(SOFT, 4)
    ref.reset(seed=3)
    ref.step(np.zeros((4, 1)))
    np.testing.assert_array_equal(env.reset()[0], ref.reset()[0])


# ----------------------------------------------------------------------------- item 9


def test_pinpoint_scenario_refuses_impossible_dispersions():
    peng = get_scenario("peng2012")
    with pytest.raises(ValueError, match="dispersion.mass_kg"):
        dataclasses.replace(peng, dispersion=PinpointDispersion(mass_kg=(-350.0, 0.0)))
    with pytest.raises(ValueError, match="dispersion.altitude_m"):
        dataclasses.replace(peng, dispersion=PinpointDispersion(altitude_m=(-13500.0, 0.0)))
    with pytest.raises(ValueError, match="target.altitude_m"):
        dataclasses.replace(peng, target=PinpointTarget(20e3, peng.target.longitude_rad,
                                                        peng.target.latitude_rad))
    for bad in (float("nan"), -5.0, 0.0):
        with pytest.raises(ValueError, match="uw_bound_m_s"):
            dataclasses.replace(peng, uw_bound_m_s=bad)
    for bad in ((-5.0, -1.0), (-1.0, 100.0)):
        with pytest.raises(ValueError, match="tf_bounds_s"):
            dataclasses.replace(peng, tf_bounds_s=bad)
    assert dataclasses.replace(peng, uw_bound_m_s=math.inf).uw_bound_m_s == math.inf


def test_planar_scenario_refuses_negative_final_times():
    zhu = get_scenario("zhu2007")
    for bad in ((-5.0, -1.0), (-1.0, 700.0), (0.0, 0.0)):
        with pytest.raises(ValueError, match="tf_bounds_s"):
            dataclasses.replace(zhu, tf_bounds_s=bad)
    with pytest.raises(ValueError, match="dispersion.mass_kg"):
        dataclasses.replace(zhu, dispersion=PlanarDispersion(mass_kg=(-400.0, 0.0)))


def test_pinpoint_scenario_every_dispersed_start_resets():
    """A valid dispersion gives starts the env accepts (200 seeds, the issue's count)."""
    peng = get_scenario("peng2012")
    wide = dataclasses.replace(peng, dispersion=PinpointDispersion(
        altitude_m=(-12_000.0, 0.0), mass_kg=(-290.0, 0.0)))
    env = gym.make(PIN, scenario=wide)
    for seed in range(200):
        env.reset(seed=seed)


# ----------------------------------------------------------------------------- item 10


@pytest.mark.parametrize("env_id", [SOFT, PIN])
@pytest.mark.parametrize("kwargs, field", [
    ({"throttle_channel": "no"}, "throttle_channel"),
    ({"throttle_channel": "False"}, "throttle_channel"),
    ({"substeps": 1.7}, "substeps"),
    ({"substeps": 0}, "substeps"),
    ({"substeps": True}, "substeps"),
    ({"max_fall_s": 0.0}, "max_fall_s"),
    ({"max_fall_s": -3.0}, "max_fall_s"),
    ({"time_limit_s": math.inf}, "time_limit_s"),
    ({"time_limit_s": math.nan}, "time_limit_s"),
    ({"max_fall_s": math.inf}, "max_fall_s"),
    ({"max_fall_s": math.nan}, "max_fall_s"),
    ({"substeps": math.inf}, "substeps"),
    ({"substeps": math.nan}, "substeps"),
    ({"dt_s": "1"}, "dt_s"),
    ({"success_speed_m_s": None}, "success_speed_m_s"),
])
def test_env_arguments_are_refused_by_name(env_id, kwargs, field):
    with pytest.raises(ValueError, match=field):
        gym.make(env_id, **kwargs)
    with pytest.raises(ValueError, match=field):
        _vec(env_id, 2, **kwargs)


@pytest.mark.parametrize("env_id", [SOFT, PIN])
def test_integral_and_numpy_arguments_are_kept_exactly(env_id):
    env = gym.make(env_id, substeps=np.int64(3), dt_s=np.float32(0.5), throttle_channel=np.bool_(1),
                   max_fall_s=4.0).unwrapped
    assert env.task.substeps == 3 and env.dt_s == 0.5 and env.task.throttle_channel is True
    assert env.task.max_fall_s == 4.0
    assert gym.make(env_id, substeps=2.0).unwrapped.task.substeps == 2


@pytest.mark.parametrize("env_id", [SOFT, PIN])
def test_reset_options_unknown_keys_and_bad_state_lengths(env_id):
    env = gym.make(env_id)
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['state'\]"):
        env.reset(options={"state": [1.0]})
    n_state = env.unwrapped.task.model.n_state
    for key in ("state_si", "state_nd"):
        with pytest.raises(ValueError, match=key):
            env.reset(options={key: np.ones(n_state - 1)})
        with pytest.raises(ValueError, match=key):
            env.reset(options={key: np.full(n_state, np.nan)})
    venv = _vec(env_id, 2)
    with pytest.raises(ValueError, match="unknown key"):
        venv.reset(options={"nominl": True})
    with pytest.raises(ValueError, match="state_si"):
        venv.reset(options={"state_si": np.ones((3, n_state))})


# ----------------------------------------------------------------------------- helpers

REPO = Path(__file__).resolve().parents[1]


def _python(code: str, *args: str, **kw) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1")
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(code), *args], cwd=REPO,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, **kw)


def _wait_for(pred, timeout_s: float, proc: subprocess.Popen | None = None) -> None:
    t0 = time.monotonic()
    while not pred():
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"process ended early:\n{proc.stdout.read().decode()[-3000:]}")
        if time.monotonic() - t0 > timeout_s:
            raise AssertionError("timed out")
        time.sleep(0.05)


def _children(pid: int) -> list[int]:
    """Every descendant pid of ``pid`` (Linux /proc)."""
    kids = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            if ppid == pid:
                kids.append(int(d.name))
    return kids + [g for k in kids for g in _children(k)]


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


# ----------------------------------------------------------------------------- item 1


_RUN_DIR_WORKER = """
    import os, sys, time
    from pathlib import Path
    from agents.common.runs import next_run_dir, write_text_atomic
    folder, start = sys.argv[1], float(sys.argv[2])
    while time.time() < start:
        pass
    for _ in range(int(sys.argv[3])):
        d = next_run_dir(folder, "LunarSoftLanding-v0")
        write_text_atomic(d / "owner.txt", str(os.getpid()))
        (d / f"pid_{os.getpid()}").touch()
"""


def test_concurrent_processes_never_share_a_run_directory(tmp_path):
    """Several processes create runs in one folder at the same instant (issue 18 item 1)."""
    n_proc, per_proc = 6, 8
    start = time.time() + 1.5
    procs = [_python(_RUN_DIR_WORKER, str(tmp_path), str(start), str(per_proc))
             for _ in range(n_proc)]
    for p in procs:
        assert p.wait(timeout=120) == 0, p.stdout.read().decode()
    dirs = sorted(tmp_path.iterdir())
    assert len(dirs) == n_proc * per_proc
    for d in dirs:  # each directory was created by exactly one process
        assert len(list(d.glob("pid_*"))) == 1, d
    names = {d.name for d in dirs}
    assert names == {f"LunarSoftLanding-v0_{k}" for k in range(1, n_proc * per_proc + 1)}


def test_explicit_run_dir_is_claimed_by_one_process(tmp_path):
    from agents.common.runs import claim_run_dir

    code = """
        import sys, time
        from agents.common.runs import claim_run_dir
        start = float(sys.argv[2])
        while time.time() < start:
            pass
        try:
            claim_run_dir(sys.argv[1])
            print("CLAIMED")
        except FileExistsError as exc:
            print("REFUSED", exc)
    """
    target = tmp_path / "run"
    start = time.time() + 1.5
    procs = [_python(code, str(target), str(start)) for _ in range(5)]
    outs = [p.communicate(timeout=120)[0].decode() for p in procs]
    assert sum("CLAIMED" in o for o in outs) == 1, outs
    assert all("run directory" in o for o in outs if "REFUSED" in o)
    with pytest.raises(FileExistsError, match="claimed by another process"):
        claim_run_dir(target)


# ----------------------------------------------------------------------------- items 2, 3


_TRAIN_ARGS = ["--quick", "--n-envs", "2", "--no-eval", "--no-progress", "--no-tensorboard",
               "--save-freq", "64", "-v", "0", "--hyperparams", "curriculum=null", "n_steps=32",
               "batch_size=64", "n_epochs=1"]


def _train(folder, n=256, seed=1, extra=()):
    from agents.train import main

    assert main(["-n", str(n), "--seed", str(seed), "-f", str(folder), *_TRAIN_ARGS,
                 *extra]) == 0
    return Path(folder) / "ppo" / "LunarSoftLanding-v0_1"


@pytest.fixture(scope="module")
def trained_run(tmp_path_factory):
    """A finished quick run with checkpoints at 64, 128, 192 and 256 steps."""
    return _train(tmp_path_factory.mktemp("base"))


@pytest.fixture
def run_copy(trained_run, tmp_path):
    dst = tmp_path / "run"
    shutil.copytree(trained_run, dst)
    (dst / "model.zip").unlink()  # an interrupted run: resume from the checkpoints
    return dst


def _resume(run_dir, *extra):
    from agents.train import main

    return main(["--resume", str(run_dir), "--no-progress", *extra])


def _steps_of(run_dir) -> int:
    from agents.common.runs import load_trained

    return int(load_trained(run_dir / "model.zip")[0].num_timesteps)


def test_resume_without_statistics_falls_back_or_refuses(run_copy, capsys):
    ck = run_copy / "checkpoints"
    (ck / "rl_model_vecnormalize_256_steps.pkl").unlink()
    (ck / "rl_model_256_steps.zip").unlink()  # a kill between the two saves
    (ck / "rl_model_vecnormalize_192_steps.pkl").unlink()  # statistics lost
    assert _resume(run_copy) == 0
    out = capsys.readouterr().out
    assert "skipping checkpoint rl_model_192_steps.zip (its statistics" in out
    assert "Resuming" in out and "from step 128" in out
    assert _steps_of(run_copy) == 256
    # no statistics anywhere: refused (no silent training on raw observations)
    for f in ck.glob("rl_model_vecnormalize_*"):
        f.unlink()
    before = (run_copy / "config.yml").read_text()
    with pytest.raises(SystemExit):
        _resume(run_copy, "-n", "512")
    assert "statistics" in capsys.readouterr().err
    assert (run_copy / "config.yml").read_text() == before


@pytest.mark.parametrize("damaged", ["rl_model_256_steps.zip",
                                     "rl_model_vecnormalize_256_steps.pkl"])
def test_damaged_newest_checkpoint_falls_back_to_older(run_copy, capsys, damaged):
    f = run_copy / "checkpoints" / damaged
    f.write_bytes(f.read_bytes()[: f.stat().st_size // 2])
    assert _resume(run_copy, "-n", "320") == 0
    out = capsys.readouterr().out
    assert "skipping checkpoint rl_model_256_steps.zip" in out and "from step 192" in out
    assert _steps_of(run_copy) == 320
    assert yaml.safe_load((run_copy / "config.yml").read_text())["n_timesteps"] == 320


def test_failed_resume_changes_nothing(run_copy, capsys):
    """``--resume -n N`` that fails must not rewrite config.yml or command.txt first."""
    files = ("config.yml", "command.txt", "args.yml")
    before = {f: (run_copy / f).read_text() for f in files}
    ck = run_copy / "checkpoints"
    # a checkpoint whose contents disagree with its name: found only when it is loaded
    os.replace(ck / "rl_model_256_steps.zip", ck / "rl_model_320_steps.zip")
    os.replace(ck / "rl_model_vecnormalize_256_steps.pkl",
               ck / "rl_model_vecnormalize_320_steps.pkl")
    with pytest.raises(RuntimeError, match="num_timesteps=256"):
        _resume(run_copy, "-n", "512")
    for f in ck.glob("rl_model_*.zip"):  # every checkpoint damaged: refused up front
        f.write_bytes(b"PK\x03\x04 not a zip")
    with pytest.raises(SystemExit):
        _resume(run_copy, "-n", "512")
    assert "no complete checkpoint" in capsys.readouterr().err
    assert {f: (run_copy / f).read_text() for f in files} == before


# ----------------------------------------------------------------------------- kill and resume

_TRAIN_CLI = """
    import sys
    from agents.train import main
    sys.exit(main(sys.argv[1:]))
"""


def _kill_and_resume_training(tmp_path, seed: int, n: int, rng: random.Random):
    folder = tmp_path / "killed"
    args = ["-n", str(n), "--seed", str(seed), "-f", str(folder), *_TRAIN_ARGS]
    run_dir = folder / "ppo" / "LunarSoftLanding-v0_1"
    proc = _python(_TRAIN_CLI, *args)
    try:
        _wait_for(lambda: any((run_dir / "checkpoints").glob("rl_model_*_steps.zip")), 300,
                  proc)
        time.sleep(rng.uniform(0.0, 1.0))
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()
    assert not (run_dir / "model.zip").exists() or True  # the kill may land after the end
    killed_sessions = yaml.safe_load((run_dir / "timing.yml").read_text())
    assert _resume(run_dir) == 0
    sessions = yaml.safe_load((run_dir / "timing.yml").read_text())
    # the killed session is accounted for, and the resumed run ends where an uninterrupted one
    # does: every step trained exactly once
    assert sessions[: len(killed_sessions)] == killed_sessions
    assert sessions[-1]["num_timesteps"] == n
    return run_dir


def _compare_with_uninterrupted(run_dir, ref_dir):
    from agents.common.runs import load_trained

    m, vn, _ = load_trained(run_dir / "model.zip")
    r, rvn, _ = load_trained(ref_dir / "model.zip")
    assert m.num_timesteps == r.num_timesteps
    assert m._n_updates == r._n_updates  # no rollout trained twice or lost
    assert vn is not None and rvn is not None
    assert yaml.safe_load((run_dir / "config.yml").read_text()) == \
        yaml.safe_load((ref_dir / "config.yml").read_text())


def test_run_killed_after_its_final_checkpoint_resumes(run_copy):
    """Killed between the final checkpoint and model.zip: the resume has nothing left to train
    and used to fail with AttributeError (found by the random kill test)."""
    assert _resume(run_copy) == 0
    assert _steps_of(run_copy) == 256


def test_training_killed_at_a_random_point_resumes(tmp_path):
    rng = random.Random()
    run_dir = _kill_and_resume_training(tmp_path, seed=4, n=320, rng=rng)
    ref = _train(tmp_path / "ref", n=320, seed=4)
    _compare_with_uninterrupted(run_dir, ref)


def test_seed_race_stopped_by_sigterm_checkpoints_every_candidate_and_resumes(tmp_path):
    """SIGTERM to a seed race (its candidates are executor tasks in worker processes): every
    candidate writes a checkpoint, the run exits with 130 and leaves no worker behind, and
    ``--resume`` trains the candidates on from there and decides the race."""
    run_dir = tmp_path / "race"
    n = 8192
    proc = _python(_TRAIN_CLI, "--quick", "--env", "LunarPinpointLanding-v2", "--seed", "3",
                   "--run-dir", str(run_dir), "--no-progress", "--no-eval", "--no-tensorboard",
                   "--hyperparams", "seed_race={candidates: 2}", f"n_timesteps={n}")
    cands = [run_dir / "race" / f"seed_{s}" / "checkpoints" for s in (3, 4)]
    try:
        _wait_for(lambda: all(any(c.glob("rl_model_*_steps.zip")) for c in cands), 300, proc)
        workers = _children(proc.pid)
        proc.send_signal(signal.SIGTERM)
        out = proc.communicate(timeout=120)[0].decode()
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == 130, out[-3000:]
    assert "[seed 3] Interrupted at step" in out and "[seed 4] Interrupted at step" in out
    assert "continue with: python train.py --resume" in out
    def alive(pid):
        try:
            return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
        except OSError:
            return False

    _wait_for(lambda: not any(alive(p) for p in workers), 10)  # exit_with_parent: < 1 s
    stopped = [max(int(f.stem.split("_")[2]) for f in c.glob("rl_model_*_steps.zip"))
               for c in cands]
    assert all(0 < s < n for s in stopped), stopped
    assert _resume(run_dir) == 0
    race = yaml.safe_load((run_dir / "race.yml").read_text())
    assert race["seeds"] == [3, 4] and race["decide_at_steps"] == n
    assert _steps_of(run_dir) == n


@pytest.mark.slow
@pytest.mark.parametrize("trial", range(4))
def test_training_killed_at_random_points_slow(tmp_path, trial):
    rng = random.Random(trial)
    run_dir = _kill_and_resume_training(tmp_path, seed=7, n=1024, rng=rng)
    ref = _train(tmp_path / "ref", n=1024, seed=7)
    _compare_with_uninterrupted(run_dir, ref)


@pytest.mark.slow
@pytest.mark.parametrize("trial", range(5))
def test_concurrent_training_runs_slow(tmp_path, trial):
    """The issue's reproduction: two train.py processes at the same instant, one folder."""
    code = """
        import sys, time
        start = float(sys.argv[1])
        from agents.train import main
        while time.time() < start:
            pass
        sys.exit(main(sys.argv[2:]))
    """
    start = time.time() + 8.0
    procs = [_python(code, str(start), "-n", "128", "--seed", str(s), "-f", str(tmp_path),
                     *_TRAIN_ARGS) for s in (1, 2)]
    for p in procs:
        assert p.wait(timeout=600) == 0, p.stdout.read().decode()
    dirs = sorted((tmp_path / "ppo").iterdir())
    assert len(dirs) == 2
    seeds = set()
    for d in dirs:
        args = yaml.safe_load((d / "args.yml").read_text())
        seeds.add(args["seed"])
        assert f"--seed {args['seed']}" in (d / "command.txt").read_text()
        assert len(yaml.safe_load((d / "timing.yml").read_text())) == 1
    assert seeds == {1, 2}


# ----------------------------------------------------------------------------- datasets


def _dataset_arrays(path):
    from agents.imitation.data import load_dataset

    ds = load_dataset(path)
    return {k: v for k, v in ds.arrays.items() if k not in ("solve_wall_s",)}


def _assert_same_dataset(a, b):
    A, B = _dataset_arrays(a), _dataset_arrays(b)
    assert set(A) == set(B)
    for k in A:
        np.testing.assert_array_equal(A[k], B[k], err_msg=k)


@pytest.fixture(scope="module")
def reference_dataset(tmp_path_factory):
    from agents.imitation.dataset import generate

    out = tmp_path_factory.mktemp("ds") / "ref.npz"
    generate(out, n=3, shard_size=1, n_workers=1, progress=False, n_steps=200)
    return out


def test_damaged_dataset_shard_is_named_and_solved_again(reference_dataset, tmp_path, capsys):
    from agents.imitation.data import load_dataset
    from agents.imitation.dataset import generate

    out = tmp_path / "d.npz"
    generate(out, n=3, shard_size=1, n_workers=1, progress=False, n_steps=200, max_shards=2)
    shard = tmp_path / "d.npz.shards" / "shard_00001.npz"
    shard.write_bytes(shard.read_bytes()[: shard.stat().st_size // 2])
    generate(out, n=3, shard_size=1, n_workers=1, progress=False, n_steps=200)
    assert f"dataset shard {shard} is damaged" in capsys.readouterr().out
    assert shard.with_name(shard.name + ".damaged").exists()
    _assert_same_dataset(out, reference_dataset)
    timing = json.loads((tmp_path / "d.npz.shards" / "timing.json").read_text())
    assert [t["new_shards"] for t in timing] == [2, 2]
    # a damaged dataset file is named too (not a bare BadZipFile)
    out.write_bytes(out.read_bytes()[:100])
    with pytest.raises(ValueError, match=f"dataset file {out}"):
        load_dataset(out)


_DATASET_CLI = """
    import sys
    from agents.dataset import main
    sys.exit(main(sys.argv[1:]))
"""


def _kill_and_resume_dataset(tmp_path, reference, n, rng):
    from agents.imitation.dataset import generate

    out = tmp_path / "killed.npz"
    proc = _python(_DATASET_CLI, "--n", str(n), "--shard-size", "1", "--workers", "2",
                   "--n-steps", "200", "--out", str(out), "--no-progress")
    shards = out.with_name(out.name + ".shards")
    workers: set[int] = set()
    try:
        def started():
            workers.update(_children(proc.pid))
            return any(shards.glob("shard_*.npz"))
        _wait_for(started, 300, proc)
        time.sleep(rng.uniform(0.0, 0.5))
        workers.update(_children(proc.pid))
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()
    assert workers, "the dataset run started no worker process"
    # item 10: the workers end with their parent (no orphans left computing or waiting)
    _wait_for(lambda: not any(_alive(p) for p in workers), 30)
    timing = json.loads((shards / "timing.json").read_text())
    assert timing and timing[0]["new_shards"] >= 1  # the killed session is recorded
    n_missing = n - len(list(shards.glob("shard_*.npz")))
    generate(out, n=n, shard_size=1, n_workers=1, progress=False, n_steps=200)
    _assert_same_dataset(out, reference)
    timing = json.loads((shards / "timing.json").read_text())
    # the killed session keeps its record (a kill between a shard's rename and the timing
    # update can leave that one shard uncounted); the resumed one solved only what was missing
    assert len(timing) == 2 and timing[1]["new_shards"] == n_missing
    assert n - 1 <= sum(t["new_shards"] for t in timing) <= n


def test_dataset_killed_at_a_random_point_resumes(reference_dataset, tmp_path):
    _kill_and_resume_dataset(tmp_path, reference_dataset, 3, random.Random())


@pytest.mark.slow
@pytest.mark.parametrize("trial", range(3))
def test_dataset_killed_at_random_points_slow(tmp_path, trial):
    from agents.imitation.dataset import generate

    ref = tmp_path / "ref.npz"
    generate(ref, n=8, shard_size=1, n_workers=1, progress=False, n_steps=200)
    _kill_and_resume_dataset(tmp_path, ref, 8, random.Random(trial))


# ----------------------------------------------------------------------------- optimisers

_ASAGA_CLI = """
    import sys
    from optimizers.evolutionary.asaga import ASAGA
    from optimizers.problems.landing import PlanarLandingProblem
    ASAGA(n_generations=int(sys.argv[2])).solve(PlanarLandingProblem(), seed=5,
                                                checkpoint=sys.argv[1], checkpoint_every=1)
"""


def _kill_and_resume_asaga(tmp_path, n_gen, rng):
    from optimizers.evolutionary.asaga import ASAGA
    from optimizers.problems.landing import PlanarLandingProblem

    ck = tmp_path / "asaga.pkl"
    proc = _python(_ASAGA_CLI, str(ck), str(n_gen))
    try:
        _wait_for(ck.exists, 300, proc)
        time.sleep(rng.uniform(0.0, 0.3))
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()
    problem = PlanarLandingProblem()
    resumed = ASAGA(n_generations=n_gen).solve(problem, seed=5, checkpoint=ck)
    full = ASAGA(n_generations=n_gen).solve(problem, seed=5)
    np.testing.assert_array_equal(resumed.x, full.x)
    np.testing.assert_array_equal(resumed.history, full.history)
    assert resumed.n_fevals == full.n_fevals and resumed.success == full.success


def test_optimiser_killed_at_a_random_point_resumes(tmp_path):
    _kill_and_resume_asaga(tmp_path, 30, random.Random())


@pytest.mark.slow
@pytest.mark.parametrize("trial", range(5))
def test_optimiser_killed_at_random_points_slow(tmp_path, trial):
    _kill_and_resume_asaga(tmp_path, 80, random.Random(trial))


def test_damaged_optimiser_checkpoint_is_named(tmp_path):
    from optimizers.evolutionary.asaga import ASAGA
    from optimizers.problems.landing import PlanarLandingProblem

    ck = tmp_path / "asaga.pkl"
    ASAGA(n_generations=2).solve(PlanarLandingProblem(), seed=5, checkpoint=ck)
    for cut in (0, 17, ck.stat().st_size // 2):
        data = ck.read_bytes()
        ck.write_bytes(data[:cut])
        with pytest.raises(ValueError, match=f"checkpoint {ck} is damaged"):
            ASAGA(n_generations=2).solve(PlanarLandingProblem(), seed=5, checkpoint=ck)
        ck.write_bytes(data)


# ----------------------------------------------------------------------------- fuzz


def _fuzz_module():
    import importlib.util

    spec = importlib.util.spec_from_file_location("fuzz_inputs",
                                                  REPO / "benchmarks" / "fuzz_inputs.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("fuzz_inputs", mod)
    spec.loader.exec_module(mod)
    return mod


def _fuzz(n_examples: int):
    from hypothesis import HealthCheck, given, settings

    fz = _fuzz_module()

    @settings(max_examples=n_examples, deadline=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(fz.cases())
    def one(case):
        tally = fz.Tally()
        fz.check_case(tally, *case)
        assert tally.silent == 0 and tally.unclear == 0, tally.examples

    one()


def test_fuzz_env_inputs_work_or_are_named():
    """Construction arguments, reset options and actions: each works or raises an error that
    names it (hypothesis; ``python benchmarks/fuzz_inputs.py`` prints the counts)."""
    _fuzz(40)


@pytest.mark.slow
def test_fuzz_env_inputs_slow():
    _fuzz(3000)
