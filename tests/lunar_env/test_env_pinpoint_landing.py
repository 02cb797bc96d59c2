"""LunarPinpointLanding-v1 (and v0): Gymnasium contract, step physics, terminal gate, miss distance
and the reward's ranking."""

import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from hypothesis import given, settings
from hypothesis import strategies as st

from lunar_env import dynamics as dyn
from lunar_env import integrators as integ
from lunar_env.envs.pinpoint_landing import (
    LunarPinpointLandingEnv,
    action_from_angles,
    angles_from_action,
)

ENV_ID = "LunarPinpointLanding-v1"
SUB = 2  # the envs' default substeps


def test_check_env_and_both_ids():
    env = gym.make(ENV_ID, render_mode="rgb_array")
    check_env(env.unwrapped, skip_render_check=False)
    assert isinstance(gym.make("lunar_env:" + ENV_ID).unwrapped, LunarPinpointLandingEnv)
    assert env.unwrapped.scenario.name == "peng2012"


def test_angle_mapping_hits_the_scenario_bounds():
    sc = gym.make(ENV_ID).unwrapped.scenario
    a, b = angles_from_action(np.array([[-1.0, -1.0], [1.0, 1.0], [0.0, 0.0], [9.0, -9.0]]))
    np.testing.assert_allclose(a[:2], sc.alpha_bounds_rad)
    np.testing.assert_allclose(b[:2], sc.beta_bounds_rad)
    assert b[2] == pytest.approx(np.radians(175.0))  # midpoint of [130°, 220°]
    assert (a[3], b[3]) == (a[1], b[0])  # clipped
    acts = np.random.default_rng(0).uniform(-1, 1, (20, 2))
    np.testing.assert_allclose(action_from_angles(*angles_from_action(acts)), acts)


def test_nan_action_raises_and_state_untouched():
    env = gym.make(ENV_ID).unwrapped
    env.reset(seed=2)
    env.step(np.zeros(2, np.float32))
    y = env.state_nd
    with pytest.raises(ValueError, match="NaN or inf"):
        env.step(np.array([0.0, np.nan], np.float32))
    np.testing.assert_array_equal(env.state_nd, y)


def test_determinism_and_options():
    acts = np.random.default_rng(1).uniform(-1, 1, (30, 2)).astype(np.float32)
    out = []
    for _ in range(2):
        env = gym.make(ENV_ID)
        o, _ = env.reset(seed=11)
        out.append(np.array([o] + [env.step(a)[0] for a in acts]))
    np.testing.assert_array_equal(out[0], out[1])
    env = gym.make(ENV_ID).unwrapped
    sc = env.scenario
    env.reset(options={"nominal": True})
    np.testing.assert_array_equal(env.state_nd, sc.state_nd())
    r, v = sc.initial_position_velocity_m()
    env.reset(options={"state_si": np.concatenate([r, v, [590.0]])})
    np.testing.assert_allclose(env.state_nd[:3] * sc.scaling().length_m, r)
    assert env.state_nd[6] * 600.0 == pytest.approx(590.0)


@settings(max_examples=12, deadline=None)
@given(st.lists(st.tuples(st.floats(-2, 2), st.floats(-2, 2)), min_size=1, max_size=30),
       st.integers(0, 2**31 - 1))
def test_random_action_sequences_stay_in_space(actions, seed):
    env = gym.make(ENV_ID, time_limit_s=20.0).unwrapped
    obs, _ = env.reset(seed=seed)
    assert env.observation_space.contains(obs)
    for a in actions:
        obs, r, term, trunc, _ = env.step(np.array(a, np.float32))
        assert env.observation_space.contains(obs) and np.isfinite(r)
        if term or trunc:
            break


def _state_above_target(sc, height_m, up_speed_m_s, offset_m=0.0):
    """Moon-fixed SI state ``height_m`` above the target gate, moving radially."""
    tgt = sc.target_position_m()
    up = tgt / np.linalg.norm(tgt)
    east = np.cross([0.0, 0.0, 1.0], up)
    east /= np.linalg.norm(east)
    pos = tgt + height_m * up + offset_m * east
    return np.concatenate([pos, up_speed_m_s * up, [450.0]])


