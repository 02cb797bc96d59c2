"""The pinpoint feedback expert with a thrust reserve (``feedback:thrust_reserve=R``)."""

from __future__ import annotations

import numpy as np
import pytest

from guidance.flight import fly
from guidance.laws.engine_estimate import ThrustScaleEstimator
from guidance.laws.pontryagin_pinpoint import PinpointPontryaginExpert, PinpointReserveExpert
from guidance.registry import LawContext, build_law, parse_law_spec
from optimizers.indirect.pinpoint_feedback import PinpointFeedback
from optimizers.optimum import plant_scenario

ENV_ID = "LunarPinpointLanding-v2"
THROTTLED = {"dt_s": 2.0, "throttle_channel": True}


def _scenario(env_id=ENV_ID, **kwargs):
    import gymnasium as gym

    import lunar_env  # noqa: F401

    return gym.make(env_id, **kwargs).unwrapped.scenario


def test_the_reserve_law_lands_the_nominal_case_at_the_reserve_throttle():
    law = PinpointReserveExpert(_scenario(), thrust_reserve=0.05)
    out = fly(ENV_ID, law, 1, seed=0, env_kwargs=THROTTLED, record=[0])
    assert out.is_success[0]
    throttle = (out.records[0]["action"][:, 2] + 1.0) / 2.0
    # the nominal start is within reach of 95 % thrust: it is flown there, not at full thrust
    levels = np.isclose(throttle[:, None], [0.95, 1.0, 0.9], atol=1e-6)
    assert np.all(levels.any(axis=1))  # the three engines' throttles only
    assert np.mean(levels[:, 0]) > 0.9
    assert law.decisions["reserve"] > 0.9 * len(throttle)
    assert sum(law.decisions.values()) == len(throttle)
    np.testing.assert_array_equal(levels.sum(axis=0), [law.decisions[k] for k in
                                                       ("reserve", "full", "low")])


