"""train.py end to end (quick configuration), resume, and seeded repeatability."""

import numpy as np
import pytest
import yaml
from stable_baselines3.common.callbacks import BaseCallback

from agents import train as tr
from agents.common.runs import latest_checkpoint
from agents.laws import SB3Law
from guidance.evaluation.compare import compare
from guidance.evaluation.report import markdown_table
from guidance.flight import rollout

ENV_ID = "LunarSoftLanding-v0"
QUICK = ["--quick", "--no-progress", "--verbose", "0", "--torch-threads", "1"]


def test_quick_config_end_to_end(tmp_path, capsys):
    """Train the CI configuration, save, reload, evaluate a few states, print the table."""
    run_dir = tmp_path / "run"
    rc = tr.main([*QUICK, "--seed", "3", "--run-dir", str(run_dir), "--eval-states", "4",
                  "--eval-expert-states", "0"])
    assert rc == 0
    for name in ("config.yml", "args.yml", "command.txt", "model.zip", "vecnormalize.pkl",
                 "timing.yml", "evaluation/comparison.md", "evaluation/comparison.json",
                 "evaluation/trajectories.png"):
        assert (run_dir / name).exists(), name
    assert any((run_dir / "tb").rglob("events.out.tfevents.*"))
    args = yaml.safe_load((run_dir / "args.yml").read_text())
    hp = yaml.safe_load((run_dir / "config.yml").read_text())
    assert args["seed"] == 3 and args["config"] == "quick" and args["algo"] == "ppo"
    assert hp["n_timesteps"] <= 10_000
    model, vn_path, algo = tr.load_trained(run_dir)
    assert algo == "ppo" and vn_path is not None
    assert model.num_timesteps >= hp["n_timesteps"]
    out = capsys.readouterr().out
    assert "| policy |" in out and "Pontryagin open loop" in out
    # the reloaded policy flies the same cases as in the table
    res = rollout(ENV_ID, SB3Law.from_path(run_dir), 4, seed=2026,
                  env_kwargs=hp.get("env_kwargs"))
    table = (run_dir / "evaluation" / "comparison.md").read_text()
    row = next(line for line in table.splitlines() if line.startswith("| PPO"))
    assert f"| {100 * res.is_success.mean():.1f} |" in row


class _InterruptAt(BaseCallback):
    """Simulates Ctrl-C once ``num_timesteps`` reaches ``at``."""

    def __init__(self, at: int):
        super().__init__()
        self.at = at

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.at:
            raise KeyboardInterrupt
        return True


def test_resume_continues_the_step_counter(tmp_path):
    run_dir = tmp_path / "run"
    parser = tr.build_parser()
    args = parser.parse_args([*QUICK, "--seed", "1", "--run-dir", str(run_dir), "-n", "3072",
                              "--save-freq", "512", "--no-eval", "--no-tensorboard"])
    hp, run = tr._resolve_args(args)
    run_dir.mkdir()
    (run_dir / "config.yml").write_text(yaml.safe_dump(hp))
    (run_dir / "args.yml").write_text(yaml.safe_dump(run))
    n_envs, n_steps = hp["n_envs"], hp["n_steps"]
    rollout_steps = n_envs * n_steps
    with pytest.raises(KeyboardInterrupt):
        tr.train(hp, run, run_dir, callbacks=[_InterruptAt(rollout_steps + 5 * n_envs)])
    ckpt, steps = latest_checkpoint(run_dir)
    # interrupted 5 steps into the second rollout: the checkpoint holds the trained steps (the
    # partial rollout was not trained on and is collected again after the resume)
    assert steps == rollout_steps
    assert (ckpt.parent / f"rl_model_vecnormalize_{steps}_steps.pkl").exists()
    assert tr.main(["--resume", str(run_dir), "--no-progress"]) == 0
    model, _, _ = tr.load_trained(run_dir)
    assert model.num_timesteps == 3072
    timing = yaml.safe_load((run_dir / "timing.yml").read_text())
    assert timing[-1]["steps_this_session"] == 3072 - steps


