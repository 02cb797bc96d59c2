"""The uncertainty model: validation, common random numbers, navigated observations, and each
plant error against physics."""

from __future__ import annotations

import dataclasses
import math
import re

import gymnasium as gym
import numpy as np
import pytest

import lunar_env  # noqa: F401
from lunar_env import uncertainty as unc
from lunar_env.integrators import integrate_reference
from lunar_env.uncertainty import SIGMA_LIMITS, EpisodeErrors, UncertaintyModel, get_uncertainty
from lunar_env.uncertainty.navigation import TERMINAL_SALT

IDS = ("LunarSoftLanding-v0", "LunarPinpointLanding-v2")


# -- validation ----------------------------------------------------------------------------------

@pytest.mark.parametrize("bad, field", [
    ({"thrust_scale": -0.01}, "thrust_scale"),
    ({"isp_scale": float("nan")}, "isp_scale"),
    ({"mass_kg": float("inf")}, "mass_kg"),
    ({"entry_position_m": (1.0, -2.0, 3.0)}, "entry_position_m[1]"),
    ({"nav_velocity_noise_m_s": (1.0, 2.0)}, "nav_velocity_noise_m_s"),
    ({"sensor_position_fraction": (0.0, 0.6, 0.0)}, "sensor_position_fraction[1]"),
    ({"sensor_altitude_m": -1.0}, "sensor_altitude_m"),
    ({"sensor_blend_fraction": 0.0}, "sensor_blend_fraction"),
    ({"imu_bias_m_s2": 2.0}, "imu_bias_m_s2"),
    ({"imu_vrw_m_s_sqrt_s": -1e-3}, "imu_vrw_m_s_sqrt_s"),
    ({"thrust_scale": 0.3}, "thrust_scale"),
    ({"misalignment_rad": "0.1"}, "misalignment_rad"),
])
def test_bad_settings_are_refused_with_the_field_named(bad, field):
    with pytest.raises(ValueError, match=field.replace("[", r"\[").replace("]", r"\]")):
        UncertaintyModel(**bad)
    with pytest.raises(ValueError, match=field.split("[")[0]):
        gym.make("LunarSoftLanding-v0", uncertainty=bad)


def test_unknown_keys_and_names_are_refused():
    with pytest.raises(ValueError, match="'thrust'"):
        UncertaintyModel.from_dict({"thrust": 0.02})
    with pytest.raises(ValueError, match="unknown uncertainty set 'big'"):
        gym.make("LunarSoftLanding-v0", uncertainty="big")
    with pytest.raises(TypeError, match="uncertainty = 3"):
        gym.make("LunarSoftLanding-v0", uncertainty=3)
    env = gym.make("LunarSoftLanding-v0")
    with pytest.raises(ValueError, match="needs an env with an uncertainty model"):
        env.reset(options={"errors": {"thrust_scale": 0.98}})
    env = gym.make("LunarSoftLanding-v0", uncertainty="standard")
    with pytest.raises(ValueError, match="'thrust'"):
        env.reset(options={"errors": {"thrust": 0.98}})
    with pytest.raises(ValueError, match="must be > 0"):
        env.reset(options={"errors": {"isp_scale": 0.0}})


def test_named_sets_and_scaling():
    std = get_uncertainty("standard")
    assert get_uncertainty("none").is_null and not std.is_null
    stress = get_uncertainty("stress")
    assert stress.thrust_scale == pytest.approx(3 * std.thrust_scale)
    assert stress.nav_position_bias_m == pytest.approx(tuple(3 * v for v in
                                                             std.nav_position_bias_m))
    assert std.scaled(0.0).is_null
    d = UncertaintyModel.from_dict({"base": "standard", "scale": 2, "mass_kg": 1.0})
    assert d.mass_kg == 2.0 and d.thrust_scale == pytest.approx(0.04)
    # a model is frozen and rebuilt validated
    with pytest.raises(ValueError, match="thrust_scale"):
        std.replace(thrust_scale=-1.0)


# -- none: the env as it was ------------------------------------------------------------------