def test_a_derated_engine_out_of_reach_of_the_target_cold_starts_from_the_given_guess():
    sc = _scenario()
    nominal = PinpointFeedback(sc).nominal_costates()
    derated = plant_scenario(sc, 0.93, 1.0)  # measured: stops ~1.5 km beyond the target
    with pytest.raises(RuntimeError, match="nominal start"):
        PinpointFeedback(derated).nominal_costates()
    np.testing.assert_array_equal(
        PinpointFeedback(derated, nominal_guess=nominal).nominal_costates(), nominal)
    # within reach (95 %), the guess only starts the solve: the derated extremal is found,
    # longer than the nominal engine's
    within = PinpointFeedback(plant_scenario(sc, 0.95, 1.0), nominal_guess=nominal)
    z = within.nominal_costates()
    assert z[6] > nominal[6]
    np.testing.assert_allclose(z, PinpointFeedback(plant_scenario(sc, 0.95, 1.0))
                               .nominal_costates(), rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("env_id, kwargs, text, match", [
    (ENV_ID, {}, "feedback:thrust_reserve=0.05", "throttle channel"),
    ("LunarSoftLanding-v0", {"throttle_channel": True}, "feedback:thrust_reserve=0.05",
     "pinpoint"),
    (ENV_ID, {"throttle_channel": True}, "feedback:thrust_reserve=0.3", r"\(0, 0.25\)"),
    (ENV_ID, {"throttle_channel": True}, "feedback:thrust_reserve=0", r"\(0, 0.25\)"),
    (ENV_ID, {"throttle_channel": True}, "feedback:thrust_reserve=much", "not valid"),
    (ENV_ID, {"throttle_channel": True}, "feedback:reserve=0.05", "unknown option"),
    (ENV_ID, {"throttle_channel": True}, "feedback:stop_above_m=4", "options of thrust_reserve"),
    (ENV_ID, {"throttle_channel": True}, "feedback:thrust_reserve=0.05,stop_above_m=-1", ">= 0"),
    (ENV_ID, {"throttle_channel": True}, "feedback:thrust_reserve=0.05,switch_m=nan", ">= 0"),
    (ENV_ID, {"throttle_channel": True}, "feedback:thrust_reserve=0.05,estimate_thrust=maybe",
     "not valid"),
    (ENV_ID, {"throttle_channel": True}, "feedback:terminal_window=1", "options of thrust_reserve"),
    (ENV_ID, {"throttle_channel": True}, "feedback:thrust_reserve=0.05,terminal_window=2",
     "not valid"),
])
def test_a_bad_reserve_spec_is_refused_by_name(env_id, kwargs, text, match):
    context = LawContext(env_id=env_id, env_kwargs=kwargs, scenario=_scenario(env_id))
    with pytest.raises(ValueError, match=match):
        build_law(parse_law_spec(text), context)


def test_the_reserve_law_refuses_an_engine_without_a_throttle():
    import gymnasium as gym

    from guidance.law import FlightComputer

    law = PinpointReserveExpert(_scenario(), thrust_reserve=0.05)
    with pytest.raises(ValueError, match="throttle channel"):
        law.reset(FlightComputer.of(gym.make(ENV_ID), ENV_ID), np.arange(1))


def test_the_imu_gives_the_thrust_acceleration_scale_within_a_decision():
    """present thrust = mass estimate × measured acceleration / throttle: one decision at a
    throttle gives the scale, brought from the step's middle mass to the believed one."""
    est = ThrustScaleEstimator(1500.0)
    est.reset(3)
    on = np.ones(3, dtype=bool)
    est.observe(np.zeros((3, 3)), np.full(3, 500.0), on)  # nothing flown yet
    np.testing.assert_array_equal(est.scale, 1.0)
    est.record(np.array([0.9, 0.02, 0.5]), np.array([500.0, 500.0, 500.0]), on)
    # the engine gave 0.98 of its thrust over a step from 500 to 498 kg (believed)
    imu = np.zeros((3, 3))
    imu[:, 2] = 0.98 * 1500.0 * np.array([0.9, 0.02, 0.5]) / 499.0
    est.observe(imu, np.full(3, 498.0), np.array([True, True, False]))
    np.testing.assert_allclose(est.scale, [0.98, 1.0, 1.0], rtol=1e-12)
    est.reset_rows([0])
    assert est.scale[0] == 1.0
    with pytest.raises(ValueError, match="thrust_n"):
        ThrustScaleEstimator(float("nan"))


@pytest.mark.parametrize("thrust, mass_error_kg", [(0.96, 0.0), (1.04, 6.0)])
def test_the_flown_estimate_reads_the_engine_and_the_mass_error_from_the_imu(thrust,
                                                                             mass_error_kg):
    """Flown under ``standard`` with a pinned engine and wet-mass error: the estimate is the
    true thrust acceleration over the model's at the believed mass, τ·m̂/(m̂ + δ), to the
    IMU's errors (~0.1 %), from the first decisions on."""
    import gymnasium as gym

    env_kwargs = dict(THROTTLED, uncertainty="standard")
    pinned = {"errors": {"thrust_scale": thrust, "mass_error_kg": mass_error_kg}}
    law = PinpointReserveExpert(_scenario(), 0.05, estimate_thrust=True)
    venv = gym.make_vec(ENV_ID, num_envs=1, vectorization_mode="vector_entry_point",
                        **env_kwargs)
    from guidance.flight import decide, navigation
    from guidance.law import FlightComputer

    obs, _ = venv.reset(seed=0, options=pinned)
    core = venv.unwrapped
    computer = FlightComputer.of(core, ENV_ID)
    law.reset(computer, np.arange(1))
    start = np.ones(1, dtype=bool)
    for _ in range(10):
        nav, _ = navigation(core, computer, obs, np.ones(1, bool), start)
        obs, *_ = venv.step(decide(law, nav))
        start = np.zeros(1, dtype=bool)
    m_believed = core.navigation_state_nd[0, 6] * core.scenario.scaling().mass_kg
    truth = thrust * m_believed / (m_believed + mass_error_kg)
    assert law.estimator.scale[0] == pytest.approx(truth, rel=2e-3)
    venv.close()


def test_the_estimate_ignores_landers_that_stopped_and_starts_over_on_reset():
    est = ThrustScaleEstimator(1500.0)
    est.reset(1)
    off = np.zeros(1, dtype=bool)
    est.record(np.array([0.9]), np.array([500.0]), off)
    est.observe(np.ones((1, 3)), np.array([499.0]), off)
    assert est.scale[0] == 1.0
    est.reset(3)
    assert est.scale.shape == (3,) and np.all(est.scale == 1.0)


@pytest.mark.slow
def test_a_weak_and_a_strong_engine_land_with_the_estimate_and_not_without_a_reserve():
    # the constant-thrust expert misses by tens of kilometres
    env_kwargs = dict(THROTTLED, uncertainty="standard")
    pinned = {"errors": {"thrust_scale": [0.96, 1.04], "mass_error_kg": [0.0, 6.0]}}
    law = PinpointReserveExpert(_scenario(), 0.05, stop_above_m=4.0, estimate_thrust=True)
    out = fly(ENV_ID, law, 2, seed=0, env_kwargs=env_kwargs, reset_options=pinned)
    assert out.is_success.all(), (out.touchdown_speed_m_s, out.miss_distance_m)
    plain = fly(ENV_ID, PinpointPontryaginExpert(_scenario()), 2, seed=0, env_kwargs=env_kwargs,
                reset_options=pinned)
    assert not plain.is_success.any()


def test_a_stop_above_the_gate_falls_the_rest_at_the_free_fall_speed():
    # nominal world: the engine cuts off at rest 4 m above the gate; sqrt(2 g 4 m) = 3.6 m/s
    law = PinpointReserveExpert(_scenario(), 0.05, stop_above_m=4.0)
    out = fly(ENV_ID, law, 1, seed=0, env_kwargs=THROTTLED)
    assert out.is_success[0]
    assert out.touchdown_speed_m_s[0] == pytest.approx(np.sqrt(2 * 1.62 * 4.0), abs=0.15)


def test_the_terminal_window_lands_the_nominal_case_without_the_fall():
    law = PinpointReserveExpert(_scenario(), 0.05, stop_above_m=4.0, terminal_window=True)
    out = fly(ENV_ID, law, 1, seed=0, env_kwargs=THROTTLED, record=[0])
    assert out.is_success[0]
    throttle = (out.records[0]["action"][:, 2] + 1.0) / 2.0
    assert 2 <= law.decisions["window"] <= 6  # the last seconds, re-planned every decision
    assert law.last_status == ["window"]  # the status of the decision flown, per lander
    assert sum(law.decisions.values()) == len(throttle)  # each decision counted once
    # after its first step (which may brake hard), the window's throttle is well below the
    # extremal's 95 %: the weave's third of the thrust
    assert np.all(throttle[1 - law.decisions["window"]:] < 0.9)


@pytest.mark.slow
def test_the_terminal_window_lands_altitude_errors_that_defeat_the_fall():
    # navigated altitude 6 m above or below the truth at the gate (the terminal sensors' range
    # error pinned at 0.3 % of the altitude, 3σ of standard's 0.1 %, at 2 km): the fall from a
    # stop 4 m up crosses braking below the gate, or falls 10 m (5.7 m/s); the window spans ±8 m
    env_kwargs = dict(THROTTLED, uncertainty="standard")
    pinned = {"errors": {"sensor_position_fraction": [[0.003, 0.0, 0.0], [-0.003, 0.0, 0.0]]}}
    window = PinpointReserveExpert(_scenario(), 0.05, stop_above_m=12.0, terminal_window=True)
    out = fly(ENV_ID, window, 2, seed=0, env_kwargs=env_kwargs, reset_options=pinned)
    assert out.is_success.all(), (out.touchdown_speed_m_s, out.miss_distance_m)
    fall = fly(ENV_ID, PinpointReserveExpert(_scenario(), 0.05, stop_above_m=4.0), 2, seed=0,
               env_kwargs=env_kwargs, reset_options=pinned)
    assert not fall.is_success.any(), (fall.touchdown_speed_m_s, fall.miss_distance_m)


class _Enough(Exception):
    """Ends a test flight after its decisions of interest."""


def test_the_estimate_follows_the_controls_flown_when_another_policy_flies():
    # as a DAgger teacher the law labels while the student flies; fed its own controls, its
    # thrust estimate would credit the engine with the difference (70 % flown, 95 % asked)
    from agents.imitation.teachers import LawRolloutTeacher

    law = PinpointReserveExpert(_scenario(), 0.05, stop_above_m=12.0, estimate_thrust=True,
                                terminal_window=True)
    student = np.float32([0.0, 0.0, 2.0 * 0.7 - 1.0])  # 70 % throttle, the law asks ~95 %

    class Rollout(LawRolloutTeacher):
        def act(self, nav):
            if nav.t_s[0] >= 30.0:
                raise _Enough
            return super().act(nav)

    roll = Rollout(law, lambda obs: np.tile(student, (len(obs), 1)), switch_s=np.zeros(1))
    with pytest.raises(_Enough):
        fly(ENV_ID, roll, 1, seed=0, env_kwargs=dict(THROTTLED, uncertainty="standard"),
            reset_options={"errors": {"thrust_scale": [0.96], "mass_error_kg": [0.0]}})
    assert law.estimator.scale[0] == pytest.approx(0.96, rel=3e-3)
