"""Imitation on ``LunarPinpointLanding-v3``: the dataset of certified optimal landings flown in
the env (rows, samples, certification), its Minari export, and DAgger with law teachers only."""

from __future__ import annotations

import numpy as np
import pytest

from agents.imitation import make_dataset as dataset_cli
from agents.imitation.data import load_dataset
from agents.imitation.families import IMITATION_FAMILIES, DaggerRequest
from agents.imitation.families.touchdown import NO_BUILT_IN_TEACHER, TOUCHDOWN_TOLERANCES
from agents.imitation.teachers import parse_teacher
from lunar_env import get_scenario

ENV_ID = "LunarPinpointLanding-v3"
SC = get_scenario("peng2012_touchdown")
OPTS = {"n_steps": 400, "check": "doubling", "tol_radius_m": None, "tol_speed_m_s": None}


@pytest.fixture(scope="module")
def dataset_file(minari_dir, tmp_path_factory):
    """``lunar dataset --env LunarPinpointLanding-v3 --n 2 --minari optimal-v0``: its file."""
    out = tmp_path_factory.mktemp("ds") / "v3.npz"
    assert dataset_cli.main(["--env", ENV_ID, "--n", "2", "--seed", "1", "--workers", "1",
                             "--out", str(out), "--no-progress", "--minari",
                             "optimal-v0"]) == 0
    return out


@pytest.fixture(scope="module")
def dataset(dataset_file):
    return load_dataset(dataset_file)


def test_recipe_rows_and_refused_noise():
    from optimizers.common.executor import check_importable

    fam = IMITATION_FAMILIES.of(SC)
    rec = fam.dataset_recipe(SC, 3, 4, action_noise=None, **OPTS)
    assert rec.rows.shape == (3, 7) and rec.tolerances == (100.0, 5.0)
    want = [SC.state_nd(r, scaling=SC.scaling())
            for r in SC.sample_initial(np.random.default_rng(4), 3)]
    np.testing.assert_array_equal(rec.rows, want)
    assert len(rec.observation_names) == 8 and rec.job_args == {}
    assert check_importable(rec.shard_fn).__module__ == "agents.imitation.families.touchdown"
    assert fam.dataset_recipe(SC, 1, 0, action_noise=0.0, **OPTS).solver["action_noise"] == 0.0
    with pytest.raises(ValueError, match="certified optimal flights themselves"):
        fam.dataset_recipe(SC, 1, 0, action_noise=0.02, **OPTS)


def test_samples_are_the_certified_optima_flown_in_the_env(dataset):
    """Every decision of each certified flight is a sample: its observation is the env's of the
    recorded state, its action the optimum's step mean (while the plan lasts), and the flight
    touched down within the tolerances with the optimum's propellant."""
    import gymnasium as gym

    import lunar_env  # noqa: F401
    from guidance.laws.touchdown_baselines import plan_step_controls
    from optimizers.optimum.touchdown import touchdown_optima

    a = dataset.arrays
    assert a["certified"].all() and dataset.summary()["n_certified"] == 2
    assert dataset.meta["certification"]["tol_radius_m"] == TOUCHDOWN_TOLERANCES["radius_m"]
    assert np.all(a["terminal_error_radius_m"] <= 100.0)
    assert np.all(a["terminal_error_speed_m_s"] <= 5.0)
    assert np.all(np.abs(a["replay_fuel_gap_kg"]) < 1.0)
    env = gym.make(ENV_ID).unwrapped
    np.testing.assert_array_equal(env.observation_from_state(a["state_nd"], a["t_s"]),
                                  a["observations"])
    x0 = np.stack([a["state_nd"][a["traj_index"] == i][0] for i in range(2)])
    optima = touchdown_optima(SC, x0, progress=False)
    for i, opt in enumerate(optima):
        rows = np.flatnonzero(a["traj_index"] == i)
        t = a["t_s"][rows]
        np.testing.assert_allclose(t, np.arange(len(rows)), rtol=0, atol=1e-9)
        assert len(rows) >= int(np.ceil(opt.tf_s))  # the whole plan, then the descent
        plan = t < opt.tf_s - 1.0
        want = env.task.actions_from_controls(
            np.array([plan_step_controls(opt, ti, 1.0, SC) for ti in t[plan]]))
        np.testing.assert_allclose(a["actions"][rows][plan], want, atol=1e-6)
        assert a["fuel_kg"][i] == pytest.approx(opt.fuel_kg)
    env.close()


