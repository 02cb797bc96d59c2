"""Every registered lander id (looped over Gymnasium's registry, so no id is forgotten): the
task contract, check_env, pickling, and single env = native vector env bit for bit."""

import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode

import lunar_env  # noqa: F401  (registers the ids)
from lunar_env.envs import LanderEnv, LanderVectorEnv
from lunar_env.envs.core import LanderBatch
from lunar_env.envs.task import LandingTask, StepSettings

LANDER_IDS = sorted(env_id for env_id, spec in gym.registry.items()
                    if env_id.startswith("Lunar") and isinstance(spec.entry_point, str)
                    and spec.entry_point.startswith("lunar_env."))
INFO_KEYS = ("fuel_used_kg", "is_success", "altitude_m", "time_s", "touchdown_speed_m_s",
             "miss_distance_m")


def test_the_registry_loop_sees_every_lander_env():
    """Guards the loops below against covering nothing (or a renamed entry point)."""
    assert {"LunarSoftLanding-v0", "LunarPinpointLanding-v0", "LunarPinpointLanding-v1",
            "LunarPinpointLanding-v2", "LunarPinpointLanding-v3"} <= set(LANDER_IDS)
    for env_id in LANDER_IDS:
        assert gym.registry[env_id].vector_entry_point is not None, env_id


@pytest.mark.parametrize("env_id", LANDER_IDS)
def test_check_env_and_pickle_round_trip(env_id):
    env = gym.make(env_id).unwrapped
    assert isinstance(env, LanderEnv)
    check_env(env)
    env.reset(seed=1)
    for _ in range(5):
        env.step(env.action_space.sample())
    clone = pickle.loads(pickle.dumps(env))
    a = np.array([0.2, -0.4, 0.9][:env.action_space.shape[0]], dtype=np.float32)
    for _ in range(3):
        s1, s2 = env.step(a), clone.step(a)
        np.testing.assert_array_equal(s1[0], s2[0])
        assert s1[1:] == s2[1:]


@pytest.mark.parametrize("env_id", LANDER_IDS)
def test_single_env_results_survive_later_steps(env_id):
    """The single env steps through the batch's scratch buffers: what it returned must not
    change when it steps again (fresh observation, Python scalars in reward and info)."""
    env = gym.make(env_id).unwrapped
    obs, _ = env.reset(seed=2)
    a = np.zeros(env.action_space.shape, dtype=np.float32)
    out = env.step(a)
    kept = (out[0].copy(), out[1], dict(out[4]))
    assert type(out[1]) is float and all(type(v) in (float, bool) for v in out[4].values())
    env.step(a)
    np.testing.assert_array_equal(out[0], kept[0])
    assert out[1] == kept[1] and out[4] == kept[2]
    # the batch's scratch flags are read-only: a caller cannot corrupt later steps
    batch = LanderBatch(env.task, 1)
    batch.set_state(0, env.state_nd)
    res = batch.step(env.task.controls_from_actions(a[None]), scratch=True)
    assert not res["terminated"][0]  # a step in mid-descent
    with pytest.raises(ValueError, match="read-only"):
        res["terminated"][0] = True


@pytest.mark.parametrize("env_id", LANDER_IDS)
def test_task_implements_the_contract_and_is_frozen(env_id):
    env = gym.make(env_id, throttle_channel=True).unwrapped
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point").unwrapped
    assert isinstance(venv, LanderVectorEnv)
    for task in (env.task, venv.task):
        assert isinstance(task, LandingTask) and isinstance(task.settings, StepSettings)
        assert not type(task).__abstractmethods__
        assert task.gate_range_m == venv.gate_range_m
    # throttle_channel=True adds the channel, unless the task's engine always throttles (v3)
    built_in = venv.task.throttle_channel
    assert env.task.throttle_channel is True and env.action_space.shape[0] == \
        venv.single_action_space.shape[0] + (0 if built_in else 1)
    with pytest.raises(AttributeError, match="frozen"):
        env.task.dt_nd = 1.0
    with pytest.raises(AttributeError, match="frozen"):
        env.task.r_stop_nd = 0.5
    with pytest.raises(AttributeError):
        env.task.dt_s = 2.0  # a read-only view of the frozen settings
    with pytest.raises(AttributeError):
        env.task.settings.dt_s = 2.0
    # a pickled task stays frozen
    with pytest.raises(AttributeError, match="frozen"):
        pickle.loads(pickle.dumps(env.task)).h_nd = 1.0


def _actions(rng, n_steps, n_envs, dim):
    a = rng.uniform(-1.0, 1.0, (n_steps, n_envs, dim))
    a[:, 0, 0] = -1.0  # sub-env 0 dives: a termination inside the run
    return a.astype(np.float32)


@pytest.mark.parametrize("kwargs", [dict(time_limit_s=200.0),
                                    dict(time_limit_s=200.0, throttle_channel=True, dt_s=2.0)],
                         ids=["default", "throttle"])
@pytest.mark.parametrize("env_id", LANDER_IDS)
def test_single_env_and_native_vector_env_step_identically(env_id, kwargs):
    """Through terminations, truncations and NEXT_STEP autoresets, sub-env i of the native
    vector env is a single env reset with seed + i: observations, rewards, flags and every
    info key, the task's own included (where defined, and undefined in the same places), bit
    for bit."""
    n = 3
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    sync = gym.vector.SyncVectorEnv([lambda: gym.make(env_id, **kwargs) for _ in range(n)],
                                    autoreset_mode=AutoresetMode.NEXT_STEP)
    o1, i1 = venv.reset(seed=7)
    o2, i2 = sync.reset(seed=7)
    np.testing.assert_array_equal(o1, o2)
    n_term = n_trunc = 0
    n_steps = int(260 / kwargs["dt_s"]) if "dt_s" in kwargs else 260  # past the time limit
    for a in _actions(np.random.default_rng(3), n_steps, n, venv.single_action_space.shape[0]):
        s1, s2 = venv.step(a), sync.step(a)
        for x, y in zip(s1[:4], s2[:4], strict=True):
            np.testing.assert_array_equal(x, y)
            assert x.dtype == y.dtype
        for key in (*INFO_KEYS, *venv.unwrapped.task.extra_info_keys):
            if key == "miss_distance_m" and not venv.unwrapped.has_target:
                assert key not in s1[4] and key not in s2[4]
                continue
            m = s1[4]["_" + key]
            if key in s2[4]:
                np.testing.assert_array_equal(m, s2[4]["_" + key])
                np.testing.assert_array_equal(s1[4][key][m], s2[4][key][m])
            else:
                assert not m.any(), key
        n_term += int(s1[2].sum())
        n_trunc += int(s1[3].sum())
    assert n_term >= 1 and n_trunc >= 1  # both endings and the autoresets after them ran
