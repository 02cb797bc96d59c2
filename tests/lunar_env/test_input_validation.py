"""Bad inputs to the envs and scenarios are refused by name, and nothing changes: vector-env
actions and resets, scenario dispersions and final-time bounds, env
construction arguments, reset options, and a hypothesis fuzz of all of them
(``benchmarks/fuzz_inputs.py``; the long fuzz is marked ``slow``).
"""

from __future__ import annotations

import dataclasses
import importlib.util
import math
import sys

import gymnasium as gym
import numpy as np
import pytest
from proc_helpers import REPO

import lunar_env  # noqa: F401  (registers the ids)
from lunar_env.scenarios import (
    PinpointDispersion,
    PinpointTarget,
    PlanarDispersion,
    get_scenario,
)

SOFT, PIN = "LunarSoftLanding-v0", "LunarPinpointLanding-v0"


def _vec(env_id, n, **kw):
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kw)


# ------------------------------------------------------------------------------------ vector envs


def test_vector_env_refuses_transposed_actions():
    """(2, 4) actions for 4 pinpoint landers of 2 channels were reshaped and mixed up."""
    env = _vec(PIN, 4)
    env.reset(seed=0)
    y0 = env.state_nd.copy()
    with pytest.raises(ValueError, match=r"action has shape \(2, 4\); expected \(4, 2\)"):
        env.step(np.zeros((2, 4), dtype=np.float32))
    np.testing.assert_array_equal(env.state_nd, y0)
    # axes of length 1 are still accepted: (N,) for a one-channel env of N landers
    soft = _vec(SOFT, 3)
    soft.reset(seed=0)
    soft.step(np.zeros(3))


def test_vector_env_step_before_reset_is_a_clear_error():
    env = _vec(PIN, 2)
    with pytest.raises(RuntimeError, match="before reset"):
        env.step(np.zeros((2, 2)))
    with pytest.raises(RuntimeError, match="before reset"):
        env.step_landers(np.zeros((2, 2)))


@pytest.mark.parametrize("key", ["state_nd", "state_si"])
def test_vector_env_failed_reset_changes_nothing_and_names_the_row(key):
    env = _vec(SOFT, 4)
    env.reset(seed=3)
    env.step(np.zeros((4, 1)))
    y, t = env.state_nd.copy(), env.t_s.copy()
    sc = env.scenario
    rows = sc.sample_initial(np.random.default_rng(0), 4)
    rows[2, 4] = 1.0  # mass below the dry mass
    if key == "state_nd":
        rows = sc.si_to_nd(rows)
    with pytest.raises(ValueError, match="sub-env 2"):
        env.reset(options={key: rows})
    np.testing.assert_array_equal(env.state_nd, y)
    np.testing.assert_array_equal(env.t_s, t)
    # the generators did not advance either: the next episode is the one it would have been
    ref = _vec(SOFT, 4)
    ref.reset(seed=3)
    ref.step(np.zeros((4, 1)))
    np.testing.assert_array_equal(env.reset()[0], ref.reset()[0])


# -------------------------------------------------------------------------------------- scenarios


def test_pinpoint_scenario_refuses_impossible_dispersions():
    peng = get_scenario("peng2012")
    with pytest.raises(ValueError, match="dispersion.mass_kg"):
        dataclasses.replace(peng, dispersion=PinpointDispersion(mass_kg=(-350.0, 0.0)))
    with pytest.raises(ValueError, match="dispersion.altitude_m"):
        dataclasses.replace(peng, dispersion=PinpointDispersion(altitude_m=(-13500.0, 0.0)))
    with pytest.raises(ValueError, match="target.altitude_m"):
        dataclasses.replace(peng, target=PinpointTarget(20e3, peng.target.longitude_rad,
                                                        peng.target.latitude_rad))
    for bad in (float("nan"), -5.0, 0.0):
        with pytest.raises(ValueError, match="uw_bound_m_s"):
            dataclasses.replace(peng, uw_bound_m_s=bad)
    for bad in ((-5.0, -1.0), (-1.0, 100.0)):
        with pytest.raises(ValueError, match="tf_bounds_s"):
            dataclasses.replace(peng, tf_bounds_s=bad)
    assert dataclasses.replace(peng, uw_bound_m_s=math.inf).uw_bound_m_s == math.inf