def test_callbacks_are_configured_by_their_constructors(tmp_path):
    """agents.rl.callbacks: the checkpoint callback saves at rollout starts every save_freq env
    steps, reports each save (on_save) and its newest step (last_saved_steps); wrappers are found
    by type, subclasses included; bad settings are refused by name."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from agents.common.vec_env import make_sb3_vec_env
    from agents.rl.callbacks import (
        CriticWarmupCallback,
        EpisodeInfoCallback,
        RolloutCheckpointCallback,
        find_wrapper,
    )
    from agents.rl.curriculum import OptimalStartCurriculum

    class Monitor(VecMonitor):
        pass

    monitor = Monitor(make_sb3_vec_env(ENV_ID, 2, seed=0))
    venv = VecNormalize(monitor)
    assert find_wrapper(venv, VecMonitor) is monitor and find_wrapper(venv, VecNormalize) is venv
    assert find_wrapper(venv, OptimalStartCurriculum) is None
    saves = []
    cb = RolloutCheckpointCallback(tmp_path, 32, {"n_steps": 8},
                                   on_save=lambda: saves.append(cb.last_saved_steps))
    assert cb.last_saved_steps is None
    model = PPO("MlpPolicy", venv, n_steps=8, batch_size=16, n_epochs=1, seed=0, device="cpu")
    model.learn(64, callback=[cb, EpisodeInfoCallback(64, summary_every=0),
                              CriticWarmupCallback(16)])
    assert saves == [32] and cb.last_saved_steps == 32  # rollouts start at 0, 16, 32, 48
    assert latest_checkpoint(tmp_path)[1] == 32
    assert (tmp_path / "checkpoints" / "rl_model_vecnormalize_32_steps.pkl").exists()
    assert yaml.safe_load((tmp_path / "checkpoints" / "config.yml").read_text()) == {"n_steps": 8}
    assert cb.save_now().name == "rl_model_64_steps.zip" and cb.last_saved_steps == 64
    assert all(p.requires_grad for p in model.policy.parameters())  # warm-up released
    with pytest.raises(ValueError, match="critic_warmup_steps=-1"):
        CriticWarmupCallback(-1)
    with pytest.raises(ValueError, match="summary_every=-5"):
        EpisodeInfoCallback(64, summary_every=-5)
    venv.close()


def test_seed_makes_a_run_repeatable(tmp_path):
    params = []
    for k in range(2):
        run_dir = tmp_path / f"run{k}"
        assert tr.main([*QUICK, "--seed", "7", "--run-dir", str(run_dir), "-n", "1024",
                        "--no-eval", "--no-tensorboard"]) == 0
        model, _, _ = tr.load_trained(run_dir)
        params.append(np.concatenate([p.detach().numpy().ravel()
                                      for p in model.policy.parameters()]))
    np.testing.assert_array_equal(params[0], params[1])


def test_evaluation_is_deterministic_and_cases_do_not_depend_on_batch(tmp_path):
    from stable_baselines3 import PPO

    from guidance.flight import initial_states

    venv = tr.make_training_env(ENV_ID, 2, seed=0)
    model = PPO("MlpPolicy", venv, seed=0, device="cpu", n_steps=64, batch_size=64)
    pol = SB3Law(model, None, "PPO-untrained")
    a = rollout(ENV_ID, pol, 6, seed=11, trace_cases=1)
    b = rollout(ENV_ID, pol, 6, seed=11, trace_cases=1)
    for f in ("is_success", "touchdown_speed_m_s", "fuel_used_kg", "episode_time_s"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    np.testing.assert_array_equal(a.traces[0]["state_nd"], b.traces[0]["state_nd"])
    s6 = initial_states(ENV_ID, 6, seed=11)
    s3 = initial_states(ENV_ID, 3, seed=11)
    np.testing.assert_array_equal(s6[:3], s3)
    assert not np.array_equal(s6[0], initial_states(ENV_ID, 1, seed=12)[0])
    rep = compare(ENV_ID, [pol], n_states=3, seed=11, n_expert_states=0, open_loop=False,
                  progress=False)
    md = markdown_table(rep)
    assert "PPO-untrained" in md
    assert np.isfinite(rep["optimum"]["fuel_mean_kg"])


def test_resume_restores_the_success_driven_error_scale(tmp_path):
    """The success schedule of the error curriculum cannot be recomputed from the step count:
    each checkpoint saves it and --resume restores it (and refuses a checkpoint without it)."""
    from agents.rl.callbacks import error_curriculum_of, error_scale_state_path

    run_dir = tmp_path / "run"
    parser = tr.build_parser()
    args = parser.parse_args([
        *QUICK, "--seed", "1", "--run-dir", str(run_dir), "-n", "3072", "--save-freq", "512",
        "--no-eval", "--no-tensorboard", "--hyperparams", "env_kwargs.uncertainty=standard",
        "error_curriculum={start_scale: 0.0, anneal_fraction: 1.0, success_threshold: 0.9, "
        "window_episodes: 100}"])
    hp, run = tr._resolve_args(args)
    run_dir.mkdir()
    (run_dir / "config.yml").write_text(yaml.safe_dump(hp))
    (run_dir / "args.yml").write_text(yaml.safe_dump(run))

    class SetScale(BaseCallback):  # as if the policy had landed enough windows
        def _on_step(self) -> bool:
            errors = error_curriculum_of(self.training_env)
            errors.success_scale = 0.75
            errors._window = [True, False]
            return True

    class Seen(BaseCallback):
        def _on_training_start(self) -> None:
            errors = error_curriculum_of(self.training_env)
            self.state = errors.state_dict()
            self.applied = errors.native.error_scale

        def _on_step(self) -> bool:
            return True

    rollout_steps = hp["n_envs"] * hp["n_steps"]
    with pytest.raises(KeyboardInterrupt):
        tr.train(hp, run, run_dir, callbacks=[SetScale(), _InterruptAt(rollout_steps + 8)])
    ckpt, steps = latest_checkpoint(run_dir)
    saved = yaml.safe_load(error_scale_state_path(ckpt).read_text())
    assert saved == {"success_scale": 0.75, "window": [True, False]}
    seen = Seen()
    tr.train(hp, run, run_dir, resume=True, callbacks=[seen])
    assert seen.state["success_scale"] == 0.75 and seen.applied == pytest.approx(0.75)
    # a checkpoint without the state cannot resume the schedule
    ckpt, _ = latest_checkpoint(run_dir)
    hp["n_timesteps"] = 4096
    error_scale_state_path(ckpt).unlink()
    with pytest.raises(FileNotFoundError, match="success-driven error scale"):
        tr.train(hp, run, run_dir, resume=True)


def test_init_from_with_fixed_statistics_keeps_the_input_map(tmp_path):
    """normalize: {update: false} keeps the observation and reward statistics loaded by
    --init-from (also after --resume); by default they keep updating. (Measured: the nominal
    pinpoint policy's own statistics, updated by a fine-tuning run, moved its inputs and its
    training success fell from 93 to 53 % with a learning rate of 0.)"""
    import pickle

    def stats(path):
        with open(path, "rb") as f:
            vn = pickle.load(f)  # a VecNormalize without its env (what VecNormalize.load reads)
        return vn.obs_rms.mean.copy(), vn.obs_rms.count, vn.ret_rms.var.copy()

    base = tmp_path / "base"
    assert tr.main([*QUICK, "--seed", "1", "--run-dir", str(base), "-n", "1024", "--no-eval",
                    "--no-tensorboard"]) == 0
    m0, n0, r0 = stats(base / "vecnormalize.pkl")
    fixed, moving = tmp_path / "fixed", tmp_path / "moving"
    assert tr.main([*QUICK, "--seed", "2", "--run-dir", str(fixed), "-n", "2048", "--no-eval",
                    "--no-tensorboard", "--save-freq", "1024", "--init-from", str(base),
                    "--hyperparams", "normalize.update=false"]) == 0
    m1, n1, r1 = stats(fixed / "vecnormalize.pkl")
    assert n1 == n0 and np.array_equal(m1, m0) and np.array_equal(r1, r0)
    # resumed (and extended), the run still keeps them
    hp = yaml.safe_load((fixed / "config.yml").read_text())
    run = yaml.safe_load((fixed / "args.yml").read_text())
    hp["n_timesteps"] = 3072
    tr.train(hp, run, fixed, resume=True)
    ckpt, steps = latest_checkpoint(fixed)
    assert steps == 3072
    assert np.array_equal(stats(ckpt.parent / f"rl_model_vecnormalize_{steps}_steps.pkl")[0], m0)
    assert tr.main([*QUICK, "--seed", "2", "--run-dir", str(moving), "-n", "1024", "--no-eval",
                    "--no-tensorboard", "--init-from", str(base)]) == 0
    m2, n2, _r2 = stats(moving / "vecnormalize.pkl")
    assert n2 > n0 and not np.array_equal(m2, m0)
    from agents.rl.training import _normalize_updates

    with pytest.raises(ValueError, match="normalize.update"):
        _normalize_updates({"update": "no"})


def _base_and_continued(tmp_path, *hyperparams: str):
    """A quick planar run ``base`` (seed 1, 1024 steps) and a run ``wide`` started from it by
    ``--init-from`` with ``hyperparams`` (seed 2, 1024 steps); their directories."""
    base, wide = tmp_path / "base", tmp_path / "wide"
    assert tr.main([*QUICK, "--seed", "1", "--run-dir", str(base), "-n", "1024", "--no-eval",
                    "--no-tensorboard"]) == 0
    assert tr.main([*QUICK, "--seed", "2", "--run-dir", str(wide), "-n", "1024", "--no-eval",
                    "--no-tensorboard", "--init-from", str(base), "--hyperparams",
                    *hyperparams]) == 0
    return base, wide


def test_init_from_a_policy_without_a_throttle_channel_widens_its_action_head(tmp_path):
    """added_action_init: a policy trained without a throttle channel continues with one. The
    widened policy's mean flies as the loaded one did, its throttle held at the given action
    (here with a learning rate of 0, so the weights are the loaded ones) with the given
    exploration σ; a mismatch without the key, a wrong count, a value out of range, or the
    key for matching heads is refused by name."""
    from agents.rl.warm_start import widen_action_head

    base, wide = _base_and_continued(tmp_path, 'env_kwargs={"throttle_channel": true}',
                                     "added_action_init={action: [0.8], log_std: [-6.0]}",
                                     "learning_rate=0.0")
    m0, _, _ = tr.load_trained(base)
    m1, _, _ = tr.load_trained(wide)
    assert m0.action_space.shape == (1,) and m1.action_space.shape == (2,)
    obs = np.random.default_rng(0).normal(size=(64, *m0.observation_space.shape))
    a0, _ = m0.policy.predict(obs, deterministic=True)
    a1, _ = m1.policy.predict(obs, deterministic=True)
    np.testing.assert_allclose(a1[:, :1], a0, rtol=0, atol=1e-6)
    np.testing.assert_allclose(a1[:, 1], 0.8, rtol=0, atol=1e-6)
    log_std_init = m0.policy.log_std.detach().numpy()  # never updated: lr 0 in both runs
    np.testing.assert_allclose(m1.policy.log_std.detach().numpy(), [log_std_init[0], -6.0])

    w0, w1 = m0.policy.state_dict(), m1.policy.state_dict()
    with pytest.raises(ValueError, match="set added_action_init to"):
        widen_action_head(w0, w1, None, "base")
    for bad in ([1.0], {"log_std": [-6.0]}, {"action": [1.0], "sigma": [1.0]}):
        with pytest.raises(ValueError, match="must be a mapping with 'action'"):
            widen_action_head(w0, w1, bad, "base")
    for bad in ({"action": [1.0, 1.0]}, {"action": [1.5]}, {"action": [float("nan")]},
                {"action": [1.0], "log_std": [-6.0, -6.0]}):
        with pytest.raises(ValueError, match="needs 1 finite value"):
            widen_action_head(w0, w1, bad, "base")
    with pytest.raises(ValueError, match="already has this env's 1 action"):
        widen_action_head(w0, w0, {"action": [1.0]}, "base")
    with pytest.raises(ValueError, match="has 2 action channels, this env 1"):
        widen_action_head(w1, w0, None, "wide")
    with pytest.raises(SystemExit):  # the key without --init-from
        tr.main([*QUICK, "--run-dir", str(tmp_path / "none"), "--no-eval", "--hyperparams",
                 "added_action_init={action: [1.0]}"])
    assert not (tmp_path / "none").exists()


def test_init_from_a_policy_without_the_imu_adds_its_inputs_with_zero_weights(tmp_path):
    """A policy trained without the IMU channels continues with them (sensors=("imu",)): the
    widened policy and critic compute what the loaded ones did whatever the IMU reads (here
    with a learning rate of 0 and fixed statistics), the added columns normalised with mean 0
    and variance 1; other input changes are refused by name."""
    import pickle

    base, wide = _base_and_continued(tmp_path, 'env_kwargs={"sensors": ["imu"]}',
                                     "learning_rate=0.0", "normalize.update=false")
    m0, vn0, _ = tr.load_trained(base)
    m1, vn1, _ = tr.load_trained(wide)
    n0 = m0.observation_space.shape[0]
    assert m1.observation_space.shape == (n0 + 2,)  # the planar IMU: 2 axes, after 5 columns
    rng = np.random.default_rng(0)
    obs0 = rng.normal(size=(64, n0)).astype(np.float32)
    obs1 = np.insert(obs0, 5, rng.normal(size=(2, 64)).astype(np.float32), axis=1)
    a0, _ = m0.policy.predict(obs0, deterministic=True)
    a1, _ = m1.policy.predict(obs1, deterministic=True)
    np.testing.assert_allclose(a1, a0, rtol=0, atol=1e-6)
    import torch

    with torch.no_grad():
        v0 = m0.policy.predict_values(torch.as_tensor(obs0))
        v1 = m1.policy.predict_values(torch.as_tensor(obs1))
    np.testing.assert_allclose(v1.numpy(), v0.numpy(), rtol=0, atol=1e-5)
    with open(vn0, "rb") as f0, open(vn1, "rb") as f1:
        s0, s1 = pickle.load(f0).obs_rms, pickle.load(f1).obs_rms
    np.testing.assert_array_equal(np.delete(s1.mean, [5, 6]), s0.mean)
    np.testing.assert_array_equal(s1.mean[5:7], 0.0)
    np.testing.assert_array_equal(s1.var[5:7], 1.0)
    with pytest.raises(ValueError, match="only the sensor channels"):
        tr.main([*QUICK, "--run-dir", str(tmp_path / "feat"), "--no-eval", "-n", "1024",
                 "--init-from", str(base), "--hyperparams", "obs_features=[log_altitude]"])


def test_init_from_adds_a_history_with_zero_weights_to_the_older_slots(tmp_path):
    """A policy trained without a history (and without the IMU) continues with both: its
    inputs become the newest slot of the history, and the widened policy and critic compute
    what the loaded ones did whatever the older slots and the past actions hold (learning rate
    0, fixed statistics). Every input slot is normalised with the loaded statistics, the
    action slots with mean 0 and variance 1. A longer history continues a history the same
    way (the loaded slots become the newest); a shorter one, or none, is refused by name."""
    import pickle

    import torch

    base, wide = _base_and_continued(tmp_path, 'env_kwargs={"sensors": ["imu"]}', "history=3",
                                     "learning_rate=0.0", "normalize.update=false")
    m0, vn0, _ = tr.load_trained(base)
    m1, vn1, _ = tr.load_trained(wide)
    n0 = m0.observation_space.shape[0]
    n_obs = n0 + 2  # the planar IMU: 2 axes, after the env's 5 columns
    assert m1.observation_space.shape == (3 * (n_obs + 1),)
    rng = np.random.default_rng(0)
    obs0 = rng.normal(size=(64, n0)).astype(np.float32)
    obs1 = rng.normal(size=(64, 3 * (n_obs + 1))).astype(np.float32)
    obs1[:, 2 * n_obs:3 * n_obs] = np.insert(obs0, 5, rng.normal(size=(2, 64)), axis=1)

    def act_and_value(model, obs):
        with torch.no_grad():
            v = model.policy.predict_values(torch.as_tensor(obs)).numpy()
        return model.policy.predict(obs, deterministic=True)[0], v

    a0, v0 = act_and_value(m0, obs0)
    a1, v1 = act_and_value(m1, obs1)
    np.testing.assert_allclose(a1, a0, rtol=0, atol=1e-6)
    np.testing.assert_allclose(v1, v0, rtol=0, atol=1e-5)
    with open(vn0, "rb") as f0, open(vn1, "rb") as f1:
        s0, s1 = pickle.load(f0).obs_rms, pickle.load(f1).obs_rms
    slot_mean = np.insert(s0.mean, 5, [0.0, 0.0])
    slot_var = np.insert(s0.var, 5, [1.0, 1.0])
    np.testing.assert_array_equal(s1.mean[:3 * n_obs], np.tile(slot_mean, 3))
    np.testing.assert_array_equal(s1.var[:3 * n_obs], np.tile(slot_var, 3))
    np.testing.assert_array_equal(s1.mean[3 * n_obs:], 0.0)
    np.testing.assert_array_equal(s1.var[3 * n_obs:], 1.0)

    longer = tmp_path / "longer"
    assert tr.main([*QUICK, "--seed", "3", "--run-dir", str(longer), "-n", "1024", "--no-eval",
                    "--no-tensorboard", "--init-from", str(wide), "--hyperparams",
                    'env_kwargs={"sensors": ["imu"]}', "history=5", "learning_rate=0.0",
                    "normalize.update=false"]) == 0
    m2, _, _ = tr.load_trained(longer)
    obs2 = rng.normal(size=(64, 5 * (n_obs + 1))).astype(np.float32)
    obs2[:, 2 * n_obs:5 * n_obs] = obs1[:, :3 * n_obs]
    obs2[:, 5 * n_obs + 2:] = obs1[:, 3 * n_obs:]  # the newest three actions
    a2, v2 = act_and_value(m2, obs2)
    np.testing.assert_allclose(a2, a1, rtol=0, atol=1e-6)
    np.testing.assert_allclose(v2, v1, rtol=0, atol=1e-5)
    for history in ("2", "null"):
        with pytest.raises(ValueError, match="a history \\(or a longer one\\)"):
            tr.main([*QUICK, "--run-dir", str(tmp_path / f"h{history}"), "--no-eval",
                     "-n", "1024", "--init-from", str(wide), "--hyperparams",
                     'env_kwargs={"sensors": ["imu"]}', f"history={history}"])