def test_minari_episodes_are_the_datasets_flights(dataset, minari_dir):
    from agents.imitation.sources import open_dataset

    back = open_dataset(f"minari:lunar/{ENV_ID}/optimal-v0")
    assert back.meta["env_id"] == ENV_ID
    assert np.array_equal(back.observations, dataset.observations)
    assert np.array_equal(back.actions, dataset.actions)
    import minari

    mds = minari.load_dataset(f"lunar/{ENV_ID}/optimal-v0")
    meta = mds.storage.metadata
    assert mds.total_episodes == 2
    assert meta["ref_min_score"] < meta["ref_max_score"] - 10.0
    for ep in mds.iterate_episodes():
        assert ep.terminations[-1] and not ep.terminations[:-1].any()


def test_dagger_refuses_the_built_in_teachers_with_the_reason():
    fam = IMITATION_FAMILIES.of(SC)
    for kind in ("privileged", "navigated", None):
        with pytest.raises(ValueError, match="no built-in DAgger teacher") as exc:
            fam.check_teacher(parse_teacher(kind))
        assert NO_BUILT_IN_TEACHER in str(exc.value)
    fam.check_teacher(parse_teacher("zem-zev"))
    request = DaggerRequest(env_id=ENV_ID, env_kwargs={}, policy_file="unused",
                            load_learner=_diving, obs_features=None, n_episodes=1, seed=0,
                            settings={}, progress=False)
    with pytest.raises(ValueError, match="no built-in DAgger teacher"):
        fam.dagger_iteration(SC, request)


def _diving(model, env_id, env_kwargs, obs_features):
    """A module-level learner loader: a student that dives at full thrust (50° down)."""
    return _dive


def _dive(obs: np.ndarray) -> np.ndarray:
    return np.tile(np.array([[-1.0, 0.0, 1.0]], dtype=np.float32), (len(obs), 1))


def test_a_law_teacher_labels_a_v3_dagger_iteration():
    """``zem-zev`` flies along with the student (β = 0: the student throughout, which dives
    into the ground) and labels every decision with its own three-channel action."""
    request = DaggerRequest(env_id=ENV_ID, env_kwargs={"dt_s": 2.0}, policy_file="unused",
                            load_learner=_diving, obs_features=None, n_episodes=2, seed=3,
                            settings={"teacher": "zem-zev", "beta": 0.0}, progress=False)
    lab, roll = IMITATION_FAMILIES.of(SC).dagger_iteration(SC, request)
    assert set(lab["status"]) == {"law"} and lab["actions"].shape == (len(lab["obs"]), 3)
    assert len(lab["obs"]) > 20 and np.isfinite(lab["actions"]).all()
    assert np.abs(lab["actions"]).max() <= 1.0 and lab["actions"][:, :2].std(axis=0).min() > 0.0
    assert roll["rollout_success_rate"] == 0.0 and roll["rollout_policy_only_episodes"] == 2.0


def _throttled_down(obs: np.ndarray) -> np.ndarray:
    """A student that flies a throttle well below the teacher's (action −0.5 of the
    throttle channel) and a fixed attitude."""
    return np.tile(np.array([[0.3, 0.0, -0.5]], dtype=np.float32), (len(obs), 1))


