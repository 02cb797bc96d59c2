"""LunarSoftLanding-v0: Gymnasium contract, physics of the step, and the reward's ranking."""

import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize

import lunar_env
from lunar_env import integrators as integ
from lunar_env.envs.soft_landing import (
    LunarSoftLandingEnv,
    action_from_thrust_angle,
    thrust_angle_from_action,
)

ENV_ID = "LunarSoftLanding-v0"
SUB = 2  # the envs' default substeps


def test_check_env_and_both_ids():
    env = gym.make(ENV_ID, render_mode="rgb_array")
    check_env(env.unwrapped, skip_render_check=False)
    env2 = gym.make("lunar_env:LunarSoftLanding-v0")
    assert isinstance(env2.unwrapped, LunarSoftLandingEnv)
    assert env.unwrapped.scenario.name == "zhu2007"


def test_thrust_angle_mapping_round_trip_and_clip():
    a = np.linspace(-1, 1, 11)
    np.testing.assert_allclose(action_from_thrust_angle(thrust_angle_from_action(a)), a)
    assert thrust_angle_from_action(1.0) == pytest.approx(np.pi / 2)
    assert thrust_angle_from_action(7.0) == thrust_angle_from_action(1.0)
    assert action_from_thrust_angle(3.0) == 1.0


def test_nan_action_raises_and_state_untouched():
    env = gym.make(ENV_ID).unwrapped
    env.reset(seed=1)
    env.step(np.array([0.2], np.float32))
    y, t = env.state_nd, env.t_s
    for bad in (np.nan, np.inf, -np.inf):
        with pytest.raises(ValueError, match="NaN or inf"):
            env.step(np.array([bad], np.float32))
    np.testing.assert_array_equal(env.state_nd, y)
    assert env.t_s == t
    env.step(np.array([0.2], np.float32))  # still usable


def test_out_of_range_actions_clip():
    e1, e2 = gym.make(ENV_ID).unwrapped, gym.make(ENV_ID).unwrapped
    e1.reset(seed=3)
    e2.reset(seed=3)
    o1 = e1.step(np.array([5.0]))[0]
    o2 = e2.step(np.array([1.0]))[0]
    np.testing.assert_array_equal(o1, o2)


def test_same_seed_same_episode_bit_for_bit():
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (60, 1)).astype(np.float32)
    runs = []
    for _ in range(2):
        env = gym.make(ENV_ID)
        obs, _ = env.reset(seed=123)
        traj = [obs]
        for a in acts:
            traj.append(env.step(a)[0])
        traj.append(env.reset()[0])  # the next episode comes from the same stream
        runs.append(np.array(traj))
    np.testing.assert_array_equal(runs[0], runs[1])
    env = gym.make(ENV_ID)
    assert not np.array_equal(env.reset(seed=124)[0], runs[0][0])


def test_reset_options_pin_the_state():
    env = gym.make(ENV_ID).unwrapped
    sc = env.scenario
    env.reset(seed=0, options={"nominal": True})
    np.testing.assert_array_equal(env.state_nd, sc.state_nd())
    si = np.array([sc.surface_radius_m + 3000.0, -20.0, 0.1, 100.0, 450.0])
    env.reset(options={"state_si": si})
    np.testing.assert_allclose(env.state_nd, sc.si_to_nd(si))
    env.reset(options={"state_nd": sc.state_nd()})
    np.testing.assert_array_equal(env.state_nd, sc.state_nd())
    with pytest.raises(ValueError, match="above the surface"):
        env.reset(options={"state_si": np.array([sc.surface_radius_m - 1, 0, 0, 0, 500.0])})


def test_observation_from_state_matches_step_and_info_units():
    env = gym.make(ENV_ID).unwrapped
    obs0, info = env.reset(seed=5)
    assert info["altitude_m"] == pytest.approx(env.state_nd[0] * env.scenario.scaling().length_m
                                                - env.scenario.surface_radius_m)
    obs, r, *_ , info = env.step(np.array([0.0], np.float32))
    np.testing.assert_array_equal(env.observation_from_state(env.state_nd[None],
                                                             np.array([env.t_s]))[0], obs)
    # one second at full thrust: fuel = F / (Isp g0) · 1 s, and the reward is -fuel/300 kg
    v = env.scenario.vehicle
    assert info["fuel_used_kg"] == pytest.approx(v.mass_flow_kg_s * 1.0, rel=1e-9)
    assert r == pytest.approx(-info["fuel_used_kg"] / (v.mass_kg - v.dry_mass_kg), rel=1e-12)
    assert info["time_s"] == pytest.approx(1.0)


