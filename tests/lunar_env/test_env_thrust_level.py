"""LunarSoftLanding-v0 at a chosen engine level ([003]: the thrust magnitude is a design
variable): the ``thrust_n`` argument and, equivalently, the throttle channel."""

import gymnasium as gym
import numpy as np
import pytest

import lunar_env  # noqa: F401

ENV_ID = "LunarSoftLanding-v0"


def _fly(env, action, n=20):
    env.reset(seed=0)
    for _ in range(n):
        obs, r, term, trunc, info = env.step(np.asarray(action, np.float32))
    return env.unwrapped.state_nd.copy(), info["fuel_used_kg"]


def test_thrust_level_equals_the_throttle_channel():
    a = gym.make(ENV_ID, scenario="wang2003", thrust_n=2000.0)
    b = gym.make(ENV_ID, scenario="wang2003", throttle_channel=True)
    assert a.unwrapped.scenario.vehicle.thrust_n == 2000.0
    ya, fa = _fly(a, [0.1])
    yb, fb = _fly(b, [0.1, 0.0])  # throttle (0 + 1)/2 = 0.5 of 4 kN
    np.testing.assert_allclose(ya, yb, rtol=1e-12, atol=1e-14)
    assert fa == pytest.approx(fb) and fa == pytest.approx(20 * 2000.0 / (300 * 9.8))


def test_bad_thrust_level():
    for bad in (0.0, -5.0, 4000.1, float("nan"), "lots", True):
        with pytest.raises(ValueError, match="thrust_n"):
            gym.make(ENV_ID, scenario="wang2003", thrust_n=bad)