@pytest.mark.parametrize("student", [_throttled_down, _dive])
def test_a_law_teachers_engine_estimate_follows_the_throttle_flown(student):
    """ZEM/ZEV with the IMU, flying along while a student flies other throttles, measures the
    engine the student's throttles give: the same thrust scale as when it flies itself (the
    nominal world's engine, 1). Told nothing, it divided the IMU's reading by its own throttle
    and believed a 40 % engine under the throttled-down student."""
    from agents.imitation.teachers import LawRolloutTeacher
    from guidance.flight import fly
    from guidance.registry import LawContext, build_law

    kw = {"dt_s": 2.0, "sensors": ["imu"]}
    law = build_law("zem-zev", LawContext(env_id=ENV_ID, env_kwargs=kw, scenario=SC))
    scales = []

    def learner(obs):
        scales.append(law.estimator.scale[law.estimator.measured].copy())
        return student(obs)

    fly(ENV_ID, LawRolloutTeacher(law, learner, np.zeros(3)), 3, seed=3, env_kwargs=kw)
    measured = np.concatenate(scales[1:8])
    assert len(measured) >= 6
    np.testing.assert_allclose(measured, 1.0, atol=0.02)


class _SpyStudent:
    """A deterministic 'model' of a history student: its action a fixed function of its input
    row (the throttle channel at −0.5, below the teacher's)."""

    def __init__(self, observation_space):
        self.observation_space = observation_space
        n = observation_space.shape[0]
        self.w = np.random.default_rng(0).normal(size=(n, 2)).astype(np.float32) / np.sqrt(n)

    def predict(self, obs, deterministic=True, **kwargs):
        a = np.tanh(np.asarray(obs, dtype=np.float32) @ self.w)
        return np.c_[a, np.full(len(a), -0.5, np.float32)], None


@pytest.mark.parametrize("switch_s", [np.inf, 0.0, 20.0])
def test_a_history_students_inputs_hold_the_actions_flown(switch_s):
    """The labels' inputs of a student with a history (k = 2) are its stacked inputs, and their
    newest action slot is the action flown at the decision before: the teacher's while the
    teacher flies (to the end at switch inf), the student's own after the switch."""
    from gymnasium import spaces

    from agents.features.history import history_space
    from agents.imitation.teachers import LawRolloutTeacher
    from agents.laws import SB3Law
    from guidance.flight import fly
    from guidance.registry import LawContext, build_law

    kw = {"dt_s": 2.0, "sensors": ["imu"]}
    law = build_law("zem-zev", LawContext(env_id=ENV_ID, env_kwargs=kw, scenario=SC))
    n_obs = 11
    box = spaces.Box(-np.inf, np.inf, (n_obs,), np.float32)
    act = spaces.Box(-1.0, 1.0, (3,), np.float32)
    student = SB3Law(_SpyStudent(history_space(box, act, 2)), None, history=2)
    flown, inputs = [], []
    rollout = LawRolloutTeacher(law, student, np.full(2, switch_s))
    act_fn = rollout.act

    def spy(nav):
        a = act_fn(nav)
        flown.append(a.copy())
        inputs.append(student.last_inputs.copy())
        return a

    rollout.act = spy
    fly(ENV_ID, rollout, 2, seed=5, env_kwargs=kw)
    inputs, flown = np.array(inputs), np.array(flown)
    assert inputs.shape[2] == 2 * (n_obs + 3)
    newest_obs = inputs[:, :, n_obs:2 * n_obs]
    newest_action = inputs[:, :, -3:]
    # decision t's newest action slot is the action flown at t - 1 (0 at the first)
    np.testing.assert_array_equal(newest_action[0], 0.0)
    np.testing.assert_allclose(newest_action[1:20], flown[:19], atol=1e-6)
    # the older input slot is the newest one of the decision before
    np.testing.assert_array_equal(inputs[1:20, :, :n_obs], newest_obs[:19])
    labels = np.concatenate(rollout.records["obs"])
    assert labels.shape[1] == 2 * (n_obs + 3)
    throttle_low = np.isclose(flown[:20, :, 2], -0.5)
    if switch_s == np.inf:
        assert not throttle_low.any()  # the teacher flew throughout
    elif switch_s == 0.0:
        assert throttle_low.all()
    else:
        assert throttle_low[12:].all() and not throttle_low[:8].any()