@pytest.mark.parametrize("env_id", IDS)
def test_none_is_the_env_without_the_model(env_id):
    """Quick twin of ``benchmarks/record_episodes.py compare`` (which checks every id and
    setting against a recording of the commit before the model)."""
    runs = []
    for kw in ({}, {"uncertainty": "none"}, {"uncertainty": get_uncertainty("standard").scaled(0)}):
        env = gym.make(env_id, **kw)
        obs, info = env.reset(seed=11)
        rng = np.random.default_rng(0)
        out = [obs]
        for _ in range(30):
            obs, r, term, trunc, info = env.step(rng.uniform(-1, 1, env.action_space.shape))
            out += [obs, np.array([r]), np.array([term, trunc])]
            assert "navigation_state_nd" not in info
        runs.append(np.concatenate([np.ravel(x).astype(np.float64) for x in out]))
    np.testing.assert_array_equal(runs[0], runs[1])
    np.testing.assert_array_equal(runs[0], runs[2])


# -- common random numbers -------------------------------------------------------------------

@pytest.mark.parametrize("env_id", IDS)
def test_case_k_errors_do_not_depend_on_the_batch(env_id):
    """Case k (sub-env k reset with seed + k) gets the same errors, start and navigation noise
    in vector envs of any size and in a single env reset with seed + k."""
    seed, steps = 100, 5
    act_rng = np.random.default_rng(1)
    actions = act_rng.uniform(-1, 1, (steps, 7, 3))
    results = {}
    for n in (3, 7):
        v = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                         uncertainty="standard")
        obs, _ = v.reset(seed=seed)
        nact = v.single_action_space.shape[0]
        errs = v.unwrapped.episode_errors
        traj = [obs]
        for s in range(steps):
            obs, *_ = v.step(actions[s, :n, :nact])
            traj.append(obs)
        results[n] = (errs, np.stack(traj, 1))
    e3, t3 = results[3]
    e7, t7 = results[7]
    for k, a in e3.as_dict().items():
        np.testing.assert_array_equal(a, getattr(e7, k)[:3], err_msg=k)
    np.testing.assert_array_equal(t3, t7[:3])
    env = gym.make(env_id, uncertainty="standard")
    for k in (0, 2):
        obs, _ = env.reset(seed=seed + k)
        single = [obs]
        for s in range(steps):
            obs, *_ = env.step(actions[s, k, :nact])
            single.append(obs)
        np.testing.assert_array_equal(np.stack(single), t3[k])
        np.testing.assert_array_equal(env.unwrapped.episode_errors.thrust_scale,
                                      e3.thrust_scale[k:k + 1])
    # the planned starts are those of the env without errors (a separate stream)
    plain = gym.make(env_id)
    plain.reset(seed=seed)
    env.reset(seed=seed)
    assert not np.array_equal(plain.unwrapped.state_nd, env.unwrapped.state_nd)


def test_every_scale_sees_the_same_standard_normals():
    std = get_uncertainty("standard")
    a = EpisodeErrors.draw(std, unc.error_stream(5))
    b = EpisodeErrors.draw(std.scaled(2.0), unc.error_stream(5))
    np.testing.assert_allclose(b.thrust_scale - 1, 2 * (a.thrust_scale - 1), rtol=1e-12)
    np.testing.assert_allclose(b.nav_position_bias_m, 2 * a.nav_position_bias_m, rtol=1e-12)
    np.testing.assert_array_equal(a.noise_key, b.noise_key)