@settings(max_examples=15, deadline=None)
@given(st.lists(st.floats(-3.0, 3.0), min_size=1, max_size=40), st.integers(0, 2**31 - 1),
       st.booleans())
def test_random_action_sequences_stay_in_space(actions, seed, throttle):
    env = gym.make(ENV_ID, throttle_channel=throttle, time_limit_s=30.0).unwrapped
    obs, _ = env.reset(seed=seed)
    assert env.observation_space.contains(obs)
    for a in actions:
        act = np.array([a, -a][: env.action_space.shape[0]], np.float32)
        obs, r, term, trunc, info = env.step(act)
        assert env.observation_space.contains(obs)
        assert np.isfinite(r)
        if term or trunc:
            break


def test_touchdown_from_low_state_and_free_fall_speed():
    """Engine cut-off at zero speed 100 m up, then free fall: v = sqrt(2 g h) at touchdown."""
    env = gym.make(ENV_ID).unwrapped
    sc = env.scenario
    R = sc.surface_radius_m
    # at rest 100 m above the surface, thrust straight down: speed grows from 0 (no minimum),
    # so the engine burns all the way down
    env.reset(options={"state_si": np.array([R + 100.0, 0.0, 0.0, 0.0, 400.0])})
    for _ in range(100):
        *_, term, trunc, info = env.step(np.array([-1.0]))
        if term:
            break
    assert term and not trunc and info["altitude_m"] == pytest.approx(0.0, abs=1e-6)
    g_down = sc.vehicle.thrust_n / 390.0 + sc.body.mu_m3_s2 / R**2  # bound: mass > 390 kg
    assert 0 < info["touchdown_speed_m_s"] <= np.sqrt(2 * g_down * 100.0) + 1e-6
    # moving up at 3 m/s, thrust down: the speed minimum (zero) is reached inside the step; the
    # engine cuts off and the lander falls freely from the apex: v_td = sqrt(v0² + 2 g h0)
    # (plus what the thrust added on the way up)
    env.reset(options={"state_si": np.array([R + 2.0, 3.0, 0.0, 0.0, 400.0])})
    _, r, term, trunc, info = env.step(np.array([-1.0]))
    assert term and info["is_success"]
    assert info["touchdown_speed_m_s"] < 5.0
    assert info["time_s"] < 5.0


# --------------------------------------------------------------------------------------------
# Reference: the fuel-optimal soft landing of zhu2007, computed here. A cubic thrust-angle law
# φ(s) = c0 + c1 s + c2 s² + c3 s³ (s = t/tf, [000]'s parameterisation) and tf are optimised by
# SLSQP: minimise tf (= fuel at constant thrust) subject to r(tf) = rL, vr(tf) = 0, v_t(tf) = 0,
# each evaluation one call of the shared compiled integrator.
# --------------------------------------------------------------------------------------------


def _cubic_law(c, tf_nd):
    coefs = np.zeros((1, 2, 4))
    coefs[0, 0] = np.asarray(c) / tf_nd ** np.arange(4)
    coefs[0, 1, 0] = 1.0
    return integ.PiecewisePolynomial.polynomial(coefs, 0.0, tf_nd)


@pytest.fixture(scope="module")
def optimal_cubic():
    sc = lunar_env.get_scenario("zhu2007")
    s = sc.scaling()
    p = sc.params()
    y0 = sc.state_nd()[None]
    r_l = float(s.length_nd(sc.surface_radius_m))
    t_unit = s.time_nd(600.0)

    def end_state(x):
        tf = x[4] * t_unit
        pr = integ.integrate(integ.PLANAR, y0, t0_nd=0.0, dt_nd=tf / 200, n_steps=200,
                             control=_cubic_law(x[:4], tf), params=p, dry_mass_nd=0.5)
        return pr.y_end[0]

    def residuals(x):
        y = end_state(x)
        v = s.velocity_m_s
        return np.array([(y[0] - r_l) * s.length_m / 1e3, y[1] * v / 10, y[0] * y[3] * v / 10])

    res = minimize(lambda x: x[4], np.array([0.0, 1.5, 0.0, 0.0, 1.0]), method="SLSQP",
                   constraints={"type": "eq", "fun": residuals},
                   options={"maxiter": 200, "ftol": 1e-12})
    assert np.max(np.abs(residuals(res.x))) < 1e-6, res
    tf_s = res.x[4] * 600.0
    return res.x[:4], tf_s, tf_s * sc.vehicle.mass_flow_kg_s


