"""LunarPinpointLanding-v3: pinpoint landing to touchdown with a throttleable engine. The
Gymnasium contract, the action and observation maps, touchdown located inside the step (against
DOP853), no engine cut-off at a speed minimum, propellant exhaustion and the fall, the verdict's
limits, bad arguments and the reward's ranking. (check_env, pickling, seeded determinism and
single = vector bit for bit for every id: test_env_registry.py.)"""

from __future__ import annotations

import math
import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from lunar_env import dynamics as dyn
from lunar_env import get_scenario
from lunar_env import integrators as integ
from lunar_env.envs.pinpoint_touchdown import (
    OBSERVATION_NAMES,
    SUCCESS_HORIZONTAL_SPEED_M_S,
    SUCCESS_MISS_M,
    SUCCESS_VERTICAL_SPEED_M_S,
    LunarPinpointTouchdownEnv,
    action_from_throttle,
    throttle_from_action,
)

ENV_ID = "LunarPinpointLanding-v3"
SC = get_scenario("peng2012_touchdown")
VERTICAL_MIN = np.array([1.0, 0.0, -1.0], np.float32)  # α = 90°, minimum throttle


def _site_frame():
    """Unit vectors (up, east, north) at the target."""
    tgt = SC.target_position_m()
    up = tgt / np.linalg.norm(tgt)
    east = np.cross([0.0, 0.0, 1.0], up)
    east /= np.linalg.norm(east)
    return tgt, up, east, np.cross(up, east)


def _state_si(height_m, v_up_m_s, mass_kg=450.0, offset_east_m=0.0, v_east_m_s=0.0):
    """Moon-fixed SI state ``height_m`` above the target (offset east), moving up and east."""
    tgt, up, east, _ = _site_frame()
    pos = tgt + height_m * up + offset_east_m * east
    return np.concatenate([pos, v_up_m_s * up + v_east_m_s * east, [mass_kg]])


def _reference(y0_nd, control, t_span_nd, events=None):
    """DOP853 of the shared model with a held (α, β, throttle)."""
    return integ.integrate_reference(integ.MOON3D, y0_nd, t_span_nd, lambda t: control,
                                     SC.params(), events=events, dense_output=True)


def test_check_env_render_and_registration():
    env = gym.make(ENV_ID, render_mode="rgb_array")
    check_env(env.unwrapped, skip_render_check=False)
    assert isinstance(gym.make("lunar_env:" + ENV_ID).unwrapped, LunarPinpointTouchdownEnv)
    u = env.unwrapped
    assert u.scenario.name == "peng2012_touchdown" and u.scenario.family == "pinpoint_touchdown"
    assert u.action_space.shape == (3,) and u.observation_space.shape == (8,)
    assert u.success_thresholds == {
        "speed_m_s": pytest.approx(math.hypot(3.0, 1.2)), "miss_m": 100.0,
        "vertical_speed_m_s": 3.0, "horizontal_speed_m_s": 1.2}
    assert (SUCCESS_MISS_M, SUCCESS_VERTICAL_SPEED_M_S, SUCCESS_HORIZONTAL_SPEED_M_S) == \
        (100.0, 3.0, 1.2)
    assert not u.task.engine_cutoff and gym.make("LunarPinpointLanding-v2").unwrapped.task \
        .engine_cutoff
    env.reset(seed=0)
    for _ in range(3):
        env.step(env.action_space.sample())
    frame = env.render()
    assert frame.ndim == 3 and frame.dtype == np.uint8
    clone = pickle.loads(pickle.dumps(u))
    np.testing.assert_array_equal(clone.step(VERTICAL_MIN)[0], u.step(VERTICAL_MIN)[0])


