"""A learned law's specs: the minimum-time handover of thrust-limited landers
(``NAME:RUN:min_time_slack=M``) and its refusals."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3 import PPO

import lunar_env  # noqa: F401  (registers the ids)
from agents.laws import SB3Law
from guidance.flight import fly
from guidance.laws.min_time_touchdown import MinimumTimeHandover
from guidance.registry import LawContext, build_law
from lunar_env.uncertainty import get_uncertainty

V3 = "LunarPinpointLanding-v3"
#: the campaigns' flight: 2-s decisions with the IMU
KW = {"dt_s": 2.0, "sensors": ["imu"]}


@pytest.fixture(scope="module")
def model_zip(tmp_path_factory):
    """An untrained PPO policy for v3 with the IMU, saved as a model file."""
    env = gym.make(V3, **KW)
    model = PPO("MlpPolicy", env, policy_kwargs={"net_arch": [8]}, seed=0, device="cpu")
    path = tmp_path_factory.mktemp("v3_policy") / "model.zip"
    model.save(path)
    return path


def _law(spec, env_id=V3, **kw):
    kwargs = {**KW, **kw} if env_id == V3 else kw
    scenario = gym.make(env_id, **kwargs).unwrapped.scenario
    return build_law(spec, LawContext(env_id, kwargs, scenario))


def test_landers_with_slack_fly_the_learned_law_unchanged(model_zip):
    kw = {**KW, "uncertainty": get_uncertainty("none")}
    law = _law(f"ppo:{model_zip}:min_time_slack=5000")
    assert isinstance(law, MinimumTimeHandover) and isinstance(law.law, SB3Law)
    assert law.name == "ppo:model.zip:min_time_slack=5000"
    handed = fly(V3, law, 2, seed=3, env_kwargs=kw)
    plain = fly(V3, _law(f"ppo:{model_zip}"), 2, seed=3, env_kwargs=kw)
    # classified on the engine the minimum-time law's estimate measured: the nominal engine's
    # natural stop lies 20-35 km short of the site
    assert not law.handed_over.any()
    assert np.all(law.natural_stop_m < -20e3)
    np.testing.assert_array_equal(handed.is_success, plain.is_success)
    np.testing.assert_allclose(handed.fuel_used_kg, plain.fuel_used_kg, rtol=0, atol=1e-6)


def test_a_lander_handed_over_from_a_learned_law_is_landed_by_the_minimum_time_law(model_zip):
    # a slack wider than any lander's: the untrained policy flies the first decision only
    law = _law(f"ppo:{model_zip}:min_time_slack=50000")
    r = fly(V3, law, 1, seed=0, env_kwargs={**KW, "uncertainty": get_uncertainty("none")})
    assert law.handed_over[0]
    assert r.is_success[0] and r.touchdown_speed_m_s[0] < 1.5
    assert law.min_time.decisions["terminal"] > 0


@pytest.mark.parametrize("options, env_id, message", [
    ("min_time_slack=0", V3, "min_time_slack = 0"),
    ("min_time_slack=60000", V3, "min_time_slack = 60000"),
    ("min_time_slack=5000", "LunarPinpointLanding-v2", "LunarPinpointLanding-v3"),
    ("slack=5000", V3, "allowed: min_time_slack"),
])
def test_bad_handover_options_and_envs_are_refused_by_name(model_zip, options, env_id, message):
    with pytest.raises(ValueError, match=message):
        _law(f"ppo:{model_zip}:{options}", env_id)


def test_a_bad_slack_is_refused_before_the_run_is_looked_for(tmp_path):
    with pytest.raises(ValueError, match="min_time_slack = -1"):
        _law(f"dagger:{tmp_path / 'absent'}:min_time_slack=-1")