def test_terminal_sensors_errors_are_their_own_below_acquisition():
    """Above the acquisition altitude the navigation error is the inertial solution's alone;
    below the hand-over band it is the terminal sensors' (a fraction of the altitude plus a
    floor, drawn from streams of their own: nothing of the inertial bias is carried across);
    in the band, a linear blend. The compiled kernel and the NumPy formula agree."""
    m = get_uncertainty("standard")
    ha = m.sensor_altitude_m
    h = np.array([15000.0, ha, ha - 1.0, 0.95 * ha, 0.9 * ha, 2000.0, 10.0, 0.0, -3.0])
    w = m.sensor_weight(h)
    np.testing.assert_allclose(w, [1.0, 1.0, 1.0 / (0.1 * ha) * (0.1 * ha - 1.0), 0.5, 0.0,
                                   0.0, 0.0, 0.0, 0.0], rtol=1e-12, atol=1e-15)
    errors = EpisodeErrors.draw(m, unc.error_stream(5))
    many = EpisodeErrors(**{f.name: np.repeat(getattr(errors, f.name), len(h), axis=0)
                            for f in dataclasses.fields(errors)})
    counters = np.zeros(len(h), dtype=np.int64)
    dpos, dvel = many.navigation_errors(m, counters, h)
    z = unc.navigation_noise(many.noise_key, counters)
    pre = many.nav_position_bias_m[:, 0] + z[:, 0] * m.nav_position_noise_m[0]
    zt = unc.navigation_noise(many.noise_key ^ TERMINAL_SALT, counters)
    term = (np.maximum(h, 0.0) * (many.sensor_position_fraction[:, 0]
                                  + zt[:, 0] * m.sensor_position_noise_fraction[0])
            + many.sensor_position_floor_m[:, 0])
    np.testing.assert_allclose(dpos[:, 0], w * pre + (1 - w) * term, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(dpos[:2, 0], pre[:2])  # above: the inertial error exactly
    # at the 2 km gate the altitude error is metres, not the inertial solution's 100 m
    assert abs(dpos[5, 0]) < 20.0 and abs(pre[5]) > abs(dpos[5, 0])
    # the terminal sensors' per-episode errors come from the episode's key, not the stream:
    # the inertial draws are those of a model without sensors
    bare = m.without("sensors")
    e_bare = EpisodeErrors.draw(bare, unc.error_stream(5))
    for f in ("entry_position_m", "nav_position_bias_m", "thrust_scale", "noise_key"):
        np.testing.assert_array_equal(getattr(e_bare, f), getattr(errors, f), err_msg=f)
    assert np.all(e_bare.sensor_position_fraction == 0) and np.all(e_bare.imu_scale == 1)


def test_groups_isolate_and_leave_out_each_error_source():
    std = get_uncertainty("standard")
    for group, names in unc.GROUPS.items():
        alone = get_uncertainty(group)
        assert alone == dataclasses.replace(std.only(group), name=group)
        for f in dataclasses.fields(std):
            if f.name in ("name", "sensor_altitude_m", "sensor_blend_fraction"):
                continue
            kept = getattr(alone, f.name) == getattr(std, f.name)
            assert kept == (f.name in names) or not any(np.ravel(getattr(std, f.name))), f.name
        left = UncertaintyModel.from_dict({"base": "standard", "without": group})
        assert left == std.without(group)
        assert all(not any(np.ravel(getattr(left, n))) for n in names)
    with pytest.raises(ValueError, match="unknown error group 'radar'"):
        std.only("radar")


def test_navigation_noise_is_a_pure_function_of_key_and_counter():
    keys = np.array([3, 99, 2**63 + 5], dtype=np.uint64)
    c = np.array([0, 7, 12])
    z = unc.navigation_noise(keys, c)
    np.testing.assert_array_equal(unc.navigation_noise(keys[1:2], c[1:2]), z[1:2])
    np.testing.assert_array_equal(unc.navigation_noise(keys, c, 4), z[:, :4])
    big = unc.navigation_noise(np.arange(40000, dtype=np.uint64), np.zeros(40000, np.int64))
    assert np.abs(big.mean(0)).max() < 0.03 and np.abs(big.std(0) - 1).max() < 0.03
    assert np.abs(np.corrcoef(big.T) - np.eye(6)).max() < 0.03


_MASK64 = (1 << 64) - 1


def _splitmix64(x: int) -> int:
    """splitmix64's finaliser in Python integers (the reference of the compiled hash)."""
    z = (x + 0x9E3779B97F4A7C15) & _MASK64
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK64
    return z ^ (z >> 31)


def _acklam_quantile(p: float) -> float:
    """Acklam's normal quantile in Python floats, term for term as the compiled one."""
    a = (-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
         1.383577518672690e+02, -3.066479806614716e+01, 2.506628277459239e+00)
    b = (-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
         6.680131188771972e+01, -1.328068155288572e+01)
    c = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
         -2.549732539343734e+00, 4.374664141464968e+00, 2.938163982698783e+00)
    d = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
         3.754408661907416e+00)
    if 0.02425 <= p <= 1.0 - 0.02425:
        q = p - 0.5
        r = q * q
        return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q \
            / (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0)
    q = math.sqrt(-2.0 * math.log(p if p < 0.5 else 1.0 - p))
    x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) \
        / ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0)
    return x if p < 0.5 else -x