def test_action_maps_onto_the_scenario_bounds_and_the_throttle_range():
    task = gym.make(ENV_ID).unwrapped.task
    u = task.controls_from_actions(np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0],
                                             [0.0, 0.0, 0.0], [5.0, -5.0, 9.0]]))
    np.testing.assert_allclose(u[0], [math.radians(-50.0), 0.0, 0.2])
    np.testing.assert_allclose(u[1], [math.radians(90.0), 2 * math.pi, 1.0])
    np.testing.assert_allclose(u[2], [math.radians(20.0), math.pi, 0.6])  # β = 180°: brake
    np.testing.assert_allclose(u[3], [math.radians(90.0), 0.0, 1.0])  # clipped
    assert throttle_from_action(-1.0) == pytest.approx(SC.throttle_min) == 0.2
    acts = np.random.default_rng(0).uniform(-1, 1, (20, 3)).astype(np.float32)
    np.testing.assert_allclose(task.actions_from_controls(task.controls_from_actions(acts)),
                               acts, atol=1e-6)
    np.testing.assert_allclose(action_from_throttle(throttle_from_action(acts[:, 2])),
                               acts[:, 2], atol=1e-6)
    assert action_from_throttle(0.05) == -1.0  # below the engine's floor


def test_nan_action_raises_and_leaves_the_state_untouched():
    env = gym.make(ENV_ID).unwrapped
    env.reset(seed=2)
    env.step(VERTICAL_MIN)
    y = env.state_nd
    for bad in ([0.0, np.nan, 0.0], [np.inf, 0.0, 0.0], [0.0, 0.0, -np.inf]):
        with pytest.raises(ValueError, match="NaN or inf"):
            env.step(np.array(bad, np.float32))
        np.testing.assert_array_equal(env.state_nd, y)


def test_seeded_episodes_repeat_bit_for_bit():
    acts = np.random.default_rng(1).uniform(-1, 1, (40, 3)).astype(np.float32)
    out = []
    for _ in range(2):
        env = gym.make(ENV_ID)
        o, _ = env.reset(seed=11)
        out.append(np.array([o] + [env.step(a)[0] for a in acts]))
    np.testing.assert_array_equal(out[0], out[1])
    other = gym.make(ENV_ID)
    assert not np.array_equal(other.reset(seed=12)[0], out[0][0])


def test_observation_is_the_target_relative_state_in_the_local_frame():
    """Its inverse gives the lander's offset from the site along the surface (the great-circle
    arc at its radius, split along the orbital frame's along- and cross-track axes), its
    altitude, its velocity (u, v, w of dynamics.moon3d_derived), the propellant and the time;
    the log scale resolves metres near the site. (The same quantities as the guidance frame's:
    tests/guidance/test_families.py.)"""
    env = gym.make(ENV_ID).unwrapped
    s = SC.scaling()
    params = SC.params()
    env.reset(seed=3)
    for _ in range(30):
        env.step(np.array([0.1, 0.05, 0.5], np.float32))
    near = _state_si(12.0, -2.0, offset_east_m=-3.0, v_east_m_s=0.5)
    tu = SC.target_position_m() / np.linalg.norm(SC.target_position_m())
    for y in (env.state_nd, np.concatenate([s.length_nd(near[:3]), s.velocity_nd(near[3:6]),
                                            [s.mass_nd(near[6])]])):
        t = 123.0
        obs = env.observation_from_state(y[None], np.array([t]))
        assert env.observation_space.contains(obs[0])
        q = env.observation_quantities(obs)
        assert list(q)[:6] == list(OBSERVATION_NAMES[:6])
        r = np.linalg.norm(y[:3]) * s.length_m
        up = y[:3] / np.linalg.norm(y[:3])
        f = np.array(dyn.orbital_frame(*y[:3], *params.plane_normal)).reshape(3, 3)
        horiz = tu - (up @ tu) * up
        psi = math.atan2(np.linalg.norm(horiz), up @ tu)  # (acos loses the metres)
        toward = horiz / np.linalg.norm(horiz)
        offset = -r * psi * np.array([toward @ f[1], toward @ f[2]])
        np.testing.assert_allclose([q["along_m"][0], q["cross_m"][0]], offset, rtol=2e-6,
                                   atol=1e-5)
        assert q["altitude_m"][0] == pytest.approx(r - SC.body.radius_m, rel=2e-6, abs=1e-5)
        d = dyn.moon3d_derived(y, params)
        vel = np.array([d["v_nd"], d["w_nd"], d["u_nd"]]) * s.velocity_m_s
        np.testing.assert_allclose([q["v_along_m_s"][0], q["v_cross_m_s"][0],
                                    q["v_up_m_s"][0]], vel, rtol=2e-6, atol=1e-6)
        prop = (y[6] * s.mass_kg - SC.vehicle.dry_mass_kg)
        assert q["propellant_kg"][0] == pytest.approx(prop, rel=1e-6)
        assert q["time_s"][0] == pytest.approx(t, rel=1e-6)
    assert q["altitude_m"][0] == pytest.approx(12.0, abs=1e-4)
    assert math.hypot(q["along_m"][0], q["cross_m"][0]) == pytest.approx(3.0, abs=1e-4)
    assert obs[0, 2] == pytest.approx(math.log1p(1.2), rel=1e-5)


