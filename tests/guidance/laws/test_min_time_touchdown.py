"""The minimum-time feedback to touchdown and the handover of thrust-limited landers to it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import lunar_env  # noqa: F401
from guidance.flight import fly
from guidance.laws.min_time_touchdown import MinimumTimeHandover, MinimumTimeTouchdownLaw
from guidance.registry import LawContext, build_law
from lunar_env.uncertainty import get_uncertainty

V3 = "LunarPinpointLanding-v3"
#: the campaigns' flight: 2-s decisions with the IMU
KW = {"dt_s": 2.0, "sensors": ["imu"]}


def _law(spec, env_id=V3, **kw):
    kwargs = {**KW, **kw} if env_id == V3 else kw
    scenario = gym.make(env_id, **kwargs).unwrapped.scenario
    return build_law(spec, LawContext(env_id, kwargs, scenario))


def test_the_natural_stop_moves_toward_the_site_as_the_engine_weakens():
    law = _law("min-time")
    sc = law.scenario
    x0 = sc.state_nd(scaling=sc.scaling())
    stops = [law.natural_stop_m(x0, k) for k in (1.0, 0.97, 0.94)]
    # a nominal engine stops 20-35 km short of the site at full thrust (the slack the
    # explicit laws spend on their gates); a weaker one brakes less per second
    assert -35e3 < stops[0] < -20e3
    assert stops[0] < stops[1] < stops[2]


def test_a_thrust_limited_lander_is_handed_over_and_lands_where_zem_zev_does_not():
    # development case 10023 (thrust 3.4 % low under `standard`): its fuel optimum is one
    # full-thrust arc of 579 s, and ZEM/ZEV's gates lose it
    kw = {**KW, "uncertainty": get_uncertainty("standard")}
    plain = fly(V3, _law("zem-zev"), 1, seed=10023, env_kwargs=kw)
    law = _law("zem-zev:min_time_slack=5000")
    assert isinstance(law, MinimumTimeHandover)
    handed = fly(V3, law, 1, seed=10023, env_kwargs=kw)
    assert not plain.is_success[0]
    assert law.handed_over[0] and -5000.0 < law.natural_stop_m[0] < 5000.0
    assert handed.is_success[0]
    assert law.min_time.decisions["terminal"] > 0 and law.min_time.decisions["reserve"] > 100


def test_landers_with_slack_fly_the_explicit_law_unchanged():
    kw = {**KW, "uncertainty": get_uncertainty("none")}
    law = _law("zem-zev:min_time_slack=5000")
    handed = fly(V3, law, 2, seed=3, env_kwargs=kw)
    plain = fly(V3, _law("zem-zev"), 2, seed=3, env_kwargs=kw)
    assert not law.handed_over.any()
    assert np.all(law.natural_stop_m < -20e3)
    np.testing.assert_array_equal(handed.is_success, plain.is_success)
    np.testing.assert_allclose(handed.fuel_used_kg, plain.fuel_used_kg, rtol=0, atol=1e-6)


def test_the_minimum_time_law_lands_the_nominal_lander():
    law = _law("min-time")
    r = fly(V3, law, 1, seed=0, env_kwargs={**KW, "uncertainty": get_uncertainty("none")})
    assert r.is_success[0]
    assert r.touchdown_speed_m_s[0] < 1.5 and r.miss_distance_m[0] < 50.0
    assert law.decisions["terminal"] > 0


@pytest.mark.parametrize("spec, env_id, message", [
    ("min-time:reserve=0.5", V3, "reserve = 0.5"),
    ("min-time:stop_above=1", V3, "stop_above_m = 1"),
    ("min-time:switch_tgo=nan", V3, "switch_tgo_s = nan"),
    ("min-time:speed=3", V3, "speed"),
    ("min-time", "LunarPinpointLanding-v2", "LunarPinpointLanding-v3"),
    ("zem-zev:min_time_slack=0", V3, "min_time_slack = 0"),
    ("zem-zev:min_time_slack=5000", "LunarPinpointLanding-v2", "LunarPinpointLanding-v3"),
])
def test_bad_options_and_envs_are_refused_by_name(spec, env_id, message):
    with pytest.raises(ValueError, match=message.replace(".", r"\.")):
        _law(spec, env_id)


def test_the_law_refuses_a_scenario_that_does_not_land_on_its_site():
    scenario = gym.make("LunarPinpointLanding-v2").unwrapped.scenario
    with pytest.raises(ValueError, match="touchdown"):
        MinimumTimeTouchdownLaw(scenario)