def test_batched_noise_is_the_per_lander_definition_bit_for_bit():
    # The compiled noise runs in vectorised passes over the batch; each draw must still be the
    # per-lander definition (hash pairs, Acklam's quantile, truncation), so recorded episodes
    # and common random numbers do not move. Enough draws to hit both tails and the clip.
    rng = np.random.default_rng(8)
    keys = rng.integers(0, 2**64 - 1, 700, dtype=np.uint64, endpoint=True)
    counters = rng.integers(0, 3000, 700)
    got = unc.navigation_noise(keys, counters, 5)
    expect = np.empty_like(got)
    for i, (k, c) in enumerate(zip(keys, counters, strict=True)):
        base = _splitmix64(int(k) ^ _splitmix64(int(c)))
        for j in range(5):
            h = _splitmix64((base + j - j % 2 + 1) & _MASK64)
            half = h >> 32 if j % 2 == 0 else h & 0xFFFFFFFF
            p = (float(half) + 0.5) / 2.0 ** 32
            expect[i, j] = min(max(_acklam_quantile(p), -4.5), 4.5)
    np.testing.assert_array_equal(got, expect)
    assert (np.abs(got) > 1.98).any()  # draws from the tails were checked too


@pytest.mark.parametrize("env_id", IDS)
@pytest.mark.parametrize("name", ["standard", "stress"])
def test_fused_navigation_kernel_equals_the_public_functions(env_id, name):
    # the tasks' one-pass navigation kernel against LandingTask's composition of
    # navigation_errors, altitude_m and offset_states: the same arrays, bit for bit, at
    # altitudes above, in and below the terminal sensors' hand-over
    from lunar_env.envs.task import LandingTask
    venv = gym.make_vec(env_id, num_envs=64, vectorization_mode="vector_entry_point",
                        uncertainty=name)
    venv.reset(seed=2)
    task = venv.unwrapped.task
    b = venv.unwrapped._batch
    y = b.y.copy()
    h = np.linspace(0.0, 6000.0, 32) / task.length_ref_m  # every other lander down to 0 m
    if task.n_axes == 2:
        y[::2, 0] = task.r_stop_nd + h
    else:
        r = np.linalg.norm(y[::2, :3], axis=1)
        y[::2, :3] *= ((task.surface_radius_nd + h) / r)[:, None]
    counters = np.arange(64) * 37
    got = task.navigation_states(y, b.errors, counters, b._mass_belief)
    expect = LandingTask.navigation_states(task, y, b.errors, counters, b._mass_belief)
    assert (task.altitude_m(y) < 0.9 * get_uncertainty(name).sensor_altitude_m).any()
    np.testing.assert_array_equal(got, expect)


# -- the navigated observation -----------------------------------------------------------------

@pytest.mark.parametrize("env_id", IDS)
def test_observation_is_the_truth_plus_the_drawn_navigation_errors(env_id):
    env = gym.make(env_id, uncertainty="standard")
    core = env.unwrapped
    task = core.task
    m = task.uncertainty
    obs, info = env.reset(seed=4)
    e = core.episode_errors
    for decision in range(6):
        truth = info["state_nd"]
        np.testing.assert_array_equal(truth, core.state_nd)
        np.testing.assert_array_equal(info["navigation_state_nd"], core.navigation_state_nd)
        assert task.altitude_m(truth[None])[0] > m.sensor_altitude_m  # inertial errors only
        z = unc.navigation_noise(e.noise_key, np.array([decision]))
        dpos = (e.nav_position_bias_m + z[:, 0::2] * np.asarray(m.nav_position_noise_m))
        dvel = (e.nav_velocity_bias_m_s + z[:, 1::2] * np.asarray(m.nav_velocity_noise_m_s))
        if task.n_axes == 2:  # planar: no crossrange
            dpos[:, 2] = dvel[:, 2] = 0.0
        expect = task.offset_states(truth[None], dpos, dvel, -e.mass_error_kg)[0]
        np.testing.assert_allclose(core.navigation_state_nd, expect, rtol=0, atol=1e-15)
        np.testing.assert_array_equal(obs, core.observation_from_state(expect[None],
                                                                       [core.t_s])[0])
        # and no more: the altitude the flight computer sees is off by the up error exactly
        alt = task.altitude_m(np.stack([truth, expect]))
        # (to the curvature: a horizontal offset d raises the radius by d²/2r, < 0.1 m)
        assert alt[1] - alt[0] == pytest.approx(dpos[0, 0], abs=0.1)
        obs, _, term, trunc, info = env.step(np.zeros(env.action_space.shape))
        if term or trunc:
            break