def test_imu_channels_are_appended_through_the_base_mechanism():
    env = gym.make(ENV_ID, sensors=("imu",)).unwrapped
    assert env.observation_space.shape == (11,)
    env.reset(seed=4)
    obs, *_ = env.step(np.array([1.0, 0.0, 1.0], np.float32))  # full thrust straight up
    imu = env.sensor_readings()["imu"]
    ref = SC.vehicle.thrust_n / SC.vehicle.mass_kg
    np.testing.assert_allclose(obs[8:], imu / ref, rtol=1e-6)
    np.testing.assert_allclose(env.observation_quantities(obs[None])["imu_m_s2"][0], imu,
                               rtol=1e-6)
    m = env.state_nd[6] * SC.scaling().mass_kg
    assert imu[2] == pytest.approx(SC.vehicle.thrust_n / m, rel=2e-3)  # the specific force


def test_uncertainty_infos_carry_the_truth_and_the_navigation_solution():
    """Under ``standard`` the observation encodes the navigated state, and every info carries
    it with the truth; the single and the vector env agree."""
    env = gym.make(ENV_ID, uncertainty="standard").unwrapped
    obs, info = env.reset(seed=5)
    for _ in range(3):
        obs, _, _, _, info = env.step(np.array([0.1, 0.0, 0.5], np.float32))
    np.testing.assert_array_equal(info["state_nd"], env.state_nd)
    np.testing.assert_array_equal(info["navigation_state_nd"], env.navigation_state_nd)
    assert not np.array_equal(info["state_nd"], info["navigation_state_nd"])
    np.testing.assert_array_equal(
        obs, env.observation_from_state(info["navigation_state_nd"][None],
                                        np.array([info["time_s"]]))[0])
    venv = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point",
                        uncertainty="standard")
    vobs, _ = venv.reset(seed=5)
    for _ in range(3):
        vobs, _, _, _, vinfo = venv.step(np.tile([0.1, 0.0, 0.5], (2, 1)).astype(np.float32))
    np.testing.assert_array_equal(vobs[0], obs)
    np.testing.assert_array_equal(vinfo["navigation_state_nd"][0], info["navigation_state_nd"])


