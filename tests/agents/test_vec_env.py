"""The SB3 adapter of the native vector env (:mod:`agents.common.vec_env`): SB3's same-step
reset with ``terminal_observation``, and PPO trains on it."""

import gymnasium as gym
import numpy as np
import pytest

import lunar_env  # noqa: F401


def test_sb3_adapter_same_step_reset_and_ppo():
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    from agents.common.vec_env import LanderSB3VecEnv, make_sb3_vec_env

    sb3_check_env(gym.make("LunarSoftLanding-v0").unwrapped, warn=True)
    venv = make_sb3_vec_env("LunarSoftLanding-v0", n_envs=3, seed=9, time_limit_s=15.0)
    assert isinstance(venv, LanderSB3VecEnv)
    obs = venv.reset()
    single = gym.make("LunarSoftLanding-v0", time_limit_s=15.0)
    first, _ = single.reset(seed=10)  # sub-env 1 <-> seed 9 + 1
    np.testing.assert_array_equal(obs[1], first)
    a = np.zeros((3, 1), np.float32)
    for k in range(15):
        obs, rew, done, infos = venv.step(a)
        o_s, r_s, term, trunc, _ = single.step(a[1])
        assert rew[1] == np.float32(r_s)
        if k < 14:
            assert not done.any()
            np.testing.assert_array_equal(obs[1], o_s)
    assert done.all()  # same-step reset at the 15 s time limit
    assert infos[1]["TimeLimit.truncated"] and trunc
    np.testing.assert_array_equal(infos[1]["terminal_observation"], o_s)
    np.testing.assert_array_equal(obs[1], single.reset()[0])  # next episode, same stream
    model = PPO("MlpPolicy", venv, n_steps=8, batch_size=12, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=48)
    venv.close()


def test_sb3_adapter_pinpoint_terminal_info():
    from agents.common.vec_env import make_sb3_vec_env

    venv = make_sb3_vec_env("lunar_env:LunarPinpointLanding-v0", n_envs=2, seed=1,
                            time_limit_s=3.0)
    obs = venv.reset()
    assert obs.shape == (2, 9) and obs.dtype == np.float32
    for _ in range(3):
        obs, rew, done, infos = venv.step(np.zeros((2, 2), np.float32))
    assert done.all() and all(i["TimeLimit.truncated"] for i in infos)
    assert all(i["miss_distance_m"] > 1e5 for i in infos)  # still ~500 km from the target
    assert np.all(rew < -5.0)  # the truncation is charged like a crash
    with pytest.raises(ValueError, match="NaN or inf"):
        venv.step(np.full((2, 2), np.nan, np.float32))
    with pytest.raises(ValueError, match="n_envs"):
        make_sb3_vec_env("LunarSoftLanding-v0", n_envs=0)
