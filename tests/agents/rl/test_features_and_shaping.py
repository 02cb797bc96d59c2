"""Observation features and potential-based shaping wrappers (agents side; the env is
unchanged)."""

import numpy as np
import pytest
import yaml

from agents import train as tr
from agents.common.vec_env import make_sb3_vec_env
from agents.features import (
    ObsFeatureWrapper,
    augment_observation,
    feature_constants,
    validate_features,
)
from agents.features.planar import PLANAR_FEATURE_WIDTHS
from agents.laws import SB3Law
from agents.rl.shaping import PotentialShaping, surface_speed_m_s
from guidance.flight import rollout

ENV_ID = "LunarSoftLanding-v0"
ALL = list(PLANAR_FEATURE_WIDTHS)


def _env():
    return make_sb3_vec_env(ENV_ID, 1, seed=0).native


def test_features_finite_on_the_whole_observation_box():
    env = _env()
    consts = feature_constants(env)
    rng = np.random.default_rng(0)
    lo = env.single_observation_space.low.astype(np.float64)
    hi = env.single_observation_space.high.astype(np.float64)
    obs = rng.uniform(lo, hi, size=(4000, 5))
    obs[:8] = lo  # corners: zero altitude, zero propellant, extreme speeds
    obs[8:16] = hi
    out = augment_observation(obs, consts, ALL)
    assert out.shape == (4000, 5 + sum(PLANAR_FEATURE_WIDTHS.values()))
    assert np.isfinite(out).all()
    np.testing.assert_array_equal(out[:, :5], obs.astype(np.float32))


def test_features_physics():
    """The stopping ratio is v²/(2 a_net h) and the fine velocities resolve 1 m/s."""
    env = _env()
    c = feature_constants(env)
    assert c["gravity_m_s2"] == pytest.approx(1.62, abs=0.01)  # the Moon's surface gravity
    h, vr, vt, prop = 1000.0, -30.0, 40.0, 100.0
    sc = env.scenario
    y = sc.si_to_nd(np.array([sc.surface_radius_m + h, vr, 0.0, vt, c["dry_mass_kg"] + prop]))
    obs = env.observation_from_state(y[None], 0.5 * env.time_limit_s)
    f = augment_observation(obs, c, ["log_altitude", "fine_velocity", "stopping_ratio"])[0]
    a_net = c["thrust_n"] / (c["dry_mass_kg"] + prop) - c["gravity_m_s2"]
    assert f[5] == pytest.approx(np.log10(1 + h) / 4.2, rel=1e-5)
    assert f[6] == pytest.approx(-np.log1p(30.0) / 7, rel=1e-5)
    assert f[7] == pytest.approx(np.log1p(40.0) / 7, rel=1e-5)
    assert f[8] == pytest.approx(np.log1p(50.0 ** 2 / (2 * a_net * h)), rel=1e-4)


def test_features_read_the_env_through_its_own_decoding():
    """The features decode observations with the env's inverse of its observation map, so they
    cannot drift from it: decode(observation(state)) gives back the state's SI quantities."""
    env = _env()
    sc = env.scenario
    rng = np.random.default_rng(3)
    n = 200
    si = np.stack([sc.surface_radius_m + rng.uniform(0, 14e3, n), rng.uniform(-150, 50, n),
                   rng.uniform(-0.1, 0.1, n), rng.uniform(-100, 1700, n),
                   rng.uniform(310, 600, n)], axis=1)
    t = rng.uniform(0, env.time_limit_s, n)
    q = env.observation_quantities(env.observation_from_state(sc.si_to_nd(si), t))
    np.testing.assert_allclose(q["altitude_m"], si[:, 0] - sc.surface_radius_m, rtol=1e-5,
                               atol=0.05)
    np.testing.assert_allclose(q["radial_velocity_m_s"], si[:, 1], rtol=1e-5, atol=1e-3)
    np.testing.assert_allclose(q["tangential_velocity_m_s"], si[:, 3], rtol=1e-5, atol=1e-2)
    np.testing.assert_allclose(q["propellant_kg"], si[:, 4] - feature_constants(env)[
        "dry_mass_kg"], rtol=1e-5, atol=1e-3)
    np.testing.assert_allclose(q["time_s"], t, rtol=1e-5, atol=1e-3)


@pytest.mark.parametrize("env_id, names, potential", [
    (ENV_ID, ALL, "surface_speed"),
    ("LunarPinpointLanding-v2", ["log_altitude", "fine_range", "stopping_ratio"],
     "gate_speed_and_range")])