def test_entry_error_moves_the_true_start_along_the_local_axes():
    """Planar: +1 km up and +2 km downrange, +1 m/s downrange and +5 kg at the start."""
    env = gym.make("LunarSoftLanding-v0", uncertainty="standard")
    core = env.unwrapped
    y0 = core.task.scenario.state_nd(scaling=core.task.scaling)
    env.reset(seed=0, options={"state_nd": y0, "errors": {
        "entry_position_m": [1000.0, 2000.0, 50.0], "entry_velocity_m_s": [0.0, 1.0, 3.0],
        "mass_error_kg": 5.0}})
    t = core.task
    y = core.state_nd
    assert (y[0] - y0[0]) * t.length_ref_m == pytest.approx(1000.0, abs=1e-6)
    assert (y[2] - y0[2]) * y0[0] * t.length_ref_m == pytest.approx(2000.0, abs=1e-6)
    assert (y[0] * y[3] - y0[0] * y0[3]) * t.velocity_ref_m_s == pytest.approx(1.0, abs=1e-9)
    assert (y[4] - y0[4]) * t.mass_ref_kg == pytest.approx(5.0, abs=1e-9)
    # the flight computer believes the planned mass
    assert core.navigation_state_nd[4] * t.mass_ref_kg == pytest.approx(y0[4] * t.mass_ref_kg,
                                                                        abs=1e-9)


# -- the plant against physics ---------------------------------------------------------------

def _inertial_velocity(y):
    """Planar polar state -> inertial Cartesian velocity (normalised)."""
    r, vr, th, om = y[0], y[1], y[2], y[3]
    # θ from Oy: position (r sin θ, r cos θ)
    return np.array([vr * math.sin(th) + r * om * math.cos(th),
                     vr * math.cos(th) - r * om * math.sin(th)])


def test_weaker_engine_gives_the_rocket_equation_velocity_change():
    """A 2 % weaker engine with the same controls: the propellant burnt is 0.98 F/c · t, and
    the thrust's velocity change (flight minus the ballistic flight from the same start) is
    c·ln(m0/m1), the rocket equation (the thrust turns with the local horizontal by
    ω·t ≈ 0.5° over the burn, which changes |Δv| by ~1e-5)."""
    burn_s = 8
    model = UncertaintyModel(thrust_scale=0.01)
    out = {}
    for label, throttle in (("burn", 1.0), ("coast", -1.0)):
        env = gym.make("LunarSoftLanding-v0", uncertainty=model, throttle_channel=True)
        core = env.unwrapped
        y0 = core.task.scenario.state_nd(scaling=core.task.scaling)
        env.reset(seed=0, options={"state_nd": y0, "errors": {"thrust_scale": 0.98}})
        for _ in range(burn_s):
            env.step(np.array([0.0, throttle]))
        out[label] = core.state_nd
    t = core.task
    veh = t.scenario.vehicle
    c = veh.exhaust_velocity_m_s
    m0 = y0[4] * t.mass_ref_kg
    m1 = out["burn"][4] * t.mass_ref_kg
    assert m0 - m1 == pytest.approx(0.98 * veh.thrust_n / c * burn_s, rel=1e-12)
    dv = np.linalg.norm(_inertial_velocity(out["burn"]) - _inertial_velocity(out["coast"])) \
        * t.velocity_ref_m_s
    assert dv == pytest.approx(c * math.log(m0 / m1), rel=2e-4)


