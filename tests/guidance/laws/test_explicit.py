"""Explicit guidance (guidance.laws.apollo, guidance.explicit): each law against its definition,
its bad settings, and short flights of both envs."""

import math

import numpy as np
import pytest

from guidance import explicit as gd
from guidance.flight import fly
from guidance.laws.apollo import AugmentedApolloLaw, GravityTurnLaw
from guidance.registry import LawContext, build_law

RNG = np.random.default_rng(30)
G_MOON = np.array([0.0, 0.0, -1.62])  # uniform-gravity limit (m/s²), up last


def _random_case(n=16, d=3):
    r = RNG.normal(0.0, 5e3, (n, d))
    v = RNG.normal(0.0, 100.0, (n, d))
    r_t = RNG.normal(0.0, 5e3, (n, d))
    v_t = RNG.normal(0.0, 5.0, (n, d))
    a_t = RNG.normal(0.0, 1.0, (n, d))
    t_go = RNG.uniform(20.0, 300.0, n)
    return r, v, r_t, v_t, a_t, t_go


def test_apollo_form_is_the_quadratic_acceleration_profile_klumpp1974():
    """(K) is a₀ of the quadratic acceleration profile meeting r_T, v_T, a_T at t_go."""
    sp = pytest.importorskip("sympy")
    t, T, r, v, rT, vT, aT = sp.symbols("t T r v r_T v_T a_T", real=True)
    a0, a1, a2 = sp.symbols("a0 a1 a2")
    acc = a0 + a1 * t + a2 * t**2
    vel = v + sp.integrate(acc, (t, 0, t))
    pos = r + sp.integrate(vel, (t, 0, t))
    sol = sp.solve([pos.subs(t, T) - rT, vel.subs(t, T) - vT, acc.subs(t, T) - aT],
                   [a0, a1, a2], dict=True)[0]
    published = aT - 6 * (vT + v) / T + 12 * (rT - r) / T**2
    assert sp.simplify(sol[a0] - published) == 0
    # [K74] prints it with the target-referenced time T' = -t_go: 12(rT-r)/T'^2 + 6(vT+v)/T' + aT
    tp = sp.symbols("Tp")
    klumpp = 12 * (rT - r) / tp**2 + 6 * (vT + v) / tp + aT
    assert sp.simplify(klumpp.subs(tp, -T) - published) == 0


def test_gain_12_equals_apollo_published_form():
    r, v, r_t, v_t, a_t, t_go = _random_case()
    thrust = gd.augmented_apollo_thrust(r, v, r_t, v_t, a_t, G_MOON, t_go, 12.0)
    total = gd.apollo_published_accel(r, v, r_t, v_t, a_t, t_go)
    np.testing.assert_allclose(thrust + G_MOON, total, rtol=1e-12, atol=1e-9)