def test_dagger_with_a_history_from_the_cli(dataset_file, tmp_path):
    """``history: 2``: the teacher flies the first iteration, the student (stacked inputs, its
    standardisation from those flights) flies the second, the selection and the saved run
    carry the history, and the run flies as a law; a history is refused, before a run
    directory exists, for behaviour cloning and with a dataset share of the minibatches."""
    import yaml

    import agents.imitation.cli as im
    from agents.features import StandardizedInputs
    from agents.imitation.policy import imitation_history
    from agents.laws import SB3Law
    from guidance.flight import rollout

    path = dataset_file
    run = tmp_path / "dg"
    assert im.main(["dagger", "--quick", "--env", ENV_ID, "--dataset", str(path),
                    "--run-dir", str(run), "--seed", "0", "--no-progress", "--no-tensorboard",
                    "--hyperparams", "history=2", "dagger.n_iterations=2",
                    "dagger.teacher=zem-zev"]) == 0
    hist = yaml.safe_load((run / "dagger_history.yml").read_text())
    assert [h["iteration"] for h in hist] == [0, 1]
    # iteration 0: the teacher throughout (its roll-outs are all mixed, none the policy's)
    with np.load(run / "labels" / "iter_000.npz") as z:
        n_in = z["obs"].shape[1]
        assert float(z["rollout_policy_only_episodes"]) == 2.0  # over all: none learner-only
    with np.load(run / "labels" / "iter_001.npz") as z:
        assert z["obs"].shape[1] == n_in
    law = SB3Law.from_path(run)
    assert law.history == 2 and law.model.observation_space.shape == (n_in,)
    ext = law.model.policy.features_extractor
    assert isinstance(ext, StandardizedInputs) and float(ext.std.min()) > 0.0
    assert not np.allclose(ext.mean.numpy(), 0.0)  # the teacher's flights' statistics
    assert yaml.safe_load((run / "selection.yml").read_text())["n_states"] == 2
    res = rollout(ENV_ID, law, 2, 7, {}, trace_cases=0)
    assert len(res.is_success) == 2

    # the PPO fine-tune of the student: its history, its standardisation, raw observations
    import agents.train as tr

    student_env = yaml.safe_load((run / "config.yml").read_text()).get("env_kwargs") or {}
    ft = tmp_path / "ft"
    assert tr.main(["--env", ENV_ID, "--config", "from_dagger", "--init-from", str(run),
                    "--run-dir", str(ft), "--seed", "0", "--no-eval", "--no-progress",
                    "--no-tensorboard", "-n", "1024", "--hyperparams", "n_envs=2",
                    "n_steps=256", "batch_size=256", "critic_warmup_steps=512",
                    f"env_kwargs={student_env!r}"]) == 0
    tuned = SB3Law.from_path(ft)
    assert tuned.history == 2 and tuned.model.observation_space.shape == (n_in,)
    assert isinstance(tuned.model.policy.features_extractor, StandardizedInputs)
    assert tuned.vecnormalize is None or tuned.vecnormalize.norm_obs is False

    hp = {"history": 2, "dagger": {"teacher": "zem-zev", "dagger_fraction": None}}
    with pytest.raises(ValueError, match="behaviour cloning"):
        imitation_history(hp, "bc")
    with pytest.raises(ValueError, match="law teacher"):
        imitation_history({"history": 2, "dagger": {"teacher": "navigated"}}, "dagger")
    with pytest.raises(ValueError, match="dagger_fraction"):
        imitation_history({"history": 2, "dagger": {"teacher": "zem-zev",
                                                    "dagger_fraction": 0.5}}, "dagger")
    with pytest.raises(ValueError, match="history=0"):
        imitation_history({"history": 0, "dagger": {}}, "dagger")
    assert imitation_history(hp, "dagger") == 2 and imitation_history({}, "bc") is None
    with pytest.raises(SystemExit):
        im.main(["bc", "--quick", "--env", ENV_ID, "--dataset", str(path), "--run-dir",
                 str(tmp_path / "bc"), "--hyperparams", "history=2"])
    assert not (tmp_path / "bc").exists()