def test_cut_off_free_fall_to_the_gate_and_miss_distance():
    env = gym.make(ENV_ID).unwrapped
    sc = env.scenario
    # 3 m above the gate, rising at 2 m/s, thrust pointing down: the speed reaches zero inside
    # the step (engine cut-off), then the lander falls freely to the gate
    env.reset(options={"state_si": _state_above_target(sc, 3.0, 2.0)})
    _, r, term, trunc, info = env.step(np.array([-1.0, 0.0], np.float32))
    assert term and not trunc
    assert info["is_success"]
    assert info["touchdown_speed_m_s"] < 5.0
    assert info["miss_distance_m"] < 20.0
    assert info["altitude_m"] == pytest.approx(sc.target.altitude_m, abs=1e-6)
    # the final reward is the fuel term plus the landing-quality term of info
    fuel_term = -info["fuel_used_kg"] / 300.0
    expect = fuel_term - np.log1p(info["touchdown_speed_m_s"]) - np.log1p(
        info["miss_distance_m"] / 100.0)
    assert r == pytest.approx(expect, rel=1e-9)
    # offset 2 km east: same landing, miss ≈ 2 km, not a success
    env.reset(options={"state_si": _state_above_target(sc, 3.0, 2.0, offset_m=2000.0)})
    *_, term, trunc, info = env.step(np.array([-1.0, 0.0], np.float32))
    assert term and not info["is_success"]
    assert info["miss_distance_m"] == pytest.approx(2000.0, abs=25.0)


def test_open_loop_replay_matches_one_integrator_call():
    env = gym.make(ENV_ID).unwrapped
    sc = env.scenario
    s = sc.scaling()
    n = 120
    t = np.arange(n) + 0.5
    acts = np.stack([np.clip(-0.8 + t / 100, -1, 1), 0.1 * np.sin(t / 20)], axis=1)
    alpha, beta = angles_from_action(acts)
    dt = s.time_nd(1.0)
    coefs = np.zeros((1, n, 3, 1))
    coefs[0, :, 0, 0], coefs[0, :, 1, 0], coefs[0, :, 2, 0] = alpha, beta, 1.0
    r_gate = s.length_nd(sc.body.radius_m + sc.target.altitude_m)
    pred = integ.integrate(integ.MOON3D, sc.state_nd()[None], t0_nd=0.0, dt_nd=dt / SUB,
                           n_steps=SUB * n,
                           control=integ.PiecewisePolynomial((np.arange(n + 1) * dt)[None],
                                                             coefs),
                           params=sc.params(), dry_mass_nd=0.5,
                           events=(integ.RadiusCrossing(r_gate), integ.SpeedMinimum()),
                           record=True)
    assert pred.status[0] == integ.STATUS_COMPLETED
    env.reset(options={"nominal": True})
    for k in range(n):
        env.step(acts[k])
        y = pred.states[0, SUB * (k + 1)]
        assert np.linalg.norm(env.state_nd[:3] - y[:3]) * s.length_m < 1.0
        assert np.linalg.norm(env.state_nd[3:6] - y[3:6]) * s.velocity_m_s < 0.1
    # the observation's velocity block is (u, v, w) of dynamics.moon3d_derived
    obs = env.observation_from_state(env.state_nd[None], np.array([env.t_s]))[0]
    d = dyn.moon3d_derived(env.state_nd, sc.params())
    v0 = 1713.8
    assert obs[5] == pytest.approx(d["v_nd"] * s.velocity_m_s / v0, rel=1e-5)
    assert obs[4] == pytest.approx(d["u_nd"] * s.velocity_m_s / (0.1 * v0), rel=1e-5, abs=1e-6)


def test_pickle_render_and_bad_scenario():
    env = gym.make(ENV_ID, render_mode="rgb_array").unwrapped
    env.reset(seed=0)
    env.step(np.zeros(2, np.float32))
    frame = env.render()
    assert frame.ndim == 3 and frame.dtype == np.uint8
    clone = pickle.loads(pickle.dumps(env))
    np.testing.assert_array_equal(clone.step(np.ones(2))[0], env.step(np.ones(2))[0])
    with pytest.raises(ValueError, match="not a pinpoint"):
        gym.make(ENV_ID, scenario="zhu2007")


@pytest.mark.slow
def test_optimal_pinpoint_landing_is_landable():
    """[001]'s optimum (GPM + direct shooting of :mod:`optimizers`) replayed open loop lands at
    the gate softly and on target with 0.25 s steps (its return ranks first:
    tests/agents/rl/test_reward_ranking.py)."""
    from lunar_env import get_scenario
    from optimizers.reproduce.peng2012 import get_solver, replay_in_env

    solver = get_solver(get_scenario("peng2012"))
    solver.build()
    nominal = solver.solve()
    fine = replay_in_env(nominal, solver.ocp, dt_s=0.25, substeps=2)
    assert fine["is_success"] and fine["touchdown_speed_m_s"] < 2.0
    assert fine["miss_distance_m"] < 5.0