def _phi_of(c, tf_s, t_s):
    s = t_s / tf_s
    return c[0] + c[1] * s + c[2] * s**2 + c[3] * s**3


def test_reference_is_the_fuel_optimum(optimal_cubic):
    """Independent check of the reference: [000]'s Pontryagin optimum is 277.5765 kg."""
    _, _, fuel = optimal_cubic
    assert fuel == pytest.approx(277.5765, abs=0.05)


def _run(env, policy, options=None, seed=None):
    obs, info = env.reset(seed=seed, options=options)
    ret = 0.0
    k = 0
    while True:
        obs, r, term, trunc, info = env.step(np.atleast_1d(policy(k, obs)).astype(np.float32))
        ret += r
        k += 1
        if term or trunc:
            return ret, term, info


def test_reward_ranks_the_fuel_optimal_landing_best(optimal_cubic):
    c, tf_s, fuel = optimal_cubic
    env = gym.make(ENV_ID).unwrapped
    nominal = {"nominal": True}

    def optimal(k, obs):  # the law held over each 1 s step, sampled at the step's midpoint
        return action_from_thrust_angle(_phi_of(c, tf_s, k + 0.5))

    r_opt, term, info = _run(env, optimal, nominal)
    assert term and info["is_success"] and info["touchdown_speed_m_s"] < 2.0
    assert info["fuel_used_kg"] == pytest.approx(fuel, abs=0.5)

    others = {
        "crash early (thrust down)": lambda k, o: -1.0,
        "hover (thrust straight up)": lambda k, o: 1.0,
        "pure horizontal braking": lambda k, o: 0.0,
        "fly past (brakes 20° less)": lambda k, o: action_from_thrust_angle(
            _phi_of(c, tf_s, k + 0.5) + np.radians(20.0)),
        "cut off 5 s early": None,
    }
    returns = {}
    for name, pol in others.items():
        if pol is None:
            continue
        returns[name] = _run(env, pol, nominal)[0]
    # landing harder to save fuel: the optimal law, then the engine points down (cut-off speed
    # never reached) for the last 5 s
    returns["harder landing"] = _run(
        env, lambda k, o: optimal(k, o) if k < tf_s - 5 else -1.0, nominal)[0]
    # 100 random policies (i.i.d. uniform actions each step), batched in the native vector env
    venv = gym.make_vec(ENV_ID, num_envs=100, vectorization_mode="vector_entry_point")
    venv.reset(seed=7, options=nominal)
    rng = np.random.default_rng(7)
    ret = np.zeros(100)
    live = np.ones(100, dtype=bool)
    while live.any():
        _, r, term, trunc, _ = venv.step(rng.uniform(-1, 1, (100, 1)).astype(np.float32))
        ret += np.where(live, r, 0.0)
        live &= ~(term | trunc)
    returns["best of 100 random"] = float(ret.max())
    for name, r in returns.items():
        assert r < r_opt, (name, r, r_opt)


def test_open_loop_replay_lands_where_the_integrator_predicts(optimal_cubic):
    """Replaying a control step by step gives, at every step, the state one long integrator
    call predicts for the same piecewise-constant control (same RK4 grid), and the same
    touchdown."""
    c, tf_s, _ = optimal_cubic
    env = gym.make(ENV_ID).unwrapped
    sc = env.scenario
    s = sc.scaling()
    y0 = sc.state_nd()
    n_env_steps = int(tf_s) + 3
    phis = _phi_of(c, tf_s, np.arange(n_env_steps) + 0.5)
    acts = action_from_thrust_angle(phis)
    dt = s.time_nd(1.0)
    breaks = (np.arange(n_env_steps + 1) * dt)[None]
    coefs = np.zeros((1, n_env_steps, 2, 1))
    coefs[0, :, 0, 0] = thrust_angle_from_action(acts)
    coefs[0, :, 1, 0] = 1.0
    pred = integ.integrate(integ.PLANAR, y0[None], t0_nd=0.0, dt_nd=dt / SUB,
                           n_steps=SUB * n_env_steps, control=integ.PiecewisePolynomial(breaks,
                                                                                     coefs),
                           params=sc.params(), dry_mass_nd=0.5,
                           events=(integ.RadiusCrossing(s.length_nd(sc.surface_radius_m)),
                                   integ.SpeedMinimum()), record=True)
    env.reset(options={"nominal": True})
    L, V = s.length_m, s.velocity_m_s
    for k, a in enumerate(acts):
        *_, term, trunc, info = env.step(np.array([a]))
        if term or trunc:
            break
        y_pred = pred.states[0, SUB * (k + 1)]
        assert abs(env.state_nd[0] - y_pred[0]) * L < 1.0
        assert abs(env.state_nd[1] - y_pred[1]) * V < 0.1
        assert abs(env.state_nd[0] * env.state_nd[3] - y_pred[0] * y_pred[3]) * V < 0.1
    assert term
    # the prediction stops at the engine cut-off (speed minimum) or touchdown; a free fall from
    # there (the public integrator, throttle 0) gives the touchdown
    y_c = pred.y_end
    if pred.status[0] == integ.STATUS_SPEED_MIN:
        fall = integ.integrate(integ.PLANAR, y_c, t0_nd=pred.t_end, dt_nd=dt / SUB, n_steps=4000,
                               control=integ.PiecewisePolynomial.constant(
                                   np.zeros((1, 2)), pred.t_end, pred.t_end + 1000 * dt),
                               params=sc.params(), dry_mass_nd=0.5,
                               events=(integ.RadiusCrossing(s.length_nd(sc.surface_radius_m)),))
        y_c = fall.y_end
        t_c = fall.t_end[0]
    else:
        t_c = pred.t_end[0]
    v_td = np.hypot(y_c[0, 1], y_c[0, 0] * y_c[0, 3]) * V
    assert info["touchdown_speed_m_s"] == pytest.approx(v_td, abs=0.1)
    assert info["time_s"] == pytest.approx(t_c * s.time_s, abs=1e-3)
    assert abs(env.state_nd[2] - y_c[0, 2]) * L < 1.0