def test_gain_6_equals_zem_zev_guo_hawkins_wie():
    r, v, r_t, v_t, a_t, t_go = _random_case()
    thrust = gd.augmented_apollo_thrust(r, v, r_t, v_t, a_t, G_MOON, t_go, 6.0)
    zem = r_t - (r + v * t_go[:, None] + 0.5 * G_MOON * t_go[:, None] ** 2)
    zev = v_t - (v + G_MOON * t_go[:, None])
    expected = 6.0 * zem / t_go[:, None] ** 2 - 2.0 * zev / t_go[:, None]
    np.testing.assert_allclose(thrust, expected, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(gd.zem_zev_thrust(r, v, r_t, v_t, G_MOON, t_go), expected,
                               rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("k_r", [6.0, 9.0, 12.0])
def test_unconstrained_law_reaches_target_exactly_in_uniform_gravity(k_r):
    """Closed loop with throttle (any magnitude), t_go = T − t, integrated by DOP853: the
    double integrator ends on (r_T, v_T) (the error vanishes with the stop time ε as
    ε^min(3, k_r/3))."""
    from scipy.integrate import solve_ivp

    r0, v0 = np.array([-3000.0, 500.0, 2000.0]), np.array([80.0, -5.0, -30.0])
    r_t, v_t, a_t = np.array([0.0, 0.0, 30.0]), np.array([0.0, 0.0, -1.0]), np.zeros(3)
    T = 120.0

    def rhs(t, y):
        a = gd.augmented_apollo_thrust(y[None, :3], y[None, 3:], r_t, v_t, a_t, G_MOON,
                                       np.array([T - t]), k_r)[0]
        return np.concatenate([y[3:], a + G_MOON])

    eps = 1e-3
    sol = solve_ivp(rhs, (0.0, T - eps), np.concatenate([r0, v0]), method="DOP853",
                    rtol=1e-11, atol=1e-9)
    assert sol.success
    # ε = 1 ms before the end: on the target to the metre's thousandth from 3.6 km away
    np.testing.assert_allclose(sol.y[:3, -1], r_t - v_t * eps, atol=2e-3)   # m
    np.testing.assert_allclose(sol.y[3:, -1], v_t, atol=2e-2)               # m/s, from 86 m/s


def test_free_position_law_reaches_the_velocity_target():
    v, g, t_go = np.array([[100.0, -3.0]]), np.array([[0.2, -1.6]]), np.array([50.0])
    a = gd.free_position_thrust(v, 0.0, g, t_go)
    np.testing.assert_allclose(v + (a + g) * t_go[:, None], 0.0, atol=1e-12)


@pytest.mark.parametrize("branch", ["short", "long"])
def test_thrust_matched_tgo_meets_the_thrust_level(branch):
    r, v, r_t, v_t, a_t, _ = _random_case(n=32)
    v[:, 0] += 300.0  # a lander moving toward its target, as in a descent

    def command(t, rows):
        return gd.augmented_apollo_thrust(r[rows], v[rows], r_t[rows], v_t[rows], a_t[rows],
                                          G_MOON, t, 6.0)

    accel = np.full(32, 4.0)
    t_go, found = gd.thrust_matched_tgo(command, accel, 0.05, 3000.0, branch=branch)
    assert found.any()
    mag = np.linalg.norm(command(t_go, slice(None)), axis=1)
    np.testing.assert_allclose(mag[found], accel[found], rtol=1e-6)


@pytest.mark.parametrize("bad", [0.0, -5.0, math.nan, math.inf])
def test_bad_tgo_is_a_clear_error(bad):
    r, v, r_t, v_t, a_t, t_go = _random_case(n=3)
    t_go[1] = bad
    with pytest.raises(ValueError, match="t_go"):
        gd.augmented_apollo_thrust(r, v, r_t, v_t, a_t, G_MOON, t_go, 12.0)
    with pytest.raises(ValueError, match="t_go"):
        gd.apollo_published_accel(r, v, r_t, v_t, a_t, t_go)


@pytest.mark.parametrize("bad", [5.9, 3.0, 25.0, math.nan, math.inf, "12", True, None])
def test_gain_out_of_range_is_a_clear_error(bad):
    with pytest.raises(ValueError, match="k_r"):
        gd.check_gain(bad)
    with pytest.raises(ValueError, match="k_r"):
        AugmentedApolloLaw(k_r=bad)


@pytest.mark.parametrize("key, value", [("tgo_margin", -0.9), ("tgo_margin", math.nan),
                                        ("lead_s", -1.0), ("lead_s", 11.0),
                                        ("tgo_rule", "fast")])
def test_bad_law_settings_are_clear_errors(key, value):
    with pytest.raises(ValueError, match=key):
        AugmentedApolloLaw(**{key: value})


def _flown(env_id, law, n, **env_kwargs):
    return fly(env_id, law, n, seed=2026, env_kwargs=env_kwargs or None)


def test_nan_navigated_state_is_a_clear_error_not_a_nan_action():
    import gymnasium as gym

    import lunar_env  # noqa: F401
    from guidance.law import FlightComputer, Navigation, actions_of

    env = gym.make("LunarSoftLanding-v0")
    computer = FlightComputer.of(env, "LunarSoftLanding-v0")
    env.close()
    law = AugmentedApolloLaw()
    law.reset(computer, np.arange(2))
    state = np.tile(computer.scenario.state_nd(), (2, 1))
    state[1, 1] = np.nan
    nav = Navigation(obs=np.zeros((2, 5), np.float32), state_nd=state, t_s=np.zeros(2),
                     active=np.ones(2, bool), frame_of=computer.frame_of)
    with pytest.raises(ValueError, match="non-finite"):
        law.act(nav)
    state[1, 1] = state[0, 1]
    nav = Navigation(obs=np.zeros((2, 5), np.float32), state_nd=state, t_s=np.zeros(2),
                     active=np.ones(2, bool), frame_of=computer.frame_of)
    act = actions_of(computer, law.act(nav))
    assert act.shape == (2, 1) and np.isfinite(act).all()


@pytest.mark.parametrize("spec", ["apollo", "zem-zev"])
def test_laws_land_planar_cases_with_the_constant_thrust_engine(spec):
    law = build_law(spec, LawContext("LunarSoftLanding-v0", {}, None))
    out = _flown("LunarSoftLanding-v0", law, 3)
    assert out.is_success.all(), out.touchdown_speed_m_s
    assert (out.touchdown_speed_m_s < 2.0).all()


@pytest.mark.parametrize("spec", ["apollo", "zem-zev"])
def test_laws_land_pinpoint_cases_with_the_throttled_engine(spec):
    law = build_law(spec, LawContext("LunarPinpointLanding-v2", {}, None))
    out = _flown("LunarPinpointLanding-v2", law, 2, throttle_channel=True)
    assert out.is_success.all(), (out.touchdown_speed_m_s, out.miss_distance_m)
    assert (out.miss_distance_m < 50.0).all()


def test_specs_parse_gains_and_options():
    ctx = LawContext("LunarSoftLanding-v0", {}, None)
    assert build_law("apollo", ctx).k_r == 12.0
    assert build_law("zem-zev", ctx).k_r == 6.0
    law = build_law("apollo:kr=9.5,tgo_margin=0.02,lead=2.2,tgo=rocket,rotation=0", ctx)
    assert (law.k_r, law.tgo_margin, law.lead_s, law.tgo_rule, law.include_rotation) == \
        (9.5, 0.02, 2.2, "rocket", False)
    assert law.name == "apollo:kr=9.5,tgo_margin=0.02,lead=2.2,tgo=rocket,rotation=0"
    law = build_law("apollo:tgo=rocket,terminal=4,aim=5", ctx)
    assert (law.terminal_s, law.aim_above_m) == (4.0, 5.0)
    assert isinstance(build_law("gravity-turn", ctx), GravityTurnLaw)
    with pytest.raises(ValueError, match="aim_above_m"):
        build_law("apollo:aim=-1", ctx)
    with pytest.raises(ValueError, match="unknown option"):
        build_law("apollo:gain=3", ctx)
    with pytest.raises(ValueError, match="k_r"):
        build_law("zem-zev:kr=4", ctx)
    with pytest.raises(ValueError, match="rotation"):
        build_law("gravity-turn:rotation=maybe", ctx)
    with pytest.raises(ValueError, match="no argument"):
        build_law("apollo:runs/x", ctx)
