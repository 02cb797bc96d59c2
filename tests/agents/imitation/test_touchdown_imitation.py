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
def dataset(minari_dir, tmp_path_factory):
    """``lunar dataset --env LunarPinpointLanding-v3 --n 2 --minari optimal-v0``."""
    out = tmp_path_factory.mktemp("ds") / "v3.npz"
    assert dataset_cli.main(["--env", ENV_ID, "--n", "2", "--seed", "1", "--workers", "1",
                             "--out", str(out), "--no-progress", "--minari",
                             "optimal-v0"]) == 0
    return load_dataset(out)


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
