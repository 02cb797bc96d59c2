"""Imitation on LunarPinpointLanding-v2: the certified dataset of the Pontryagin feedback
expert's flights, BC and DAgger with that expert as oracle, and the quick PPO run of the
shipped pinpoint entry (CI versions of the imitation-then-PPO pipeline)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import yaml

ENV_ID = "LunarPinpointLanding-v2"


@pytest.fixture(scope="module")
def pinpoint_dataset(tmp_path_factory):
    from agents.imitation.dataset import generate

    root = tmp_path_factory.mktemp("pinpoint_imitation")
    ds = generate(root / "pp.npz", env_id=ENV_ID, n=2, seed=3, n_workers=1, shard_size=2,
                  progress=False)
    return root, ds


@pytest.fixture(scope="module")
def pinpoint_bc(pinpoint_dataset):
    """One quick BC run on the dataset, shared (read only) by the DAgger tests: the clone that
    DAgger starts from and whose roll-outs the expert labels (trained once, not once per
    test)."""
    import agents.imitation.cli as im

    root, _ = pinpoint_dataset
    bc_dir = root / "bc"
    assert im.main(["bc", "--quick", "--env", ENV_ID, "--dataset", str(root / "pp.npz"),
                    "--run-dir", str(bc_dir), "--seed", "0", "--no-progress",
                    "--no-tensorboard", "--eval-states", "0"]) == 0
    return bc_dir


def test_pinpoint_dataset_is_certified_by_the_env(pinpoint_dataset):
    import gymnasium as gym

    import lunar_env  # noqa: F401
    from lunar_env.envs.pinpoint_landing import action_from_angles
    from lunar_env.states import moon3d_si_to_nd
    from optimizers.indirect.pinpoint_feedback import PinpointFeedback

    _, ds = pinpoint_dataset
    a = ds.arrays
    env = gym.make(ENV_ID).unwrapped
    sc = env.scenario
    assert ds.meta["env_id"] == ENV_ID and ds.meta["dt_s"] == env.dt_s
    assert ds.meta["solver"]["action_noise"] == pytest.approx(0.02)
    # certified = the expert's own (noisy) flight is the env's success; the per-case optimum
    # (the extremal from the start) is recorded beside the flight's fuel
    assert a["certified"].all() and a["replay_success"].all()
    assert (a["terminal_error_speed_m_s"] <= 5.0).all()
    assert (a["terminal_error_radius_m"] <= 500.0).all()
    assert np.all((270.0 < a["fuel_kg"]) & (a["fuel_kg"] < 295.0))
    np.testing.assert_allclose(a["fuel_kg"], sc.vehicle.mass_flow_kg_s * a["tf_s"], rtol=1e-9)
    # noise of 0.9° per step costs a fraction of a kilogram, not more
    assert np.all(np.abs(a["replay_fuel_gap_kg"]) < 1.5)
    # one sample per decision of each flight (labels of unconverged solves would be dropped)
    for k in range(2):
        m = a["traj_index"] == k
        t = a["t_s"][m]
        assert t[0] == 0.0 and len(t) == pytest.approx(a["tf_s"][k] / env.dt_s, abs=3)
        np.testing.assert_allclose(np.diff(t), env.dt_s, atol=1e-9)
        # the observations are the env's of the recorded states
        np.testing.assert_allclose(ds.observations[m],
                                   env.observation_from_state(a["state_nd"][m], t), atol=1e-6)
    assert ds.observations.shape[1] == 9 and ds.actions.shape[1] == 2
    assert np.all(np.abs(ds.actions) <= 1.0)
    # the labels are the expert's clean action (noise is only flown): at the initial states,
    # the extremal's law averaged over the first step
    x0 = moon3d_si_to_nd(a["initial_state_si"], sc.scaling())
    fb = PinpointFeedback(sc)
    ang = fb(x0, np.zeros(2), env.dt_s)
    first = a["t_s"] == 0.0
    np.testing.assert_allclose(ds.actions[first], action_from_angles(
        ang[:, 0], ang[:, 1], sc.alpha_bounds_rad, sc.beta_bounds_rad), atol=1e-5)


def test_pinpoint_bc_and_dagger_quick(pinpoint_dataset, pinpoint_bc, tmp_path):
    import agents.imitation.cli as im
    from agents.laws import SB3Law

    root, _ = pinpoint_dataset
    path = root / "pp.npz"
    bc_dir = pinpoint_bc
    hp = yaml.safe_load((bc_dir / "config.yml").read_text())
    assert "reference_profile" in hp["obs_features"] and "stop_point" in hp["obs_features"]
    pol = SB3Law.from_path(bc_dir)
    assert pol.obs_features == hp["obs_features"]
    assert pol.model.observation_space.shape == (31,)

    dg_dir = tmp_path / "dagger"
    # one roll-out (seeded: the clone and its roll-out, hence the cost of the labels, are the
    # same every run): the expert labels every state it visits, ~300 of them
    assert im.main(["dagger", "--quick", "--env", ENV_ID, "--dataset", str(path), "--init",
                    str(bc_dir), "--run-dir", str(dg_dir), "--seed", "0", "--no-progress",
                    "--no-tensorboard", "--eval-states", "0",
                    "--hyperparams", "dagger.n_episodes=1"]) == 0
    hist = yaml.safe_load((dg_dir / "dagger_history.yml").read_text())
    assert len(hist) == 1 and hist[0]["n_labels"] > 100
    # every visited state labelled by the feedback expert from converged solves only
    assert set(hist[0]["expert_status"]) <= {"optimal", "nearest", "hold"}
    assert hist[0]["expert_status"].get("optimal", 0) >= 1
    with np.load(dg_dir / "labels" / "iter_000.npz") as z:
        assert z["obs"].shape[1] == 9 and z["actions"].shape[1] == 2
        assert np.all(np.abs(z["actions"]) <= 1.0)
    assert (dg_dir / "model.zip").exists()
    # the final policy is the iteration chosen on held-out validation cases
    sel = yaml.safe_load((dg_dir / "selection.yml").read_text())
    assert sel["chosen_iteration"] == 0 and sel["n_states"] == 2
    assert sel["validation_seed"] == 50000 and len(sel["scores"]) == 1
    assert 0.0 <= sel["scores"][0]["success_rate"] <= 1.0

    # CI version of the fine-tuning stage: the from_dagger profile starts PPO from the clone,
    # with the clone's input standardisation and raw observations
    import agents.train as tr
    from agents.features import StandardizedInputs

    ft_dir = tmp_path / "ft"
    assert tr.main(["--env", ENV_ID, "--config", "from_dagger", "--init-from", str(dg_dir),
                    "--run-dir", str(ft_dir), "--seed", "0", "--no-eval", "--no-progress",
                    "--no-tensorboard", "-n", "2048", "--hyperparams", "n_envs=2",
                    "n_steps=512", "batch_size=512", "critic_warmup_steps=1024"]) == 0
    ft = SB3Law.from_path(ft_dir)
    assert isinstance(ft.model.policy.features_extractor, StandardizedInputs)
    assert ft.vecnormalize is None or ft.vecnormalize.norm_obs is False


def test_dagger_rollouts_mix_expert_and_policy(pinpoint_bc):
    """β = 0: every roll-out is the policy's alone; β = 1: every roll-out starts with the
    expert (up to a random switch time), so none counts as policy-only. The roll-outs fly 4 s
    decisions (the clone was trained at 1 s): what is checked is the mixing, and a quarter of
    the expert's solves keeps this the cheap twin of a DAgger iteration."""
    import agents.imitation.families.pinpoint as lab_mod
    from agents.imitation.policy import load_learner

    bc_dir = pinpoint_bc
    hp = yaml.safe_load((bc_dir / "config.yml").read_text())
    coarse = {"dt_s": 4.0}
    lab, roll = lab_mod.pinpoint_dagger_rollouts(bc_dir / "model.zip", load_learner, ENV_ID,
                                                 coarse, 1, 11, hp["obs_features"], beta=0.0,
                                                 progress=False)
    assert roll["rollout_policy_only_episodes"] == 1
    assert len(lab["obs"]) == len(lab["actions"]) > 10
    lab1, roll1 = lab_mod.pinpoint_dagger_rollouts(bc_dir / "model.zip", load_learner, ENV_ID,
                                                   coarse, 1, 11, hp["obs_features"], beta=1.0,
                                                   progress=False)
    assert len(lab1["obs"]) > 10
    # the expert flew the start: its labels are not the policy-only roll-out's
    assert not np.array_equal(lab1["obs"][:5], lab["obs"][:5])
    # no policy-only episode: the rate is then over all roll-outs (documented fallback)
    assert roll1["rollout_policy_only_episodes"] == 1 and 0.0 <= roll1["rollout_success_rate"]