def test_planar_scenario_refuses_negative_final_times():
    zhu = get_scenario("zhu2007")
    for bad in ((-5.0, -1.0), (-1.0, 700.0), (0.0, 0.0)):
        with pytest.raises(ValueError, match="tf_bounds_s"):
            dataclasses.replace(zhu, tf_bounds_s=bad)
    with pytest.raises(ValueError, match="dispersion.mass_kg"):
        dataclasses.replace(zhu, dispersion=PlanarDispersion(mass_kg=(-400.0, 0.0)))


def test_pinpoint_scenario_every_dispersed_start_resets():
    """A valid dispersion gives starts the env accepts (200 seeds)."""
    peng = get_scenario("peng2012")
    wide = dataclasses.replace(peng, dispersion=PinpointDispersion(
        altitude_m=(-12_000.0, 0.0), mass_kg=(-290.0, 0.0)))
    env = gym.make(PIN, scenario=wide)
    alt0, m0 = wide.initial.altitude_m, wide.initial.mass_kg
    dry = wide.vehicle.dry_mass_kg
    for seed in range(200):
        obs, info = env.reset(seed=seed)
        assert obs in env.observation_space and np.all(np.isfinite(obs)), seed
        # the start is the dispersed one: altitude and mass inside the ranges, above the dry mass
        assert alt0 - 12_000.0 - 1e-6 <= info["altitude_m"] <= alt0 + 1e-6, (seed, info)
        mass_kg = env.unwrapped.state_nd[6] * m0
        assert dry < m0 - 290.0 - 1e-6 <= mass_kg <= m0 + 1e-6, (seed, mass_kg)
        assert info["fuel_used_kg"] == 0.0 and not info["is_success"], (seed, info)


# ---------------------------------------------------------------- env arguments and reset options


@pytest.mark.parametrize("env_id", [SOFT, PIN])
@pytest.mark.parametrize("kwargs, field", [
    ({"throttle_channel": "no"}, "throttle_channel"),
    ({"throttle_channel": "False"}, "throttle_channel"),
    ({"substeps": 1.7}, "substeps"),
    ({"substeps": 0}, "substeps"),
    ({"substeps": True}, "substeps"),
    ({"max_fall_s": 0.0}, "max_fall_s"),
    ({"max_fall_s": -3.0}, "max_fall_s"),
    ({"time_limit_s": math.inf}, "time_limit_s"),
    ({"time_limit_s": math.nan}, "time_limit_s"),
    ({"max_fall_s": math.inf}, "max_fall_s"),
    ({"max_fall_s": math.nan}, "max_fall_s"),
    ({"substeps": math.inf}, "substeps"),
    ({"substeps": math.nan}, "substeps"),
    ({"dt_s": "1"}, "dt_s"),
    ({"dt_s": 5e-324}, "dt_s"),  # subnormal: divided the free fall's step count by zero
    ({"dt_s": 9e-4}, "dt_s"),
    ({"success_speed_m_s": None}, "success_speed_m_s"),
])
def test_env_arguments_are_refused_by_name(env_id, kwargs, field):
    with pytest.raises(ValueError, match=field):
        gym.make(env_id, **kwargs)
    with pytest.raises(ValueError, match=field):
        _vec(env_id, 2, **kwargs)


@pytest.mark.parametrize("env_id", [SOFT, PIN])
def test_integral_and_numpy_arguments_are_kept_exactly(env_id):
    env = gym.make(env_id, substeps=np.int64(3), dt_s=np.float32(0.5), throttle_channel=np.bool_(1),
                   max_fall_s=4.0).unwrapped
    assert env.task.substeps == 3 and env.dt_s == 0.5 and env.task.throttle_channel is True
    assert env.task.max_fall_s == 4.0
    assert gym.make(env_id, substeps=2.0).unwrapped.task.substeps == 2


@pytest.mark.parametrize("env_id", [SOFT, PIN])
def test_reset_options_unknown_keys_and_bad_state_lengths(env_id):
    env = gym.make(env_id)
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['state'\]"):
        env.reset(options={"state": [1.0]})
    n_state = env.unwrapped.task.model.n_state
    for key in ("state_si", "state_nd"):
        with pytest.raises(ValueError, match=key):
            env.reset(options={key: np.ones(n_state - 1)})
        with pytest.raises(ValueError, match=key):
            env.reset(options={key: np.full(n_state, np.nan)})
    venv = _vec(env_id, 2)
    with pytest.raises(ValueError, match="unknown key"):
        venv.reset(options={"nominl": True})
    with pytest.raises(ValueError, match="state_si"):
        venv.reset(options={"state_si": np.ones((3, n_state))})