def test_pickle_and_render():
    env = gym.make(ENV_ID, render_mode="rgb_array").unwrapped
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.array([0.1], np.float32))
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    assert frame.std() > 0
    clone = pickle.loads(pickle.dumps(env))
    np.testing.assert_array_equal(clone.state_nd, env.state_nd)
    o1 = clone.step(np.array([0.3], np.float32))[0]
    o2 = env.step(np.array([0.3], np.float32))[0]
    np.testing.assert_array_equal(o1, o2)


def test_other_planar_scenario_and_bad_scenario():
    env = gym.make(ENV_ID, scenario="wang2003", throttle_channel=True).unwrapped
    obs, _ = env.reset(seed=0)
    assert env.action_space.shape == (2,)
    # throttle 0 (action -1): no fuel burnt, but the speed minimum does not cut off (high speed)
    _, r, *_ , info = env.step(np.array([0.0, -1.0], np.float32))
    assert info["fuel_used_kg"] == 0.0 and r == 0.0
    with pytest.raises(ValueError, match="not planar"):
        gym.make(ENV_ID, scenario="peng2012")


def test_pontryagin_optimum_replayed_scores_at_least_as_well(optimal_cubic):
    """Second, independent reference: the indirect (Pontryagin) optimum of
    :mod:`optimizers.indirect.planar`, sampled at the step midpoints, lands softly and its return is
    at least that of the cubic law (it is the better optimum)."""
    from optimizers.indirect.planar import solve_planar_min_fuel

    c, tf_s, _ = optimal_cubic
    env = gym.make(ENV_ID).unwrapped
    sol = solve_planar_min_fuel(env.scenario)
    r_pmp, term, info = _run(
        env, lambda k, o: action_from_thrust_angle(sol.thrust_angle_at(k + 0.5)),
        {"nominal": True})
    r_cubic, *_ = _run(env, lambda k, o: action_from_thrust_angle(_phi_of(c, tf_s, k + 0.5)),
                       {"nominal": True})
    assert term and info["is_success"]
    assert r_pmp >= r_cubic - 1e-3


def test_regression_cutoff_under_the_surface_is_a_touchdown():
    """Regression: a braking lander whose speed minimum falls a few mm below the surface inside
    a step used to fall through the Moon until the time limit. It must touch down at once."""
    sc = lunar_env.get_scenario("zhu2007")
    env = gym.make("LunarSoftLanding-v0")
    # 5 cm up, sinking at 0.28 m/s and sliding at 1.24 m/s, thrust angle 34.8°: the state the
    # re-planning expert reached in the reported case
    state = np.array([sc.target.radius_m + 0.0478, -0.28, 0.0, 1.24, 325.0])
    env.reset(options={"state_si": state})
    a = np.array([np.radians(34.8) / (np.pi / 2)], dtype=np.float32)
    _, _, terminated, truncated, info = env.step(a)
    assert terminated and not truncated
    assert info["is_success"]
    assert info["altitude_m"] == pytest.approx(0.0, abs=1e-3)
    assert info["touchdown_speed_m_s"] < 1.0