@pytest.mark.parametrize("env_id", IDS)
def test_plant_errors_match_an_independent_integration(env_id):
    """The env's truth under its drawn thrust, Isp and misalignment equals a DOP853
    integration of the model with those parameters and the biased angles."""
    env = gym.make(env_id, uncertainty="stress")
    core = env.unwrapped
    t = core.task
    env.reset(seed=21)
    e = core.episode_errors
    y0 = core.state_nd
    action = np.full(env.action_space.shape, 0.3)
    controls = t.controls_from_actions(action[None].astype(np.float64))[0].copy()
    steps = 10
    for _ in range(steps):
        env.step(action)
    controls[:-1] += e.misalignment_rad[0, :len(controls) - 1]
    params = t.params_array.copy()
    params[0] *= e.thrust_scale[0]
    params[1] *= e.isp_scale[0]
    from dataclasses import replace
    p = replace(t.params, thrust_nd=params[0], exhaust_velocity_nd=params[1])
    ref = integrate_reference(t.model, y0, (0.0, steps * t.dt_nd), lambda _t: controls, p)
    np.testing.assert_allclose(core.state_nd, ref.y[:, -1], rtol=1e-8, atol=1e-10)
    # the same run with the nominal plant ends elsewhere (the errors matter)
    nom = integrate_reference(t.model, y0, (0.0, steps * t.dt_nd),
                              lambda _t: t.controls_from_actions(action[None].astype(float))[0],
                              t.params)
    assert np.abs(core.state_nd - nom.y[:, -1]).max() > 1e-6


@pytest.mark.parametrize("env_id", IDS)
def test_check_env_under_the_standard_set(env_id):
    from gymnasium.utils.env_checker import check_env

    check_env(gym.make(env_id, uncertainty="standard").unwrapped, skip_render_check=True)
    v = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point",
                     uncertainty="stress")
    obs, info = v.reset(seed=0)
    assert v.observation_space.contains(obs)
    n_state = v.unwrapped.task.model.n_state
    assert info["navigation_state_nd"].shape == info["state_nd"].shape == (3, n_state)
    assert not np.array_equal(info["navigation_state_nd"], info["state_nd"])


@pytest.mark.parametrize("env_id", ["LunarSoftLanding-v0", "LunarPinpointLanding-v2"])
def test_error_scale_multiplies_every_error_of_the_episodes_that_start_after_it(env_id):
    """``set_error_scale(k)``: the next episodes' errors are k times those drawn at 1 (the
    same normals), and so is the navigation noise; the single and the vector env agree."""
    ref = gym.make_vec(env_id, 3, vectorization_mode="vector_entry_point",
                       uncertainty="standard")
    ref.reset(seed=11)
    e1 = ref.unwrapped.episode_errors
    nav1 = ref.unwrapped.navigation_state_nd - ref.unwrapped.state_nd
    for k in (0.0, 0.5):
        env = gym.make_vec(env_id, 3, vectorization_mode="vector_entry_point",
                           uncertainty="standard")
        core = env.unwrapped
        assert core.error_scale == 1.0
        core.set_error_scale(k)
        assert core.error_scale == k and core.task.uncertainty == get_uncertainty(
            "standard").scaled(k)
        env.reset(seed=11)
        ek = core.episode_errors
        for f in ("entry_position_m", "entry_velocity_m_s", "misalignment_rad",
                  "mass_error_kg", "nav_position_bias_m", "nav_velocity_bias_m_s"):
            np.testing.assert_allclose(getattr(ek, f), k * getattr(e1, f), rtol=1e-12,
                                       atol=1e-12, err_msg=f)
        for f in ("thrust_scale", "isp_scale"):
            np.testing.assert_allclose(getattr(ek, f) - 1.0, k * (getattr(e1, f) - 1.0),
                                       rtol=1e-12, atol=1e-15, err_msg=f)
        nav = core.navigation_state_nd - core.state_nd
        # the same planned starts: the navigation offsets shrink with the scale
        assert np.abs(nav).max() <= max(k, 1e-12) * 1.01 * np.abs(nav1).max()
        if k == 0.0:  # no error at all: the env without the model, bit for bit
            plain = gym.make_vec(env_id, 3, vectorization_mode="vector_entry_point")
            obs0, _ = plain.reset(seed=11)
            np.testing.assert_array_equal(core.observations(), obs0)
            plain.close()
        single = gym.make(env_id, uncertainty="standard").unwrapped
        single.set_error_scale(k)
        single.reset(seed=11)
        np.testing.assert_array_equal(single.state_nd, core.state_nd[0])
        np.testing.assert_array_equal(single.navigation_state_nd, core.navigation_state_nd[0])
        env.close()
    ref.close()