def test_dataset_cli_runs_as_a_module(tmp_path):
    """Regression: ``lunar dataset`` failed before any work ("task function
    _shard_work is defined in __main__") because the shard function was taken from __main__."""
    out = tmp_path / "small.npz"
    res = subprocess.run([sys.executable, "-m", "agents.imitation.make_dataset", "--n", "2",
                          "--shard-size", "2", "--workers", "1", "--no-progress", "--out",
                          str(out)],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    assert out.exists()


def test_pinpoint_ppo_quick_with_curriculum_features_and_shaping(tmp_path):
    """CI version of the default pinpoint PPO run: the shipped entry (curriculum from the
    optimal extremals, features, shaping) at its @quick size, then the evaluation against the
    per-case optimum."""
    import json

    import agents.train as tr

    run_dir = tmp_path / "ppo"
    assert tr.main(["--quick", "--env", ENV_ID, "--seed", "3", "--run-dir", str(run_dir),
                    "--no-progress", "--no-tensorboard", "--eval-states", "2",
                    "--eval-expert-states", "0"]) == 0
    hp = yaml.safe_load((run_dir / "config.yml").read_text())
    assert hp["curriculum"] and hp["obs_features"] and hp["reward_shaping"]
    assert hp["curriculum"]["start_noise"]["position_m"] > 0
    # the final policy is the best of the last checkpoints on validation cases, copied whole
    sel = yaml.safe_load((run_dir / "selection.yml").read_text())
    assert sel["n_states"] == 2 and sel["validation_seed"] == 50000
    assert len(sel["scores"]) == 2 and sel["chosen_steps"] in [r["steps"] for r in sel["scores"]]
    chosen = run_dir / "checkpoints" / f"rl_model_{sel['chosen_steps']}_steps.zip"
    assert (run_dir / "model.zip").read_bytes() == chosen.read_bytes()
    rep = json.loads((run_dir / "evaluation" / "comparison.json").read_text())
    assert rep["optimum"]["converged"] == 2 and 270.0 < rep["optimum"]["fuel_mean_kg"] < 295.0
    rows = {r["policy"]: r for r in rep["rows"]}
    assert any(k.startswith("PPO") for k in rows) and "optimum, open loop" in rows


def test_same_view_teacher_labels_every_decision_and_flies_until_its_switch():
    """The law teacher (a guidance law on the navigation solution) is asked at every
    decision, whoever flies; its actions are the labels of the active landers; the learner
    flies each lander after that lander's switch time."""
    from agents.imitation.teachers import LawRolloutTeacher
    from guidance.law import CallableLaw, Navigation

    asked = []

    def teacher_fn(nav):
        # each row's action depends on its own navigation: labels from the wrong rows differ
        asked.append(nav.t_s.copy())
        return (np.float32([0.1, -0.2, 0.9]) * nav.obs[:, :1] / 26.0).astype(np.float32)

    teacher = CallableLaw(teacher_fn, "teacher")
    roll = LawRolloutTeacher(teacher,
                             lambda obs: np.full((len(obs), 3), -0.5, dtype=np.float32),
                             switch_s=np.array([0.0, 10.0, 1e9]))
    roll.reset(None, np.arange(3))
    nav = Navigation(obs=np.arange(27, dtype=np.float32).reshape(3, 9),
                     state_nd=np.zeros((3, 7)), t_s=np.array([4.0, 4.0, 4.0]),
                     active=np.array([True, False, True]))
    act = roll.act(nav)
    assert len(asked) == 1
    own = teacher.act(nav)  # the teacher asked again on the recorded navigation
    np.testing.assert_array_equal(act[0], [-0.5, -0.5, -0.5])  # switched at 0 s: the learner
    np.testing.assert_array_equal(act[1:], own[1:])  # before their switch: the law
    # labels: the active landers' navigated observations and the teacher's own actions there
    np.testing.assert_array_equal(roll.records["obs"][0], nav.obs[[0, 2]])
    np.testing.assert_array_equal(roll.records["actions"][0], own[[0, 2]])
    assert np.all(own[0] == 0.0) and not np.allclose(own[1], own[2])


def test_same_view_teacher_is_told_the_actions_flown():
    """The law's memory must follow the flight (the window law's thrust estimate, fed its own
    controls while the student flew, was 8 % off): the roll-out tells it the actions flown,
    the learner's after its switch, its own before."""
    from agents.imitation.teachers import LawRolloutTeacher
    from guidance.law import CallableLaw, Navigation

    told = []

    class Teacher(CallableLaw):
        def flown(self, nav, actions):
            told.append(np.array(actions))

    law = Teacher(lambda nav: np.full((nav.n, 3), 0.9, dtype=np.float32), "teacher")
    roll = LawRolloutTeacher(law, lambda obs: np.full((len(obs), 3), -0.5, dtype=np.float32),
                             switch_s=np.array([0.0, 1e9]))
    roll.reset(None, np.arange(2))
    nav = Navigation(obs=np.zeros((2, 9), dtype=np.float32), state_nd=np.zeros((2, 7)),
                     t_s=np.ones(2), active=np.ones(2, dtype=bool))
    flown = roll.act(nav)
    assert len(told) == 1
    np.testing.assert_array_equal(told[0], flown)
    np.testing.assert_allclose(told[0], [[-0.5] * 3, [0.9] * 3])


def test_same_view_teacher_drops_the_laws_guesses():
    """A law that reports a per-row status (the reserve law's ``last_status``): its guesses
    (no converged solve, "stale" / "fallback") are flown but not recorded as labels."""
    from agents.imitation.teachers import LawRolloutTeacher
    from guidance.law import CallableLaw, Navigation

    law = CallableLaw(lambda nav: np.zeros((nav.n, 3), dtype=np.float32), "teacher")
    law.last_status = ["optimal", "stale", "fallback", "window"]
    roll = LawRolloutTeacher(law, lambda obs: np.ones((len(obs), 3), dtype=np.float32),
                             switch_s=np.full(4, 1e9))
    roll.reset(None, np.arange(4))
    nav = Navigation(obs=np.arange(36, dtype=np.float32).reshape(4, 9),
                     state_nd=np.zeros((4, 7)), t_s=np.zeros(4), active=np.ones(4, dtype=bool))
    assert roll.act(nav).shape == (4, 3)
    np.testing.assert_array_equal(roll.records["obs"][0], nav.obs[[0, 3]])
    assert list(roll.records["status"][0]) == ["optimal", "window"]


def test_privileged_law_is_refused_as_a_same_view_teacher():
    from agents.imitation.families.pinpoint import DaggerRolloutTeacher
    from agents.imitation.teachers import LawRolloutTeacher

    privileged = DaggerRolloutTeacher(None, None, np.zeros(1))
    with pytest.raises(ValueError, match="same-view teacher"):
        LawRolloutTeacher(privileged, None, np.zeros(1))


def test_bad_teacher_is_refused_before_flying(pinpoint_bc):
    import agents.imitation.families.pinpoint as lab_mod
    from agents.imitation.policy import load_learner

    with pytest.raises(ValueError, match="unknown law 'nope'"):
        lab_mod.pinpoint_dagger_rollouts(pinpoint_bc / "model.zip", load_learner, ENV_ID, {}, 1,
                                         11, None, beta=0.0, progress=False,
                                         teacher="nope:x=1")


def test_dagger_rollouts_with_a_law_teacher_on_the_throttled_engine(monkeypatch):
    """The law teacher flies (β = 1, switch drawn in [0, 540] s) and labels a throttled,
    uncertain env: every label has the env's three channels (angles and throttle), and the
    learner's roll-out is scored. The learner here is a fixed action (no policy file needed:
    ``load_learner`` is any module-level loader). Each decision's labels are the teacher
    law's own actions on the navigation recorded there: a twin of the law, asked the same
    navigations in the same order and told the same actions flown, gives them again, before
    and after the switch."""
    import copy

    import agents.imitation.families.pinpoint as lab_mod
    import agents.imitation.teachers as teachers
    from guidance.flight import fly
    from guidance.law import ActionSequenceLaw, Navigation, actions_of

    made = []

    class Recording(teachers.LawRolloutTeacher):
        def __init__(self, teacher, learner, switch_s):
            super().__init__(teacher, learner, switch_s)
            self.twin = copy.deepcopy(teacher)  # built, not yet reset: a fresh law
            self.navs, self.flown = [], []
            made.append(self)

        def act(self, nav):
            self.navs.append(Navigation(
                obs=nav.obs.copy(), state_nd=nav.state_nd.copy(), t_s=nav.t_s.copy(),
                active=nav.active.copy(), episode_start=nav.episode_start.copy(),
                sensors={k: np.array(v) for k, v in nav.sensors.items()},
                frame_of=nav.frame_of))
            out = super().act(nav)
            self.flown.append(out.copy())
            return out

    monkeypatch.setattr(teachers, "LawRolloutTeacher", Recording)
    env_kwargs = {"dt_s": 4.0, "throttle_channel": True, "uncertainty": "standard"}
    lab, roll = lab_mod.pinpoint_dagger_rollouts(
        "unused", _fixed_learner, ENV_ID, env_kwargs, 1, 11, None, beta=1.0, progress=False,
        teacher="zem-zev")
    assert lab["actions"].shape[1] == 3 and len(lab["obs"]) > 10
    assert set(lab["status"]) == {"law"}
    assert np.isfinite(lab["actions"]).all() and (np.abs(lab["actions"]) <= 1.0).all()

    (rec,) = made
    # the roll-out's score is its episode's outcome: the actions flown, replayed open loop on
    # the same case, land (or not) the same way and burn the same propellant
    flown = [a[0] for a, nav in zip(rec.flown, rec.navs, strict=True) if nav.active[0]]
    replay = fly(ENV_ID, ActionSequenceLaw([np.array(flown)]), 1, seed=11,
                 env_kwargs=env_kwargs)
    assert roll["rollout_success_rate"] == float(replay.is_success[0])
    assert roll["rollout_fuel_mean_kg"] == float(replay.fuel_used_kg[0])
    rec.twin.reset(rec.computer, np.arange(1))
    n_learner = 0
    for k, nav in enumerate(rec.navs):
        again = actions_of(rec.twin.computer, rec.twin.act(nav))[nav.active]
        rec.twin.flown(nav, rec.flown[k])  # its engine estimate follows the flight
        np.testing.assert_array_equal(rec.records["actions"][k], again)
        np.testing.assert_array_equal(rec.records["obs"][k], nav.obs[nav.active])
        n_learner += int(np.any(nav.active & (nav.t_s >= rec.switch_s)))
    assert 0 < n_learner < len(rec.navs)  # labels on the teacher's flight and the learner's
    np.testing.assert_array_equal(lab["actions"], np.concatenate(rec.records["actions"]))


def _fixed_learner(model, env_id, env_kwargs, obs_features):
    """A learner that always commands zero angles at full throttle (a module-level loader, so
    that worker processes can load it like a policy file)."""
    return lambda obs: np.tile(np.float32([0.0, 0.0, 1.0]), (len(obs), 1))


def test_expert_flights_on_a_throttled_engine_keep_full_thrust_without_noise():
    """On a throttled env the constant-thrust expert's labels carry the throttle channel
    (without it the dataset fails), and no noise is put on it (clipped at full thrust, noise
    would only ever weaken the engine). Labels: the throttle at +1; flown: noise on the angles
    only."""
    from types import SimpleNamespace

    import gymnasium as gym

    import lunar_env  # noqa: F401
    from agents.imitation.families.pinpoint import ExpertFlightTeacher
    from guidance.law import FlightComputer, Navigation, Truth
    from lunar_env.envs.pinpoint_landing import angles_from_action

    env = gym.make(ENV_ID, throttle_channel=True).unwrapped
    n = 3

    class Expert:
        scenario = env.scenario
        feedback = SimpleNamespace(last_tgo_s=np.full(n, 500.0))
        last_status = np.array(["optimal"] * n)

        def reset(self, computer, case_ids):
            pass

        def labels(self, states, times, active):
            sc = env.scenario
            alpha, beta = angles_from_action(np.array([0.25, 0.25]), sc.alpha_bounds_rad,
                                             sc.beta_bounds_rad)
            return (np.tile([alpha, beta], (n, 1)), np.full((n, 2), 0.25, dtype=np.float32),
                    active.copy())

    teacher = ExpertFlightTeacher(Expert(), n, 0.3, np.random.default_rng(0))
    teacher.reset(FlightComputer.of(env, ENV_ID), np.arange(n))
    nav = Navigation(obs=np.zeros((n, 9), dtype=np.float32), state_nd=np.zeros((n, 7)),
                     t_s=np.zeros(n), active=np.ones(n, dtype=bool))
    flown = teacher.act_privileged(nav, Truth(state_nd=np.zeros((n, 7)), t_s=np.zeros(n)))
    assert flown.shape == (n, 3)
    np.testing.assert_array_equal(flown[:, 2], 1.0)
    assert np.all(flown[:, :2] != 0.25)  # the angles carry the noise
    for i in range(n):
        np.testing.assert_allclose(teacher.records["actions"][i][0], [0.25, 0.25, 1.0],
                                   rtol=0, atol=1e-6)