def test_features_and_potentials_of_an_imu_env_are_those_of_its_own_columns(env_id, names,
                                                                            potential):
    """With ``sensors=("imu",)`` the features and the shaping potential read the env's own
    columns (the sensor channels pass through, before the features); a width that is neither
    the env's nor its own columns' is refused."""
    plain = make_sb3_vec_env(env_id, 4, seed=0)
    imu = make_sb3_vec_env(env_id, 4, seed=0, sensors=("imu",))
    o_plain, o_imu = plain.reset(), imu.reset()
    n = o_plain.shape[1]
    np.testing.assert_array_equal(o_imu[:, :n], o_plain)
    f_plain = augment_observation(o_plain, feature_constants(plain.native), names)
    f_imu = augment_observation(o_imu, feature_constants(imu.native), names)
    np.testing.assert_array_equal(f_imu[:, :o_imu.shape[1]], o_imu)
    np.testing.assert_allclose(f_imu[:, o_imu.shape[1]:], f_plain[:, n:], rtol=0, atol=1e-6)
    np.testing.assert_allclose(PotentialShaping(imu, 0.99, potential=potential).phi(o_imu),
                               PotentialShaping(plain, 0.99, potential=potential).phi(o_plain),
                               rtol=1e-12)
    with pytest.raises(ValueError, match="observations of width"):
        imu.native.observation_quantities(o_imu[:, :-1])


def test_validate_features_rejects_unknown_names():
    with pytest.raises(ValueError, match="unknown obs_features"):
        validate_features(["altitude_squared"])
    with pytest.raises(TypeError):
        validate_features("log_altitude")
    assert validate_features(None) == []


def test_wrapper_appends_features_also_to_terminal_observations():
    venv = ObsFeatureWrapper(make_sb3_vec_env(ENV_ID, 3, seed=1, dt_s=5.0), ALL)
    obs = venv.reset()
    assert obs.shape == (3, venv.observation_space.shape[0]) == (3, 12)
    for _ in range(300):
        obs, _, done, infos = venv.step(np.zeros((3, 1), dtype=np.float32))
        assert np.isfinite(obs).all()
        if done.any():
            t = infos[int(np.flatnonzero(done)[0])]["terminal_observation"]
            assert t.shape == (12,) and np.isfinite(t).all()
            break
    else:
        pytest.fail("no episode ended")


def test_shaping_telescopes_to_minus_initial_potential():
    """With γ = 1 the shaped return is the env's return minus Φ(s₀) (policy invariance)."""
    base = make_sb3_vec_env(ENV_ID, 2, seed=4, dt_s=5.0)
    raw = make_sb3_vec_env(ENV_ID, 2, seed=4, dt_s=5.0)
    sh = PotentialShaping(base, gamma=1.0, weight=1.0)
    o_sh, o_raw = sh.reset(), raw.reset()
    phi0 = sh.phi(o_sh)
    ret_sh, ret_raw = np.zeros(2), np.zeros(2)
    ended = np.zeros(2, dtype=bool)
    for _ in range(400):
        a = np.zeros((2, 1), dtype=np.float32)
        _, r1, d1, _ = sh.step(a)
        _, r2, d2, _ = raw.step(a)
        ret_sh += np.where(ended, 0.0, r1)
        ret_raw += np.where(ended, 0.0, r2)
        ended |= d1
        if ended.all():
            break
    assert ended.all()
    np.testing.assert_allclose(ret_sh, ret_raw - phi0, rtol=1e-4, atol=1e-3)
    # the potential is the engine-off surface speed: never below the current speed
    q = sh.consts["decode"](o_raw)
    speed = np.hypot(q["radial_velocity_m_s"], q["tangential_velocity_m_s"])
    assert (surface_speed_m_s(o_raw, sh.consts, sh.surface_radius_m) >= speed).all()


def test_feature_run_round_trips_through_save_load_evaluate(tmp_path):
    """obs_features and reward_shaping from YAML: recorded, reloaded, re-applied in evaluation."""
    run_dir = tmp_path / "run"
    rc = tr.main(["--quick", "--no-progress", "--verbose", "0", "--seed", "5", "--run-dir",
                  str(run_dir), "-n", "1024", "--no-eval", "--no-tensorboard", "--hyperparams",
                  "obs_features=[log_altitude, stopping_ratio, fuel_margin]",
                  "reward_shaping={potential: surface_speed, weight: 1.0}"])
    assert rc == 0
    hp = yaml.safe_load((run_dir / "config.yml").read_text())
    assert hp["obs_features"] == ["log_altitude", "stopping_ratio", "fuel_margin"]
    pol = SB3Law.from_path(run_dir)
    assert pol.obs_features == hp["obs_features"]
    assert pol.model.observation_space.shape == (8,)
    env_kwargs = hp.get("env_kwargs")
    a = rollout(ENV_ID, pol, 3, seed=7, env_kwargs=env_kwargs, trace_cases=1)
    b = rollout(ENV_ID, SB3Law.from_path(run_dir / "model.zip"), 3, seed=7,
                env_kwargs=env_kwargs, trace_cases=1)
    np.testing.assert_array_equal(a.fuel_used_kg, b.fuel_used_kg)
    assert np.isfinite(a.fuel_used_kg).all()
    # a policy without its features cannot be fed the raw observation
    with pytest.raises(ValueError):
        rollout(ENV_ID, SB3Law(pol.model, pol.vecnormalize), 1, seed=7, env_kwargs=env_kwargs)