def test_error_scale_refuses_bad_values_and_an_env_without_errors():
    env = gym.make("LunarSoftLanding-v0", uncertainty="standard").unwrapped
    for bad in (-0.1, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="scale"):
            env.set_error_scale(bad)
    assert env.error_scale == 1.0
    plain = gym.make("LunarSoftLanding-v0").unwrapped
    with pytest.raises(ValueError, match="uncertainty model"):
        plain.set_error_scale(0.5)


# -- σ limits ----------------------------------------------------------------------------------

@pytest.mark.parametrize("field", sorted(SIGMA_LIMITS))
def test_each_sigma_limit_is_refused_at_construction_naming_the_field(field):
    """A σ at its limit is refused when the model is built (not at the first reset), the
    message naming the field, the value and the limit; just under the limit is a model."""
    limit = SIGMA_LIMITS[field]
    vector = isinstance(getattr(UncertaintyModel(), field), tuple)
    label = f"{field}[1]" if vector else field
    at = (0.0, limit, 0.0) if vector else limit
    with pytest.raises(ValueError, match=rf"{re.escape(label)} = .*< {limit:g}"):
        UncertaintyModel(**{field: at})
    with pytest.raises(ValueError, match=re.escape(label)):
        get_uncertainty("standard").replace(**{field: at})
    below = math.nextafter(limit, 0.0)
    UncertaintyModel(**{field: (below,) * 3 if vector else below})


def test_a_huge_mass_error_is_refused_when_the_env_is_made():
    with pytest.raises(ValueError, match=r"mass_kg = 1000000000.0 .*< 1000 kg"):
        gym.make("LunarSoftLanding-v0", uncertainty={"mass_kg": 1e9})
    with pytest.raises(ValueError, match="entry_position_m"):
        get_uncertainty("standard").scaled(1e3)


def test_ten_times_stress_is_within_the_limits_but_the_engine_scales():
    """The limits are generous: 10 × stress is a valid model in every field whose limit is
    not physical; the engine's scales stop at 0.2 (a positive thrust within 4.5σ)."""
    big = get_uncertainty("stress").replace(thrust_scale=0.0, isp_scale=0.0).scaled(10.0)
    assert big.mass_kg == pytest.approx(10 * get_uncertainty("stress").mass_kg)
    with pytest.raises(ValueError, match="thrust_scale"):
        get_uncertainty("stress").scaled(10.0)


# -- a change of error scale is a new batch ----------------------------------------------------

def _batch_arrays(b) -> dict[str, np.ndarray]:
    return {"y": b.y.copy(), "t_nd": b.t_nd.copy(), "m_start_nd": b.m_start_nd.copy(),
            "decision": b.decision.copy(),
            **{f"errors.{k}": v.copy() for k, v in b.errors.as_dict().items()}}


@pytest.mark.parametrize("env_id", IDS)
def test_error_scale_swaps_the_batch_and_leaves_the_old_one_untouched(env_id):
    env = gym.make_vec(env_id, 4, vectorization_mode="vector_entry_point",
                       uncertainty="standard")
    core = env.unwrapped
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    for _ in range(3):
        env.step(rng.uniform(-1, 1, env.action_space.shape))
    old = core._batch
    old_task, old_model = old.task, old.uncertainty
    before = _batch_arrays(old)
    nav_before = old.last_navigation.copy()
    core.set_error_scale(0.5)
    new = core._batch
    assert new is not old and new.task is not old_task and core.task is new.task
    assert old.task is old_task and old.uncertainty is old_model == get_uncertainty("standard")
    assert new.uncertainty == get_uncertainty("standard").scaled(0.5)
    # the landers carry over: states, clocks, decision counters, episode errors
    for k, v in _batch_arrays(new).items():
        np.testing.assert_array_equal(v, before[k], err_msg=k)
    np.testing.assert_array_equal(new.last_navigation, nav_before)
    env.step(rng.uniform(-1, 1, env.action_space.shape))
    assert not np.array_equal(new.y, before["y"])
    for k, v in _batch_arrays(old).items():
        np.testing.assert_array_equal(v, before[k], err_msg=k)
    # a batch's task and model cannot be assigned
    with pytest.raises(AttributeError):
        old.task = new.task
    with pytest.raises(AttributeError):
        old.uncertainty = new.uncertainty
    env.close()


