"""Native vector envs: same episodes as single envs, autoreset, seeding (the SB3 adapter:
tests/agents/test_vec_env.py)."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import lunar_env  # noqa: F401
from lunar_env.envs.soft_landing import LunarSoftLandingVectorEnv

IDS = ["LunarSoftLanding-v0", "LunarPinpointLanding-v0"]


def _actions(rng, n_steps, n_envs, dim):
    a = rng.uniform(-1.0, 1.0, (n_steps, n_envs, dim))
    a[:, 0, 0] = -1.0  # sub-env 0 dives: a termination (crash) inside the run
    return a.astype(np.float32)


@pytest.mark.parametrize("env_id", IDS)
def test_native_vector_env_matches_single_envs_step_for_step(env_id):
    """Through terminations, truncations and NEXT_STEP autoresets, sub-env i is a single env
    reset with seed + i: same observations, rewards, flags and infos, bit for bit."""
    n, kw = 4, dict(time_limit_s=140.0)
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kw)
    assert venv.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    sync = gym.vector.SyncVectorEnv([lambda: gym.make(env_id, **kw) for _ in range(n)],
                                    autoreset_mode=AutoresetMode.NEXT_STEP)
    dim = venv.single_action_space.shape[0]
    assert venv.single_observation_space == sync.single_observation_space
    o1, _ = venv.reset(seed=42)
    o2, _ = sync.reset(seed=42)
    np.testing.assert_array_equal(o1, o2)
    n_done = 0
    for a in _actions(np.random.default_rng(0), 300, n, dim):
        s1 = venv.step(a)
        s2 = sync.step(a)
        for x, y in zip(s1[:4], s2[:4], strict=True):
            np.testing.assert_array_equal(x, y)
        for key in ("fuel_used_kg", "time_s", "is_success", "touchdown_speed_m_s"):
            m = s1[4]["_" + key]
            if key in s2[4]:
                np.testing.assert_array_equal(m, s2[4]["_" + key])
                np.testing.assert_array_equal(s1[4][key][m], s2[4][key][m])
            else:
                assert not m.any()
        n_done += int(np.sum(s1[2] | s1[3]))
    assert n_done >= 5  # crashes, time limits and the autoresets after them were exercised


def test_native_vector_env_seeding_is_reproducible_and_distinct():
    def run(seed):
        venv = LunarSoftLandingVectorEnv(num_envs=3, time_limit_s=20.0)
        obs = [venv.reset(seed=seed)[0]]
        for _ in range(45):  # two autoresets per sub-env
            obs.append(venv.step(np.zeros((3, 1), np.float32))[0])
        return np.array(obs)

    a, b, c = run(5), run(5), run(6)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert not np.array_equal(a[0, 0], a[0, 1])  # sub-envs draw different states
    assert not np.array_equal(a[21], a[0])  # the next episode is a new draw


def test_vector_env_bad_actions_and_observation_from_state():
    venv = gym.make_vec("LunarSoftLanding-v0", num_envs=3,
                        vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    y = venv.unwrapped.state_nd
    bad = np.zeros((3, 1), np.float32)
    bad[1, 0] = np.nan
    with pytest.raises(ValueError, match="NaN or inf"):
        venv.step(bad)
    np.testing.assert_array_equal(venv.unwrapped.state_nd, y)
    obs = venv.step(np.zeros((3, 1), np.float32))[0]
    u = venv.unwrapped
    np.testing.assert_array_equal(u.observation_from_state(u.state_nd, u.t_s), obs)


def test_async_vector_env_with_pickled_envs():
    kw = dict(time_limit_s=30.0)
    env_fns = [lambda: gym.make("LunarSoftLanding-v0", **kw) for _ in range(2)]
    asyn = gym.vector.AsyncVectorEnv(env_fns, context="fork")
    sync = gym.vector.SyncVectorEnv(env_fns)
    try:
        np.testing.assert_array_equal(asyn.reset(seed=3)[0], sync.reset(seed=3)[0])
        for a in np.random.default_rng(1).uniform(-1, 1, (40, 2, 1)).astype(np.float32):
            r1 = asyn.step(a)
            r2 = sync.step(a)
            np.testing.assert_array_equal(r1[0], r2[0])
            np.testing.assert_array_equal(r1[1], r2[1])
    finally:
        asyn.close()
        sync.close()