def test_v1_charges_the_propellant_left_on_failure_and_v0_does_not():
    """Same flight under both ids; only the last reward of a failed episode differs, by the
    propellant left / capacity. The vector env follows the id's reward too."""
    acts = np.tile(np.array([-1.0, 0.111], np.float32), (400, 1))  # dive to the gate
    rewards, infos = {}, {}
    for env_id in ("LunarPinpointLanding-v0", ENV_ID):
        env = gym.make(env_id).unwrapped
        env.reset(seed=3)
        rs = []
        for a in acts:
            _, r, term, trunc, info = env.step(a)
            rs.append(r)
            if term or trunc:
                break
        rewards[env_id], infos[env_id] = np.array(rs), info
    r0, r1 = rewards["LunarPinpointLanding-v0"], rewards[ENV_ID]
    assert len(r0) == len(r1) and not infos[ENV_ID]["is_success"]
    np.testing.assert_array_equal(r0[:-1], r1[:-1])
    sc = gym.make(ENV_ID).unwrapped.scenario
    env = gym.make(ENV_ID).unwrapped
    env.reset(seed=3)
    m_start = env.state_nd[-1] * sc.scaling().mass_kg
    left = m_start - infos[ENV_ID]["fuel_used_kg"] - sc.vehicle.dry_mass_kg
    cap = sc.vehicle.mass_kg - sc.vehicle.dry_mass_kg
    assert r1[-1] - r0[-1] == pytest.approx(-left / cap, rel=1e-9)
    venv = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point")
    venv.reset(seed=3)
    total = np.zeros(2)
    live = np.ones(2, bool)
    for a in acts:
        _, r, term, trunc, _ = venv.step(np.tile(a, (2, 1)))
        total += np.where(live, r, 0.0)
        live &= ~(term | trunc)
        if not live.any():
            break
    assert total[0] == pytest.approx(r1.sum(), rel=1e-12)


def test_v2_gate_counts_only_near_the_target():
    """v2: diving far from the target does not end at the 2 km gate sphere but at the surface;
    the altitude below the gate stays observable; entering the target zone under the gate ends
    the episode; the single and the vector env agree; every other step is v1's."""
    v2 = gym.make("LunarPinpointLanding-v2").unwrapped
    check_env(v2, skip_render_check=True)
    task = v2.task
    assert task.gate_range_m == 10_000.0 and v2.observation_space.low[0] < 0.0
    dive = np.tile(np.array([-1.0, 0.111], np.float32), (600, 1))
    ends = {}
    for env_id in (ENV_ID, "LunarPinpointLanding-v2"):
        env = gym.make(env_id).unwrapped
        env.reset(seed=3)
        alts, obs0 = [], []
        for a in dive:
            obs, _, term, trunc, info = env.step(a)
            alts.append(info["altitude_m"])
            obs0.append(obs[0])
            if term or trunc:
                break
        ends[env_id] = (info, np.array(alts), np.array(obs0))
    i1, a1, _ = ends[ENV_ID]
    i2, a2, o2 = ends["LunarPinpointLanding-v2"]
    gate_alt = v2.scenario.target.altitude_m
    # v1 ends at the gate sphere (2 km), hundreds of km short; v2 flies on below 2 km to the
    # surface (altitude 0), and its observation shows the negative altitude above the gate
    assert abs(a1[-1] - gate_alt) < 1.0 and i1["miss_distance_m"] > 1e5
    assert abs(a2[-1]) < 1.0 and a2[-1] < gate_alt - 1000.0 and len(a2) > len(a1)
    assert o2[-2] < 0.0 and not i2["is_success"]
    # the same flight agrees until v1 stops
    np.testing.assert_allclose(a2[:len(a1) - 1], a1[:-1], rtol=0, atol=1e-6)
    # the zone: within 10 km of the target (great circle at the gate radius)
    r_hat = task.target_nd / np.linalg.norm(task.target_nd)
    below = np.concatenate([task.target_nd * (1.0 - 1e-6), np.zeros(3), [v2.state_nd[-1]]])
    above = np.concatenate([task.target_nd * (1.0 + 1e-6), np.zeros(3), [v2.state_nd[-1]]])
    assert task.below_gate_in_zone(below[None])[0] and not task.below_gate_in_zone(above[None])[0]
    side = np.cross(r_hat, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    for d_m, inside in ((9_000.0, True), (11_000.0, False)):
        ang = d_m / (task.r_stop_nd * task.length_ref_m)
        far = below.copy()
        far[0:3] = np.linalg.norm(below[0:3]) * (np.cos(ang) * r_hat + np.sin(ang) * side)
        assert task.in_gate_zone(far[None])[0] == inside
        assert task.below_gate_in_zone(far[None])[0] == inside
        assert task.stop_radius(far[None])[0] == (task.r_stop_nd if inside
                                                   else task.surface_radius_nd)
    # v0/v1: the gate sphere everywhere
    t1 = gym.make(ENV_ID).unwrapped.task
    assert t1.stop_radius(below[None])[0] == t1.r_stop_nd
    assert not t1.below_gate_in_zone(below[None])[0]