def test_with_uncertainty_flies_on_as_the_old_batch_under_the_same_model():
    """A batch rebuilt under the same model steps exactly as the original would have."""
    env_a = gym.make_vec("LunarPinpointLanding-v2", 3, vectorization_mode="vector_entry_point",
                         uncertainty="stress")
    env_b = gym.make_vec("LunarPinpointLanding-v2", 3, vectorization_mode="vector_entry_point",
                         uncertainty="stress")
    env_a.reset(seed=5)
    env_b.reset(seed=5)
    rng = np.random.default_rng(1)
    actions = rng.uniform(-1, 1, (6, *env_a.action_space.shape))
    for a in actions[:3]:
        env_a.step(a)
        env_b.step(a)
    core_b = env_b.unwrapped
    core_b._batch = core_b._batch.with_uncertainty(core_b.task.uncertainty)
    for a in actions[3:]:
        oa = env_a.step(a)
        ob = env_b.step(a)
        np.testing.assert_array_equal(oa[0], ob[0])
        np.testing.assert_array_equal(oa[1], ob[1])
    np.testing.assert_array_equal(env_a.unwrapped.state_nd, core_b.state_nd)


def test_with_uncertainty_needs_a_batch_with_errors():
    from lunar_env.envs.core import LanderBatch
    from lunar_env.envs.soft_landing import PlanarTask

    with pytest.raises(ValueError, match="uncertainty"):
        LanderBatch(PlanarTask(), 2).with_uncertainty(get_uncertainty("standard"))
    task = PlanarTask(dt_s=2.0, uncertainty="standard")
    other = task.with_uncertainty("stress")
    assert other.dt_s == 2.0 and other.uncertainty == get_uncertainty("stress")
    assert task.uncertainty == get_uncertainty("standard")


# -- the plant, by parameter name ------------------------------------------------------------

@pytest.mark.parametrize("env_id", IDS)
def test_plant_scaling_by_name_equals_the_packed_indices(env_id):
    """``plant_params`` scales ``thrust_nd`` and ``exhaust_velocity_nd`` by name; packed, it is
    bit for bit the kernel row of the nominal array with entries 0 and 1 scaled, and the
    row the batch flies."""
    env = gym.make_vec(env_id, 5, vectorization_mode="vector_entry_point", uncertainty="stress")
    core = env.unwrapped
    env.reset(seed=9)
    task = core.task
    e = core.episode_errors
    for i in range(5):
        by_index = np.array(task.params_array)
        by_index[0] *= e.thrust_scale[i]
        by_index[1] *= e.isp_scale[i]
        by_name = e.plant_params(task.params, i)
        assert by_name.thrust_nd == task.params.thrust_nd * e.thrust_scale[i]
        np.testing.assert_array_equal(by_name.as_array(), by_index)
        np.testing.assert_array_equal(core._batch._p[i], by_index)
    assert (e.thrust_scale != 1.0).all() and (e.isp_scale != 1.0).all()
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_a_mass_error_that_can_reach_the_dry_mass_is_refused_when_the_env_is_made(env_id):
    """Within its own limit (< 1000 kg), a wet-mass σ whose truncated draw takes the lightest
    start to the dry mass is refused by the task when it is built, naming the largest σ
    allowed, not at the reset of the case that draws it; ``stress`` (18 kg) is far from it."""
    from lunar_env.uncertainty import TRUNCATION_SIGMA

    gym.make(env_id, uncertainty="stress").close()
    with pytest.raises(ValueError, match=r"mass_kg = 200 kg \(1σ\) is not allowed .*allowed: "
                                         r"mass_kg < \d"):
        gym.make(env_id, uncertainty={"base": "standard", "mass_kg": 200.0})
    env = gym.make(env_id)
    sc = env.unwrapped.scenario
    env.close()
    margin = sc.vehicle.mass_kg + min(0.0, sc.dispersion.mass_kg[0]) - sc.vehicle.dry_mass_kg
    gym.make(env_id, uncertainty={"mass_kg": 0.99 * margin / TRUNCATION_SIGMA}).close()
    with pytest.raises(ValueError, match="mass_kg"):
        gym.make(env_id, uncertainty={"mass_kg": 1.01 * margin / TRUNCATION_SIGMA})


def test_the_model_version_is_exported():
    assert isinstance(unc.MODEL_VERSION, int) and unc.MODEL_VERSION >= 1
    assert "MODEL_VERSION" in unc.__all__
