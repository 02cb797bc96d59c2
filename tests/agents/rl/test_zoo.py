"""RL Baselines3 Zoo: the generated Zoo files are up to date and train under rl_zoo3.train."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from agents.hyperparams import ALGOS
from agents.rl.zoo import ZOO_PROFILES, main, render_zoo_yaml, zoo_entry, zoo_path

pytest.importorskip("rl_zoo3")

REPO = Path(__file__).resolve().parents[3]


def test_shipped_zoo_files_are_generated_from_the_project_files():
    for algo in ALGOS:
        for profile in ZOO_PROFILES:
            path = zoo_path(algo, profile)
            assert path.read_text(encoding="utf-8") == render_zoo_yaml(algo, profile), (
                f"{path} is stale: run python -m agents.rl.zoo")
    assert main(["--check"]) == 0


def test_zoo_entry_moves_project_keys_into_the_vec_env_wrapper():
    hp = {"n_envs": 4, "n_timesteps": 1000.0, "gamma": 0.99, "obs_features": ["log_altitude"],
          "history": 8,
          "reward_shaping": {"potential": "surface_speed"}, "curriculum": {"start_prob": 0.5},
          "select_checkpoint": {"states": 3}, "seed_race": {"candidates": 2},
          "policy_kwargs": {"net_arch": [8], "activation_fn": "relu",
                            "optimizer_class": "adamw"}}
    out = zoo_entry(hp)
    assert out["policy_kwargs"] == "dict(net_arch=[8], activation_fn=nn.ReLU, " \
                                   "optimizer_class=th.optim.AdamW)"
    assert "select_checkpoint" not in out and "seed_race" not in out
    assert "obs_features" not in out and "curriculum" not in out
    (wrapper,) = out["vec_env_wrapper"]
    kw = wrapper["agents.rl.zoo.lunar_vec_env"]
    assert kw["obs_features"] == ["log_altitude"] and kw["history"] == 8
    assert "history" not in out
    assert kw["gamma"] == 0.99 and kw["total_timesteps"] == 1000
    with pytest.raises(ValueError, match="activation_fn='swish'"):
        zoo_entry({"policy_kwargs": {"activation_fn": "swish"}})
    with pytest.raises(ValueError, match="error_curriculum is not available"):
        zoo_entry({"error_curriculum": {"start_scale": 0.0}})
    with pytest.raises(ValueError, match="normalize.update is not a VecNormalize argument"):
        zoo_entry({"normalize": {"norm_obs": True, "update": False}})


def _zoo_train(tmp_path: Path, algo: str, env_id: str, conf: str, *extra: str) -> Path:
    env = dict(os.environ, PYTHONPATH=str(REPO), OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    cmd = [sys.executable, "-m", "rl_zoo3.train", "--algo", algo, "--env", env_id,
           "--gym-packages", "lunar_env", "--conf-file", conf, "-f", str(tmp_path),
           "--seed", "3", "--eval-freq", "-1", *extra]
    proc = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    run = tmp_path / algo / f"{env_id}_1"
    assert (run / f"{env_id}.zip").is_file()
    assert (run / "native.monitor.csv").is_file()
    return run


# The planar case is ``slow``; its quick twin is the pinpoint case (the same wrapper with
# more of it used: the curriculum's extremal pool, the features and the shaping).
@pytest.mark.parametrize("env_id", [pytest.param("LunarSoftLanding-v0", marks=pytest.mark.slow),
                                    "LunarPinpointLanding-v2"])
def test_rl_zoo_trains_ppo_with_the_shipped_quick_file(tmp_path, env_id):
    run = _zoo_train(tmp_path, "ppo", env_id, "agents/hyperparams/zoo/ppo_quick.yml",
                     "-n", "2048")
    config = yaml.load((run / env_id / "config.yml").read_text(), Loader=yaml.UnsafeLoader)
    cfg = dict(config)
    assert "agents.rl.zoo.lunar_vec_env" in cfg["vec_env_wrapper"][0]
    # the native env logged whole episodes in the Zoo's monitor format
    lines = (run / "native.monitor.csv").read_text().splitlines()
    assert lines[0].startswith("#") and lines[1].startswith("r,l,t")


@pytest.mark.slow
def test_rl_zoo_trains_recurrent_ppo_as_ppo_lstm(tmp_path):
    """The recurrent entry's Zoo file under the Zoo's name of RecurrentPPO (``ppo_lstm``)."""
    pytest.importorskip("sb3_contrib")
    assert "--algo ppo_lstm" in render_zoo_yaml("recurrent-ppo", "quick")
    _zoo_train(tmp_path, "ppo_lstm", "LunarPinpointLanding-v2",
               "agents/hyperparams/zoo/recurrent-ppo_quick.yml", "-n", "1024")


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_rl_zoo_trains_off_policy_and_enjoy_plays_the_run(tmp_path, algo):
    env_id = "LunarSoftLanding-v0"
    _zoo_train(tmp_path, algo, env_id, f"agents/hyperparams/zoo/{algo}_quick.yml")
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.run([sys.executable, "-m", "rl_zoo3.enjoy", "--algo", algo, "--env",
                           env_id, "--gym-packages", "lunar_env", "-f", str(tmp_path),
                           "--no-render", "-n", "300"], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "Episode Reward" in proc.stdout
