"""The sensors a lander flies: the IMU's specific force (truth, errors, observation channels)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import lunar_env  # noqa: F401
from lunar_env.uncertainty import get_uncertainty

IDS = ["LunarSoftLanding-v0", "LunarPinpointLanding-v2"]


def _full_throttle(env) -> np.ndarray:
    a = np.zeros(env.action_space.shape, dtype=np.float32)
    a[-1] = 1.0
    return a


@pytest.mark.parametrize("env_id", IDS)
def test_the_imu_reads_the_thrust_acceleration_in_the_nominal_world(env_id):
    env = gym.make(env_id, throttle_channel=True)
    core = env.unwrapped
    env.reset(seed=3)
    np.testing.assert_array_equal(core.sensor_readings()["imu"], 0.0)  # nothing flown yet
    thrust_n = core.scenario.vehicle.thrust_n
    for throttle in (1.0, 0.5):
        a = _full_throttle(env)
        a[-1] = 2.0 * throttle - 1.0
        m0 = core.state_nd[-1] * core.task.mass_ref_kg
        env.step(a)
        m1 = core.state_nd[-1] * core.task.mass_ref_kg
        f = core.sensor_readings()["imu"]
        # the step's mean acceleration: T·throttle over (about) its middle mass
        assert np.linalg.norm(f) == pytest.approx(thrust_n * throttle / (0.5 * (m0 + m1)),
                                                  rel=1e-5)
    # the action 0 on the angles thrusts along the middle of the bounds: braking, level-ish
    assert f[0] < 0.0


@pytest.mark.parametrize("env_id", IDS)
def test_the_imu_errors_are_the_models_and_the_same_whatever_the_batch(env_id):
    m = get_uncertainty("standard")
    kw = {"throttle_channel": True, "uncertainty": "standard"}
    big = gym.make_vec(env_id, num_envs=64, vectorization_mode="vector_entry_point", **kw)
    big.reset(seed=100)
    core = big.unwrapped
    act = np.tile(_full_throttle(gym.make(env_id, throttle_channel=True)), (64, 1))
    for _ in range(3):
        big.step(act)
    read = core.sensor_readings()["imu"]
    truth = core._batch.specific_force_m_s2()
    e = core.episode_errors
    resid = read - e.imu_scale[:, None] * truth
    # bias + noise: the bias's σ (1e-3 m/s²) dominates the noise's (3e-4/√dt)
    assert 0.5e-3 < np.std(resid) < 2e-3
    np.testing.assert_allclose(np.std(e.imu_scale - 1.0), m.imu_scale_factor, rtol=0.5)
    # case k's reading does not depend on the batch it flies in
    one = gym.make_vec(env_id, num_envs=1, vectorization_mode="vector_entry_point", **kw)
    one.reset(seed=105)
    for _ in range(3):
        one.step(act[:1])
    np.testing.assert_array_equal(one.unwrapped.sensor_readings()["imu"][0], read[5])


@pytest.mark.parametrize("env_id", IDS)
def test_the_imu_channels_of_the_observation(env_id):
    plain = gym.make(env_id)
    env = gym.make(env_id, sensors=("imu",), uncertainty="standard")
    n = plain.observation_space.shape[0]
    d = 2 if env_id.startswith("LunarSoft") else 3
    assert env.observation_space.shape == (n + d,)
    obs, _ = env.reset(seed=1)
    obs, *_ = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
    assert env.observation_space.contains(obs)
    q = env.unwrapped.observation_quantities(obs[None])
    np.testing.assert_allclose(q["imu_m_s2"][0], env.unwrapped.sensor_readings()["imu"],
                               rtol=1e-6, atol=1e-6)
    # the base columns are those of the env without the channel
    base = gym.make(env_id, uncertainty="standard")
    b0, _ = base.reset(seed=1)
    b1, *_ = base.step(np.zeros(base.action_space.shape, dtype=np.float32))
    np.testing.assert_array_equal(obs[:n], b1)


@pytest.mark.parametrize("env_id", IDS + ["LunarPinpointLanding-v3"])
def test_observation_from_state_has_the_sensor_channels_of_a_first_decision(env_id):
    """``observation_from_state`` returns the env's observation width with the sensor
    channels: in the nominal world exactly the reset's observation (an ideal IMU that has
    flown no step reads zero), single and vector env alike."""
    env = gym.make(env_id, sensors=("imu",))
    obs, _ = env.reset(seed=4)
    core = env.unwrapped
    got = core.observation_from_state(core.state_nd[None], np.array([core.t_s]))
    assert got.shape == (1,) + env.observation_space.shape
    np.testing.assert_array_equal(got[0], obs)
    vec = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point",
                       sensors=("imu",))
    vobs, _ = vec.reset(seed=4)
    vcore = vec.unwrapped
    np.testing.assert_array_equal(vcore.observation_from_state(vcore.state_nd, vcore.t_s),
                                  vobs)
    # and it decodes as an observation does
    q = core.observation_quantities(got)
    np.testing.assert_array_equal(q["imu_m_s2"], 0.0)


@pytest.mark.parametrize("bad, match", [(("lidar",), "unknown sensor 'lidar'"),
                                        (("imu", "imu"), "twice"), ("imu", "list of names")])
def test_a_bad_sensor_setting_is_refused_by_name(bad, match):
    with pytest.raises(ValueError, match=match):
        gym.make("LunarSoftLanding-v0", sensors=bad)