def test_touchdown_is_located_inside_the_step_against_dop853():
    """A lander 30 m above the site, sinking at 6 m/s and drifting 1 m/s east at the minimum
    throttle, touches down 4.6 s into an 8 s step: the step's touchdown speed, components and
    time are DOP853's (event on the radius) within 1 mm/s and 1 ms."""
    env = gym.make(ENV_ID, dt_s=8.0, substeps=16).unwrapped
    s = SC.scaling()
    env.reset(options={"state_si": _state_si(30.0, -6.0, v_east_m_s=1.0)})
    y0 = env.state_nd
    u = env.task.controls_from_actions(VERTICAL_MIN[None])[0]
    _, r, term, trunc, info = env.step(VERTICAL_MIN)
    assert term and not trunc and 0.5 < info["time_s"] < 7.5

    def ground(t, y):
        return np.linalg.norm(y[:3]) - env.task.r_stop_nd
    ground.terminal, ground.direction = True, -1
    ref = _reference(y0, u, (0.0, s.time_nd(8.0)), events=[ground])
    y_td = ref.y_events[0][0]
    t_td = ref.t_events[0][0] * s.time_s
    v = y_td[3:6] * s.velocity_m_s
    up = y_td[:3] / np.linalg.norm(y_td[:3])
    assert info["touchdown_speed_m_s"] == pytest.approx(np.linalg.norm(v), abs=1e-3)
    assert info["touchdown_vertical_speed_m_s"] == pytest.approx(-v @ up, abs=1e-3)
    assert info["touchdown_horizontal_speed_m_s"] == pytest.approx(
        np.linalg.norm(v - (v @ up) * up), abs=1e-3)
    assert info["time_s"] == pytest.approx(t_td, abs=1e-3)
    assert info["altitude_m"] == pytest.approx(0.0, abs=1e-6)
    # the crash verdict: 6+ m/s down is beyond the gear's 3 m/s
    assert not info["is_success"] and info["touchdown_vertical_speed_m_s"] > 3.0


def test_no_engine_cut_off_at_a_speed_minimum():
    """Rising at 1 m/s 100 m above the site at the minimum throttle (pointing up), the speed
    passes through zero inside the step. v3 keeps burning through it (the throttle is the
    law's): the step is the integrator's without events, mass flow included. v2's engine cuts
    off at such a minimum (its cut-off ends the burn and the episode)."""
    env = gym.make(ENV_ID, dt_s=4.0).unwrapped
    s = SC.scaling()
    env.reset(options={"state_si": _state_si(100.0, 1.0)})
    y0 = env.state_nd
    u = env.task.controls_from_actions(VERTICAL_MIN[None])[0]
    _, _, term, trunc, info = env.step(VERTICAL_MIN)
    assert not term and not trunc
    mdot = SC.vehicle.mass_flow_kg_s * SC.throttle_min
    assert info["fuel_used_kg"] == pytest.approx(4.0 * mdot, rel=1e-9)
    h = s.time_nd(4.0) / 4
    pred = integ.integrate(integ.MOON3D, y0[None], t0_nd=0.0, dt_nd=h, n_steps=4,
                           control=integ.PiecewisePolynomial.constant(u[None], 0.0, 4 * h),
                           params=SC.params(), dry_mass_nd=0.1)
    assert pred.status[0] == integ.STATUS_COMPLETED
    np.testing.assert_allclose(env.state_nd, pred.y_end[0], rtol=0, atol=1e-12)
    # the same integration with the cut-off event armed stops at the speed minimum
    cut = integ.integrate(integ.MOON3D, y0[None], t0_nd=0.0, dt_nd=h, n_steps=4,
                          control=integ.PiecewisePolynomial.constant(u[None], 0.0, 4 * h),
                          params=SC.params(), dry_mass_nd=0.1, events=(integ.SpeedMinimum(),))
    assert cut.status[0] == integ.STATUS_SPEED_MIN
    # v2, the same situation above its gate: cut-off, then the fall ends the episode
    v2 = gym.make("LunarPinpointLanding-v2", dt_s=4.0, throttle_channel=True).unwrapped
    gate = get_scenario("peng2012").target.altitude_m
    v2.reset(options={"state_si": _state_si(gate + 100.0, 1.0)})
    *_, term2, _, info2 = v2.step(np.array([1.0, 0.0, -1.0], np.float32))
    assert term2 and info2["time_s"] > 4.0  # the fall to the gate, in the same step