# ------------------------------------------------------------------------------------------- fuzz


def _fuzz_module():
    spec = importlib.util.spec_from_file_location("fuzz_inputs",
                                                  REPO / "benchmarks" / "fuzz_inputs.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("fuzz_inputs", mod)
    spec.loader.exec_module(mod)
    return mod


def _fuzz(n_examples: int):
    from hypothesis import HealthCheck, given, settings

    fz = _fuzz_module()

    @settings(max_examples=n_examples, deadline=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(fz.cases())
    def one(case):
        tally = fz.Tally()
        fz.check_case(tally, *case)
        assert tally.silent == 0 and tally.unclear == 0, tally.examples

    one()


def test_fuzz_env_inputs_work_or_are_named():
    """Construction arguments, reset options and actions: each works or raises an error that
    names it (hypothesis; ``python benchmarks/fuzz_inputs.py`` prints the counts)."""
    _fuzz(40)


def test_fuzz_reads_cutoff_speed_none_as_no_cutoff():
    """``cutoff_speed_m_s=None`` is the documented "no cut-off" (stored as 0): the fuzzer
    counts it as kept, not as a crash of its own."""
    fz = _fuzz_module()
    tally = fz.Tally()
    fz.check_case(tally, "LunarSoftLanding-v0", None, {"cutoff_speed_m_s": None}, None, None,
                  ["valid"], 0)
    assert tally.silent == 0 and tally.unclear == 0, tally.examples


@pytest.mark.slow
def test_fuzz_env_inputs_slow():
    _fuzz(3000)


@pytest.mark.parametrize("env_id", [PIN, "LunarPinpointLanding-v2"])
def test_pinpoint_success_miss_none_is_refused_by_name(env_id):
    """A pinpoint landing always has a miss criterion: ``success_miss_m=None`` is refused, as
    before the task contract (the shared settings read None as "no miss criterion" for the
    planar task only)."""
    with pytest.raises(ValueError, match="success_miss_m"):
        gym.make(env_id, success_miss_m=None)


# ------------------------------------------------------------------ pinned starts and actions

#: a pinned start the soft-landing env accepted, after which its next step returned NaN
#: observations: mass ~10⁶ times the full tank, speed
#: ~10⁶ times the orbital speed
_NAN_START = [547846.7, -920853.1, -1836105.9, -1933889.5, 1253081.0]


def _nominal(env, key):
    """The nominal start as the option ``key`` takes it."""
    task = env.unwrapped.task
    y = env.unwrapped.scenario.state_nd(scaling=task.scaling)
    if key == "state_nd":
        return y
    if env.unwrapped.task.model.n_state == 5:
        return env.unwrapped.scenario.nd_to_si(y[None])[0]
    s = task.scaling
    return np.r_[y[0:3] * s.length_m, y[3:6] * s.velocity_m_s, y[6] * s.mass_kg]


def test_the_pinned_start_that_gave_nan_observations_is_refused():
    env = gym.make(SOFT)
    with pytest.raises(ValueError, match=r"options\['state_nd'\].*has mass 1253081 "
                                         r"\(normalised; .* allowed: above the dry mass 0\.5 "
                                         r"\(normalised; 300 kg\), at most the full tank"):
        env.reset(options={"state_nd": _NAN_START})
    obs, _ = env.reset(seed=0)  # the env is still usable
    assert np.isfinite(obs).all()


@pytest.mark.parametrize("env_id", [SOFT, PIN])
@pytest.mark.parametrize("key", ["state_nd", "state_si"])
@pytest.mark.parametrize("bad, match", [
    ("mass_high", r"has mass .*allowed: above the dry mass .* at most the full tank"),
    ("mass_dry", r"has mass .*allowed: above the dry mass"),
    ("below", r"not above the (surface|terminal gate); allowed: above"),
    ("escape", r"has speed .* m/s relative to the surface; allowed: below the escape speed"),
    ("nan", r"must be \d finite numbers|contains NaN or inf"),
])
def test_pinned_starts_are_checked_as_dispersed_ones(env_id, key, bad, match):
    """Finite, above the terminal radius, mass in (dry, full tank], bound to the body: a
    pinned start outside is refused with a ValueError naming the option, the value and the
    allowed range, in the single and the vector env, and nothing changes."""
    env = gym.make(env_id)
    env.reset(seed=1)
    task = env.unwrapped.task
    y = np.array(_nominal(env, key), dtype=np.float64)
    si = key == "state_si"
    mass_unit = task.mass_ref_kg if si else 1.0
    if bad == "mass_high":
        y[-1] = task.full_mass_nd() * mass_unit * 1.001
    elif bad == "mass_dry":
        y[-1] = task.dry_mass_nd * mass_unit
    elif bad == "below":
        if task.model.n_state == 5:
            y[0] = task.r_stop_nd * (task.length_ref_m if si else 1.0) * 0.999
        else:
            y[0:3] *= 0.999 * task.r_stop_nd / np.linalg.norm(y[0:3])
    elif bad == "escape":
        if task.model.n_state == 5:
            y[1] *= 0.0
            y[1] = 2.0 * (task.velocity_ref_m_s if si else 1.0)  # twice the orbital speed
        else:
            y[3:6] *= 2.0
    else:
        y[1] = np.nan
    before = env.unwrapped.state_nd.copy()
    with pytest.raises(ValueError, match=match) as info:
        env.reset(options={key: y})
    assert f"options['{key}']" in str(info.value) or "NaN" in str(info.value)
    np.testing.assert_array_equal(env.unwrapped.state_nd, before)
    venv = _vec(env_id, 2)
    with pytest.raises(ValueError, match=match):
        venv.reset(options={key: np.stack([_nominal(env, key), y])})
    # the nominal start itself passes the same checks, pinned either way
    obs, _ = env.reset(options={key: _nominal(env, key)})
    assert np.isfinite(obs).all()


@pytest.mark.parametrize("env_id", [SOFT, PIN])
def test_random_pinned_starts_never_give_nan(env_id):
    """Starts pinned anywhere near or far from the nominal one (the fuzz's ranges): each is
    refused by name, or the episode's observations, rewards and infos stay finite."""
    env = gym.make(env_id).unwrapped
    task = env.task
    rng = np.random.default_rng(7)
    nominal = env.scenario.state_nd(scaling=task.scaling)
    n_ok = 0
    for i in range(300):
        y = nominal * rng.uniform(0.5, 1.5, nominal.size) if i % 2 else \
            rng.uniform(-2e6, 2e6, nominal.size)
        if i % 3 == 0:
            y[-1] = rng.uniform(task.dry_mass_nd, task.full_mass_nd())  # a valid mass
        try:
            obs, info = env.reset(options={"state_nd": y})
        except ValueError as exc:
            assert "options['state_nd']" in str(exc) and "allowed" in str(exc), exc
            continue
        n_ok += 1
        for _ in range(5):
            obs, reward, term, trunc, info = env.step(env.action_space.sample())
            assert np.isfinite(obs).all() and np.isfinite(reward), (y, obs, info)
            assert all(np.isfinite(v) for v in info.values() if isinstance(v, float)), info
            if term or trunc:
                break
    assert n_ok > 20


@pytest.mark.parametrize("env_id", [SOFT, PIN])
@pytest.mark.parametrize("action, match", [
    (None, r"action is None; expected an array of real numbers of shape"),
    (0.3 + 0.1j, r"is complex; actions are real numbers"),
    (np.array([0.5 + 0j, 0.1 + 0j]), r"is complex; actions are real numbers"),
    ("0.5", r"holds text, not real numbers"),
    ([None, 0.2], r"contains None"),
    ([object(), 0.2], r"holds Python objects, not real numbers"),
])
def test_non_numeric_actions_are_refused_by_name(env_id, action, match):
    """Complex actions passed with a warning (their imaginary part dropped); None was reported
    as "contains NaN or inf". Both, and other non-numbers, are refused by name in the single
    and the vector env, and the state is left as it was."""
    import warnings

    env = gym.make(env_id).unwrapped
    env.reset(seed=0)
    y0 = env.state_nd.copy()
    venv = _vec(env_id, 1)
    venv.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", np.exceptions.ComplexWarning)  # none on the way
        with pytest.raises(ValueError, match=match):
            env.step(action)
        np.testing.assert_array_equal(env.state_nd, y0)
        with pytest.raises(ValueError, match=match):
            venv.step(action if action is None or np.ndim(action) == 0 else [action])
