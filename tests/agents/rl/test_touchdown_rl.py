"""RL on ``LunarPinpointLanding-v3``: the touchdown family's observation features, shaping
potential and curriculum starts, ``train.py --quick`` end to end, and its RL Zoo entry."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from agents import train as tr
from agents.common.vec_env import make_sb3_vec_env
from agents.features import (
    FEATURE_FAMILIES,
    ObsFeatureWrapper,
    augment_observation,
    feature_constants,
    validate_features,
)
from agents.features.touchdown import TOUCHDOWN_FEATURE_WIDTHS
from agents.rl.shaping import (
    FAMILY_POTENTIALS,
    LOW_GATE_DEFAULTS,
    PotentialShaping,
    resolve_low_gate,
    resolve_margin_bonus,
    resolve_success_bonus,
)
from agents.rl.starts import START_FAMILIES
from lunar_env import get_scenario

ENV_ID = "LunarPinpointLanding-v3"
SC = get_scenario("peng2012_touchdown")
ALL = list(TOUCHDOWN_FEATURE_WIDTHS)


@pytest.fixture(scope="module")
def pool():
    """Curriculum starts along two certified optima (cached on disk), 21 points each."""
    return START_FAMILIES.get("pinpoint_touchdown").start_pool(SC, 2, 1, n_points=21,
                                                               progress=False)


def test_features_finite_on_the_observation_box_and_the_imu_channels():
    for sensors in ((), ("imu",)):
        env = make_sb3_vec_env(ENV_ID, 1, seed=0, sensors=sensors).native
        consts = feature_constants(env)
        lo = env.single_observation_space.low.astype(np.float64)
        hi = env.single_observation_space.high.astype(np.float64)
        obs = np.random.default_rng(0).uniform(lo, hi, size=(2000, len(lo)))
        obs[:4], obs[4:8] = lo, hi
        out = augment_observation(obs, consts, ALL)
        assert out.shape == (2000, len(lo) + sum(TOUCHDOWN_FEATURE_WIDTHS.values()))
        assert np.isfinite(out).all()
        np.testing.assert_array_equal(out[:, :len(lo)], obs.astype(np.float32))
        flo, fhi = FEATURE_FAMILIES.get("pinpoint_touchdown").bounds(ALL)
        assert np.all(out[:, len(lo):] >= np.array(flo) - 1e-6)
        assert np.all(out[:, len(lo):] <= np.array(fhi) + 1e-6)


def test_features_physics_and_the_nominal_profile(pool):
    """On the nominal optimum's own states the reference profile deviation is ~0; the stop
    point and stopping ratio follow their definitions."""
    env = make_sb3_vec_env(ENV_ID, 1, seed=0).native
    c = feature_constants(env)
    from optimizers.optimum.touchdown import touchdown_ocp

    x0 = touchdown_ocp(SC).x0_nd
    f = augment_observation(env.observation_from_state(x0[None], np.zeros(1)), c,
                            ["reference_profile"])[0, 8:]
    assert np.abs(f).max() < 1e-3  # the profile starts at the nominal start, at t = 0
    # a 500 kg lander 1000 m above the target, falling at 20 m/s, at rest horizontally
    target = touchdown_ocp(SC).target_position_nd
    s = SC.scaling()
    r = float(np.linalg.norm(target)) * s.length_m
    up = target / np.linalg.norm(target)
    y = np.concatenate([up * (r + 1000.0) / s.length_m, up * -20.0 / s.velocity_m_s,
                        [500.0 / s.mass_kg]])
    feats = augment_observation(env.observation_from_state(y[None], np.zeros(1)), c,
                                ["stopping_ratio", "stop_point"])[0, 8:]
    a = c["thrust_n"] / 500.0  # full thrust over the 500 kg lander
    assert feats[0] == pytest.approx(np.log1p(400.0 / (2 * a * 1000.0)), rel=1e-4)
    g = c["mu_m3_s2"] / (r + 1000.0) ** 2  # gravity where the lander is
    tau = 20.0 / (a - g)  # straight down: thrust minus gravity stops it
    stop_up = -1000.0 + 20.0 * tau / 2  # target − stop point, up
    assert feats[1] == pytest.approx(np.sign(stop_up) * np.log1p(abs(stop_up) / 10) / 8,
                                     rel=1e-4)
    assert feats[4] == pytest.approx(tau / 100.0, rel=1e-4)


def test_pinpoint_only_features_are_refused_with_the_allowed_names():
    env = make_sb3_vec_env(ENV_ID, 1, seed=0).native
    c = feature_constants(env)
    assert validate_features(["fine_range"]) == ["fine_range"]  # a name of some family
    with pytest.raises(ValueError, match="not defined for LunarPinpointLanding-v3"):
        augment_observation(np.zeros((1, 8)), c, ["fine_range"])
    wrapped = ObsFeatureWrapper(make_sb3_vec_env(ENV_ID, 2, seed=0), ALL)
    assert wrapped.observation_space.shape == (8 + 15,)


def test_shaping_potential_is_the_terminal_term_of_a_truncation(pool):
    """Φ(s) = −(the env's terminal term of an episode truncated at s), along an optimal
    flight; the success bonus is the term at the verdict's boundary."""
    states, times = pool
    venv = make_sb3_vec_env(ENV_ID, 1, seed=0)
    shaped = PotentialShaping(venv, gamma=0.998, potential="touchdown_speeds_and_range",
                              success_bonus="auto")
    task = venv.native.task
    y = states[0, [0, 10, 18, 20]]
    touched = np.zeros(len(y), dtype=bool)
    speed, miss = task.landing_metrics(y, touched)
    want = -task.terminal_penalty(y, speed, miss, touched)
    got = shaped.phi(venv.native.observation_from_state(y, times[0, [0, 10, 18, 20]]))
    np.testing.assert_allclose(got, want, rtol=2e-3, atol=2e-3)
    assert shaped.success_bonus == pytest.approx(np.log(4.0) + np.log(2.2) + np.log(2.0))
    assert resolve_success_bonus("auto", {"speed_m_s": 5.0, "miss_m": 500.0}) == \
        pytest.approx(np.log(6.0) + np.log(6.0))
    assert FAMILY_POTENTIALS["pinpoint_touchdown"] == ("touchdown_speeds_and_range",)
    with pytest.raises(ValueError, match="does not fit this env"):
        PotentialShaping(venv, gamma=0.99, potential="gate_speed_and_range")


def test_margin_bonus_pays_a_success_by_its_room_to_the_nearest_limit(monkeypatch):
    """P·min_k(1 − x_k/limit_k) over the verdict's limits (miss 100 m, 3 m/s down, 1.2 m/s
    across) is added to a success's reward, nothing to a failure; ``auto`` is the success
    bonus; the env's final info carries each bounded quantity."""
    venv = make_sb3_vec_env(ENV_ID, 3, seed=0)
    plain = PotentialShaping(venv, gamma=0.998, potential="touchdown_speeds_and_range",
                             success_bonus="auto")
    margin = PotentialShaping(venv, gamma=0.998, potential="touchdown_speeds_and_range",
                              success_bonus="auto", margin_bonus="auto")
    assert margin.margin_bonus == pytest.approx(plain.success_bonus)
    assert margin.config()["margin_bonus"] == margin.margin_bonus
    assert margin.limits == {"miss_distance_m": 100.0, "touchdown_vertical_speed_m_s": 3.0,
                             "touchdown_horizontal_speed_m_s": 1.2}
    obs = venv.reset()
    speeds = {"touchdown_speed_m_s": 2.0, "touchdown_vertical_speed_m_s": 0.6,
              "touchdown_horizontal_speed_m_s": 0.24}
    ends = (obs, np.zeros(3, dtype=np.float32), np.array([True, True, True]),
            [{"is_success": True, "miss_distance_m": 25.0, **speeds},   # miss nearest: 0.75
             {"is_success": True, "miss_distance_m": 10.0, **speeds,   # across nearest: 0.25
              "touchdown_horizontal_speed_m_s": 0.9},
             {"is_success": False, "miss_distance_m": 40.0, **speeds}])
    monkeypatch.setattr(venv, "step_wait", lambda: ends)
    got = {}
    for name, w in (("plain", plain), ("margin", margin)):
        w._phi = w.phi(obs)
        got[name] = w.step_wait()[1]
    np.testing.assert_allclose(got["margin"] - got["plain"],
                               [0.75 * margin.margin_bonus, 0.25 * margin.margin_bonus, 0.0],
                               rtol=1e-6)
    monkeypatch.undo()
    # the real env's final info has every quantity the verdict bounds
    for _ in range(2000):
        obs, _, done, infos = venv.step(np.tile([[0.0, 0.0, 0.0]], (3, 1)).astype(np.float32))
        if done.any():
            info = infos[int(np.flatnonzero(done)[0])]
            assert set(margin.limits) <= set(info)
            assert np.isfinite(margin.margins([info])).all()
            break
    else:
        raise AssertionError("no episode ended")


@pytest.mark.parametrize("value, match", [("best", "allowed: 'auto'"), (-1.0, ">= 0"),
                                          (float("nan"), ">= 0")])
def test_a_bad_margin_bonus_is_refused_by_name(value, match):
    with pytest.raises(ValueError, match=match):
        resolve_margin_bonus(value, {"miss_m": 100.0, "vertical_speed_m_s": 3.0,
                                     "horizontal_speed_m_s": 1.2})
    with pytest.raises(ValueError, match="needs a verdict with limits"):
        resolve_margin_bonus("auto", {"miss_m": float("inf")})
    assert resolve_margin_bonus(None, {}) == 0.0
    assert resolve_margin_bonus(2.0, {"speed_m_s": 5.0}) == 2.0


def test_start_pool_follows_the_optimal_landings(pool):
    states, times = pool
    assert states.shape == (2, 21, 7) and times.shape == (2, 21)
    assert np.all(np.diff(times, axis=1) > 0) and np.all(times[:, 0] == 0.0)
    from optimizers.optimum.touchdown import touchdown_ocp

    r_surface = float(np.linalg.norm(touchdown_ocp(SC).target_position_nd))
    h = np.linalg.norm(states[..., :3], axis=2) - r_surface
    assert np.all(h > 0) and h[:, -1].max() * SC.scaling().length_m < 60.0  # near touchdown
    fam = START_FAMILIES.get("pinpoint_touchdown")
    sig = fam.start_noise_nd(SC, {"position_m": 1000.0, "velocity_m_s": 2.0})
    late = states[:, -1]
    out = fam.perturb_starts(np.repeat(late, 200, axis=0), sig, np.random.default_rng(0))
    h0 = np.repeat(h[:, -1], 200)
    h1 = np.linalg.norm(out[:, :3], axis=1) - r_surface
    assert np.all(h1 >= 0.5 * h0 - 1e-12) and np.any(h1 > h0)


def test_quick_train_end_to_end(tmp_path, capsys):
    """``train.py --env LunarPinpointLanding-v3 --quick`` (a tiny step count): trains, selects,
    evaluates against the optimiser baseline and prints the table; no closed-loop expert (one
    re-planned landing outlasts the quick training)."""
    run_dir = tmp_path / "run"
    rc = tr.main(["--env", ENV_ID, "--quick", "--no-progress", "--torch-threads", "1",
                  "--seed", "3", "--run-dir", str(run_dir), "-n", "512", "--n-envs", "4",
                  "--eval-states", "2", "--no-tensorboard", "--hyperparams",
                  "seed_race=null", "n_steps=64", "batch_size=128",
                  "curriculum.n_trajectories=2", "select_checkpoint.states=1"])
    assert rc == 0
    args = yaml.safe_load((run_dir / "args.yml").read_text())
    hp = yaml.safe_load((run_dir / "config.yml").read_text())
    assert args["eval_expert_states"] == 0 and hp["obs_features"] == ALL
    assert (run_dir / "selection.yml").exists() and (run_dir / "model.zip").exists()
    out = capsys.readouterr().out
    assert "| PPO (run) | 2 |" in out and "| optimum, open loop | 2 |" in out
    assert "| random | 2 |" in out and "feedback" not in out


def test_zoo_entry_of_v3_carries_the_wrappers():
    from agents.rl.zoo import render_zoo_yaml, zoo_hyperparams, zoo_path

    for profile in (None, "quick"):
        entry = zoo_hyperparams("ppo", profile)[ENV_ID]
        wrapper = entry["vec_env_wrapper"][0]["agents.rl.zoo.lunar_vec_env"]
        assert wrapper["obs_features"] == ALL
        assert wrapper["reward_shaping"]["potential"] == "touchdown_speeds_and_range"
        assert wrapper["curriculum"]["pool_seed"] == 1
        assert "seed_race" not in entry and "select_checkpoint" not in entry
        assert zoo_path("ppo", profile).read_text() == render_zoo_yaml("ppo", profile)


def test_initial_action_sets_the_mean_action_of_a_new_ppo_policy():
    from stable_baselines3 import PPO

    from agents.hyperparams import RUN_KEYS
    from agents.rl.training import set_initial_action

    venv = make_sb3_vec_env(ENV_ID, 2, seed=0)
    model = PPO("MlpPolicy", venv, n_steps=8, batch_size=8, seed=0, device="cpu")
    obs = np.random.default_rng(0).uniform(-3, 3, size=(64, 8)).astype(np.float32)
    before, _ = model.predict(obs, deterministic=True)
    assert np.abs(before).max() < 0.2  # an untrained head: ~0 (a 60 % throttle)
    set_initial_action(model, [0.0, 0.0, 1.0])
    after, _ = model.predict(obs, deterministic=True)
    np.testing.assert_allclose(after, np.tile([0.0, 0.0, 1.0], (64, 1)), atol=0.2)
    assert after[:, 2].min() > 0.8
    for bad in ([0.0, 1.0], [0.0, 0.0, 1.5], [0.0, 0.0, float("nan")]):
        with pytest.raises(ValueError, match="one per action channel"):
            set_initial_action(model, bad)
    assert "initial_action" in RUN_KEYS


def test_quick_runs_fly_no_expert_where_it_outlasts_the_training():
    assert tr._quick_expert_states(ENV_ID, {"dt_s": 2.0}) == 0
    assert tr._quick_expert_states("LunarPinpointLanding-v2", None) == 2
    assert tr._quick_expert_states("LunarSoftLanding-v0", None) == 2


def test_low_gate_costs_horizontal_speed_above_an_envelope_per_metre_lost(pool):
    """The cost w·log(1 + e)·Δh, e the horizontal speed above max(0, h − h_gate)/τ and Δh the
    height lost: nothing on the envelope or when climbing, the same per metre however fast
    the lander falls; subtracted from every decision, an episode's last one at its final
    observation."""
    states, times = pool
    venv = make_sb3_vec_env(ENV_ID, 2, seed=0)
    gate = PotentialShaping(venv, gamma=0.998, potential="touchdown_speeds_and_range",
                            low_gate={"height_m": 20.0, "weight_per_m": 0.5})
    assert gate.low_gate == {"height_m": 20.0, "time_s": 1.0, "weight_per_m": 0.5}
    obs = venv.native.observation_from_state(states[0], times[0])
    q = gate.consts["decode"](obs)
    v_h = np.hypot(q["v_along_m_s"], q["v_cross_m_s"])
    excess = np.maximum(v_h - np.maximum(q["altitude_m"] - 20.0, 0.0), 0.0)
    cost = gate.low_gate_cost(obs, q["altitude_m"] + 2.0)
    np.testing.assert_allclose(cost, 0.5 * np.log1p(excess) * 2.0, rtol=1e-9)
    # the certified optimum brakes along-track into the ground: over the envelope near the end
    assert cost[-3:].max() > 0.0 and cost[0] == 0.0
    # on the envelope nothing; below the gate the horizontal speed's, per metre lost only
    on = dict({k: v[:2] for k, v in q.items()}, altitude_m=np.array([120.0, 10.0]),
              v_along_m_s=np.array([60.0, 3.0]), v_cross_m_s=np.array([80.0, 4.0]))
    gate.consts = dict(gate.consts, decode=lambda o: on)
    np.testing.assert_allclose(gate.low_gate_cost(obs[:2], np.array([130.0, 14.0])),
                               [0.0, 0.5 * np.log1p(5.0) * 4.0])
    np.testing.assert_allclose(gate.low_gate_cost(obs[:2], np.array([130.0, 6.0])), [0.0, 0.0])
    # each decision is charged, an episode's last one at its final observation (the decode
    # below reads it as the same state): two landers fall 4 m below the gate, the first lands
    below = dict(on, altitude_m=np.array([10.0, 10.0]), v_along_m_s=np.array([3.0, 3.0]),
                 v_cross_m_s=np.array([4.0, 4.0]))
    # (one row per observation decoded: the final observations are decoded on their own)
    gate.consts = dict(gate.consts, decode=lambda o: {k: v[:len(o)] for k, v in below.items()})
    plain = PotentialShaping(venv, gamma=0.998, potential="touchdown_speeds_and_range")
    plain.consts = gate.consts
    ends = (obs[:2], np.zeros(2, dtype=np.float32), np.array([True, False]),
            [{"is_success": False, "terminal_observation": obs[0]}, {"is_success": False}])
    venv.step_wait = lambda: ends
    got = {}
    for name, w in (("plain", plain), ("gate", gate)):
        w._phi = np.zeros(2)
        w._height_m = np.array([14.0, 14.0])
        got[name] = w.step_wait()[1]
    np.testing.assert_allclose(got["plain"] - got["gate"], [0.5 * np.log1p(5.0) * 4.0] * 2,
                               rtol=1e-6)
    np.testing.assert_array_equal(gate._height_m, [10.0, 10.0])


@pytest.mark.parametrize("value, match", [({"height_m": 0.0}, "finite number > 0"),
                                          ({"time_s": float("nan")}, "finite number > 0"),
                                          ({"gate_m": 15.0}, "unknown"),
                                          (15.0, "must be a mapping")])
def test_a_bad_low_gate_is_refused_by_name(value, match):
    with pytest.raises(ValueError, match=match):
        resolve_low_gate(value, "pinpoint_touchdown")
    with pytest.raises(ValueError, match="needs LunarPinpointLanding-v3"):
        resolve_low_gate({}, "pinpoint")
    assert resolve_low_gate(None, "planar") is None
    assert resolve_low_gate({}, "pinpoint_touchdown") == LOW_GATE_DEFAULTS