def test_propellant_exhaustion_then_the_fall_in_the_same_step():
    """50 g of propellant 500 m above the site at full throttle: the burn ends 0.1 s into the
    step, the lander falls the rest of the way within the same step, and touches down at the
    speed of DOP853's burn-then-fall; a crash that loses nothing more (the tank is empty)."""
    env = gym.make(ENV_ID).unwrapped
    s = SC.scaling()
    dry = SC.vehicle.dry_mass_kg
    env.reset(options={"state_si": _state_si(500.0, 0.0, mass_kg=dry + 0.05)})
    y0 = env.state_nd
    full_up = np.array([1.0, 0.0, 1.0], np.float32)
    u = env.task.controls_from_actions(full_up[None])[0]
    _, r, term, trunc, info = env.step(full_up)
    assert term and not trunc and not info["is_success"]
    assert info["fuel_used_kg"] == pytest.approx(0.05, abs=1e-9)
    t_burn = s.time_nd(0.05 / SC.vehicle.mass_flow_kg_s)
    burn = _reference(y0, u, (0.0, t_burn))
    y1 = burn.y[:, -1]

    def ground(t, y):
        return np.linalg.norm(y[:3]) - env.task.r_stop_nd
    ground.terminal, ground.direction = True, -1
    fall = _reference(y1, np.array([0.0, 0.0, 0.0]), (t_burn, s.time_nd(200.0)),
                      events=[ground])
    v_td = np.linalg.norm(fall.y_events[0][0][3:6]) * s.velocity_m_s
    assert info["touchdown_speed_m_s"] == pytest.approx(v_td, abs=1e-3)
    assert info["time_s"] == pytest.approx(fall.t_events[0][0] * s.time_s, abs=1e-3)
    assert 30.0 < v_td < 50.0  # about sqrt(2 g h)
    expect = -0.05 / 300.0 - math.log1p(info["touchdown_vertical_speed_m_s"]) \
        - math.log1p(info["touchdown_horizontal_speed_m_s"]) \
        - math.log1p(info["miss_distance_m"] / 100.0)
    assert r == pytest.approx(expect, rel=1e-9)  # the tank is empty: no further charge


@pytest.mark.parametrize("v_up, v_east, offset, success", [
    (-1.0, 0.5, 0.0, True),       # within every limit
    (-3.6, 0.0, 0.0, False),      # too fast down (> 3 m/s)
    (-1.0, 1.6, 0.0, False),      # too fast sideways (> 1.2 m/s)
    (-1.0, 0.0, 130.0, False),    # off target (> 100 m)
    (-1.0, 0.0, 60.0, True),      # on target
], ids=["soft", "sink", "drift", "off", "near"])
def test_success_needs_every_limit(v_up, v_east, offset, success):
    env = gym.make(ENV_ID, dt_s=2.0).unwrapped
    env.reset(options={"state_si": _state_si(0.5, v_up, offset_east_m=offset,
                                             v_east_m_s=v_east)})
    _, r, term, _, info = env.step(VERTICAL_MIN)
    assert term and info["is_success"] is success
    assert (info["touchdown_vertical_speed_m_s"] <= 3.0
            and info["touchdown_horizontal_speed_m_s"] <= 1.2
            and info["miss_distance_m"] <= 100.0) is success
    # the terminal term of info's quantities, and a failure's propellant charge
    prop = SC.scaling().mass_kg * env.state_nd[6] - SC.vehicle.dry_mass_kg
    expect = -info["fuel_used_kg"] / 300.0 - math.log1p(info["touchdown_vertical_speed_m_s"]) \
        - math.log1p(info["touchdown_horizontal_speed_m_s"]) \
        - math.log1p(info["miss_distance_m"] / 100.0) - (0.0 if success else prop / 300.0)
    assert r == pytest.approx(expect, rel=1e-9)
    # the limits are the env's arguments
    loose = gym.make(ENV_ID, dt_s=2.0, success_vertical_speed_m_s=5.0,
                     success_horizontal_speed_m_s=2.0, success_miss_m=200.0).unwrapped
    loose.reset(options={"state_si": _state_si(0.5, v_up, offset_east_m=offset,
                                               v_east_m_s=v_east)})
    assert loose.step(VERTICAL_MIN)[4]["is_success"]


@pytest.mark.parametrize("name", ["success_miss_m", "success_vertical_speed_m_s",
                                  "success_horizontal_speed_m_s"])
@pytest.mark.parametrize("value", [0.0, -1.0, math.nan, math.inf])
def test_bad_limits_are_refused_by_name(name, value):
    with pytest.raises(ValueError, match=name):
        gym.make(ENV_ID, **{name: value})


def test_other_bad_arguments_are_refused():
    with pytest.raises(ValueError, match="throttle_channel"):
        gym.make(ENV_ID, throttle_channel=False)
    with pytest.raises(ValueError, match="not a touchdown scenario"):
        gym.make(ENV_ID, scenario="peng2012")
    with pytest.raises(TypeError):
        gym.make(ENV_ID, cutoff_speed_m_s=20.0)  # v3's engine has no cut-off
    import dataclasses

    for bad in (0.0, 1.0, -0.1, math.nan):
        with pytest.raises(ValueError, match="throttle_min"):
            dataclasses.replace(SC, throttle_min=bad)


def _fly(policy, dt_s=1.0, seed=None):
    """Return and last info of one nominal-start episode; ``policy(env, k) -> action``."""
    env = gym.make(ENV_ID, dt_s=dt_s).unwrapped
    env.reset(seed=seed, options={"nominal": True})
    total, k = 0.0, 0
    while True:
        _, r, term, trunc, info = env.step(policy(env, k))
        total += r
        k += 1
        if term or trunc:
            return total, info


def _hover(env, k):
    """Thrust straight up, balancing gravity at the current mass (flies on at orbital speed
    until the propellant runs out)."""
    m = env.state_nd[6] * SC.scaling().mass_kg
    g = SC.body.mu_m3_s2 / np.linalg.norm(env.state_nd[:3] * SC.scaling().length_m) ** 2
    thr = min(m * g / SC.vehicle.thrust_n, 1.0)
    return np.array([1.0, 0.0, action_from_throttle(thr)], np.float32)


def _optimum_replay(opt):
    """The certified optimum open loop (its law averaged over each step), then the engine at
    its minimum throttle straight up once the plan has ended."""
    def policy(env, k):
        t = k * env.dt_s
        if t < opt.tf_s:
            u = opt.mean_controls(t, env.dt_s, SC)
        else:
            u = np.array([math.pi / 2, math.pi, SC.throttle_min])
        return env.task.actions_from_controls(u[None])[0]
    return policy


def _ranking(n_random):
    from optimizers.optimum.touchdown import solve_touchdown_case, touchdown_ocp

    opt = solve_touchdown_case(SC, touchdown_ocp(SC).x0_nd)
    assert opt.success
    best, info = _fly(_optimum_replay(opt))
    assert info["is_success"] and info["fuel_used_kg"] < opt.fuel_kg + 1.0
    others = {
        "hover until the propellant runs out": _fly(_hover)[0],
        "dive": _fly(lambda env, k: np.array([-1.0, 0.0, 1.0], np.float32))[0],
        "fly past (no braking)": _fly(lambda env, k: VERTICAL_MIN)[0],
    }
    rng = np.random.default_rng(0)
    for i in range(n_random):
        acts = rng.uniform(-1, 1, (1500, 3)).astype(np.float32)
        others[f"random {i}"] = _fly(lambda env, k, a=acts: a[k])[0]
    return best, others


def test_reward_ranks_the_optimum_first():
    best, others = _ranking(n_random=3)
    assert best > max(others.values()) + 1.0, (best, others)


@pytest.mark.slow
def test_reward_ranks_the_optimum_first_full():
    best, others = _ranking(n_random=50)
    assert best > max(others.values()) + 1.0, (best, sorted(others.items(), key=lambda kv: -kv[1]))
