"""DAgger teachers, one contract for both families (:mod:`agents.imitation.teachers`): the
planar expert's two views, ``privileged`` (true state, true plant) and ``navigated`` (the
student's navigation solution, nominal plant), on short roll-outs under uncertainty models that
isolate one kind of error; the pinpoint expert's two views; a law spec as teacher in either
family; and the run's env arguments."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from agents.imitation.families import planar as pd
from guidance.laws.pontryagin_planar import PontryaginExpert, planar_state_si
from lunar_env import get_scenario

ENV_ID = "LunarSoftLanding-v0"
SCENARIO = "zhu2007"
DT_S = 1.0
#: labelled steps of the truncated roll-outs: every 20th and the last (dense tail of 0 s)
N_STEPS, LABEL_EVERY = 60, 20
THRUST_ONLY = {"thrust_scale": 0.05}
NAVIGATION_ONLY = {"nav_position_bias_m": [100.0, 200.0, 0.0],
                   "nav_velocity_bias_m_s": [0.5, 0.5, 0.0],
                   "nav_position_noise_m": [10.0, 10.0, 0.0]}


def _hold_attitude(obs: np.ndarray) -> np.ndarray:
    """A student that holds φ = 0 (the optimum's early attitude): its first minute of flight
    stays landable, so the expert converges from every labelled state."""
    return np.zeros((len(obs), 1), dtype=np.float32)


def _episodes(uncertainty) -> list[dict]:
    """Two roll-outs under ``uncertainty``, cut to their first :data:`N_STEPS` decisions."""
    eps = pd.rollout_policy(_hold_attitude, ENV_ID, {"uncertainty": uncertainty}, 2, seed=7)
    return [{k: (v[:N_STEPS] if isinstance(v, np.ndarray) else v) for k, v in e.items()}
            for e in eps]


def _labels(eps: list[dict], teacher: str) -> dict[str, np.ndarray]:
    sc = get_scenario(SCENARIO)
    return pd.label_episodes(eps, SCENARIO, DT_S, LABEL_EVERY, 0.0, progress=False,
                             velocity_ref_m_s=sc.scaling().velocity_m_s, teacher=teacher)


def _expert_labels(scenario, eps: list[dict], key: str) -> np.ndarray:
    """The labels written out: per episode one expert on ``scenario``, re-planning in time
    order from the states ``ep[key]`` at the labelled steps, each label the new plan's angle
    at mid-step."""
    nominal = get_scenario(SCENARIO)
    out = []
    for ep in eps:
        idx = np.r_[np.arange(0, N_STEPS, LABEL_EVERY), N_STEPS - 1]
        expert = PontryaginExpert(scenario)
        for k in idx:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                expert(planar_state_si(nominal, ep[key][k]), t_s=float(ep["t_s"][k]))
            assert expert.last_status == ["optimal"]
            out.append(expert.plan(0).thrust_angle_at(0.5 * DT_S))
    return np.asarray(out)


def test_rollout_records_navigation_and_true_plant():
    """The roll-outs keep the true states, the navigation solutions the observations encode,
    and each lander's drawn engine (1 in the nominal world)."""
    nominal = _episodes("none")
    for ep in nominal:
        np.testing.assert_array_equal(ep["navigation_state_nd"], ep["state_nd"])
        assert ep["thrust_scale"] == ep["isp_scale"] == 1.0
    nav = _episodes(NAVIGATION_ONLY)
    for ep in nav:
        assert ep["navigation_state_nd"].shape == ep["state_nd"].shape
        assert not np.allclose(ep["navigation_state_nd"][:, 0], ep["state_nd"][:, 0],
                               rtol=0.0, atol=1e-7)
        assert ep["thrust_scale"] == ep["isp_scale"] == 1.0


def test_nominal_world_both_teachers_label_identically():
    eps = _episodes("none")
    priv, navi = _labels(eps, "privileged"), _labels(eps, "navigated")
    assert len(priv["obs"]) == 2 * 4
    for k in priv:
        np.testing.assert_array_equal(priv[k], navi[k], err_msg=k)


def test_privileged_teacher_plans_with_the_landers_true_engine():
    """Thrust error only: the privileged labels are the expert's on a scenario whose engine
    has the lander's true thrust, from the true states; the navigated teacher (nominal engine)
    labels otherwise."""
    eps = _episodes(THRUST_ONLY)
    scales = [ep["thrust_scale"] for ep in eps]
    assert all(abs(s - 1.0) > 1e-3 for s in scales) and all(ep["isp_scale"] == 1.0 for ep in eps)
    priv = _labels(eps, "privileged")
    nominal = get_scenario(SCENARIO)
    want = []
    for ep in eps:
        v = nominal.vehicle
        true_engine = dataclasses.replace(
            nominal, vehicle=dataclasses.replace(v, thrust_n=v.thrust_n * ep["thrust_scale"]))
        want.append(_expert_labels(true_engine, [ep], "state_nd"))
    np.testing.assert_allclose(priv["phi_rad"], np.concatenate(want), rtol=0.0, atol=1e-12)
    assert set(priv["status"]) == {"optimal"}
    navi = _labels(eps, "navigated")
    assert np.max(np.abs(navi["phi_rad"] - priv["phi_rad"])) > 1e-4
    np.testing.assert_array_equal(priv["obs"], navi["obs"])  # same student observations


def test_navigated_teacher_plans_from_the_navigation_solution():
    """Navigation errors only: the navigated teacher's labels are the nominal expert's at the
    navigated states; the privileged teacher's are the same expert's at the true states."""
    eps = _episodes(NAVIGATION_ONLY)
    nominal = get_scenario(SCENARIO)
    navi = _labels(eps, "navigated")
    np.testing.assert_allclose(navi["phi_rad"],
                               _expert_labels(nominal, eps, "navigation_state_nd"),
                               rtol=0.0, atol=1e-12)
    priv = _labels(eps, "privileged")
    np.testing.assert_allclose(priv["phi_rad"], _expert_labels(nominal, eps, "state_nd"),
                               rtol=0.0, atol=1e-12)
    assert np.max(np.abs(navi["phi_rad"] - priv["phi_rad"])) > 1e-6


def test_bad_teacher_is_refused_by_name():
    from agents.imitation.families import DaggerRequest

    eps = [{"obs": np.zeros((1, 5), np.float32), "state_nd": np.ones((1, 5)),
            "t_s": np.zeros(1)}]
    with pytest.raises(ValueError, match=r"teacher = 'oracle' is not allowed; choose one of "
                                         r"privileged, navigated"):
        pd.label_episodes(eps, SCENARIO, DT_S, 1, 0.0, progress=False, teacher="oracle")
    with pytest.raises(ValueError, match="'oracle'"):
        pd.label_chunk({"scenario": SCENARIO, "dt_s": DT_S, "teacher": "oracle",
                        "episodes": []})

    def never(*args):
        raise AssertionError("the teacher must be checked before the policy is loaded")

    request = DaggerRequest(env_id=ENV_ID, env_kwargs={}, policy_file="none.zip",
                            load_learner=never, obs_features=None, n_episodes=1, seed=0,
                            settings={"teacher": "Privileged", "label_every": 1,
                                      "dense_tail_s": 0.0})
    with pytest.raises(ValueError, match="'Privileged'"):
        pd.planar_dagger_iteration(get_scenario(SCENARIO), request)
    # the navigated teacher needs the navigation solutions of a roll-out
    with pytest.raises(ValueError, match="navigation_state_nd"):
        pd.label_episodes(eps, SCENARIO, DT_S, 1, 0.0, progress=False, teacher="navigated")


def test_run_env_kwargs_merge_over_the_dataset_and_keep_its_decision_interval():
    from agents.imitation.sources import run_env_kwargs

    assert run_env_kwargs(ENV_ID, {}, None) == {}
    assert run_env_kwargs(ENV_ID, {"dt_s": 1.0}, {"uncertainty": "standard"}) == {
        "dt_s": 1.0, "uncertainty": "standard"}
    # the env's default equals the dataset's implicit value: allowed
    assert run_env_kwargs(ENV_ID, {}, {"dt_s": 1.0, "uncertainty": "standard"}) == {
        "dt_s": 1.0, "uncertainty": "standard"}
    with pytest.raises(ValueError, match=r"changes the env's dt_s from the dataset's 1.0 to 2.5"):
        run_env_kwargs(ENV_ID, {}, {"dt_s": 2.5, "uncertainty": "standard"})
    with pytest.raises(ValueError, match="must be a mapping"):
        run_env_kwargs(ENV_ID, {}, "standard")


def test_dataset_recipes_of_both_families():
    """Each family answers what its imitation dataset is made of (rows, names, tolerances,
    label rule, a module-level shard task), and refuses options it does not take."""
    from agents.imitation.families import IMITATION_FAMILIES, DatasetRecipe
    from agents.imitation.flights import make_env
    from optimizers.common.executor import check_importable

    opts = {"n_steps": 200, "check": "grid", "tol_radius_m": None, "tol_speed_m_s": None}
    planar_sc = get_scenario("zhu2007")
    rec = IMITATION_FAMILIES.of(planar_sc).dataset_recipe(planar_sc, 3, 4, action_noise=None,
                                                          **opts)
    assert isinstance(rec, DatasetRecipe) and rec.rows.shape == (3, 5)
    np.testing.assert_array_equal(
        rec.rows, planar_sc.sample_initial(np.random.default_rng(4), 3))  # SI rows
    assert rec.tolerances == (1e-3, 1e-3) and len(rec.observation_names) == 5
    assert rec.job_args == {"n_steps": 200, "check": "grid"}
    assert check_importable(rec.shard_fn).__module__ == "agents.imitation.families.planar"
    with pytest.raises(ValueError, match="action_noise = 0.1: defined for the pinpoint env"):
        IMITATION_FAMILIES.of(planar_sc).dataset_recipe(planar_sc, 3, 4, action_noise=0.1, **opts)

    env = make_env("LunarPinpointLanding-v2", None)
    pp_sc = env.scenario
    env.close()
    fam = IMITATION_FAMILIES.of(pp_sc)
    rec = fam.dataset_recipe(pp_sc, 2, 0, action_noise=None,
                             **dict(opts, tol_speed_m_s=3.0))
    assert rec.rows.shape == (2, 7) and rec.tolerances == (500.0, 3.0)
    assert len(rec.observation_names) == env.observation_space.shape[0]
    assert rec.job_args == {"action_noise": 0.02} and rec.solver["action_noise"] == 0.02
    assert check_importable(rec.shard_fn).__module__ == "agents.imitation.families.pinpoint"
    for bad in (-0.1, float("nan")):
        with pytest.raises(ValueError, match="action_noise = .* must be finite and >= 0"):
            fam.dataset_recipe(pp_sc, 2, 0, action_noise=bad, **opts)


def test_one_teacher_setting_for_every_family():
    from agents.imitation.teachers import TEACHER_KINDS, Teacher, parse_teacher

    assert TEACHER_KINDS == ("privileged", "navigated")
    assert parse_teacher(None) == Teacher("privileged")
    assert parse_teacher("navigated") == Teacher("navigated")
    law = parse_teacher("apollo:kr=10")
    assert law.is_law and law.spec == "apollo:kr=10" and str(law) == "apollo:kr=10"
    for bad in ("oracle", "", 3, "Privileged", "nope:x=1"):
        with pytest.raises(ValueError, match="dagger teacher|privileged, navigated"):
            parse_teacher(bad)


def _still(model, env_id, env_kwargs, obs_features):
    """A module-level learner loader: a student that holds φ = 0."""
    return _hold_attitude


def test_a_law_teacher_labels_a_planar_dagger_iteration():
    """A law spec as the planar teacher: the law flies along with the student (β = 0: the
    student throughout) and labels every active decision with its own action, which a twin of
    the law asked on the same observations gives again."""
    from agents.imitation.families import DaggerRequest

    request = DaggerRequest(env_id=ENV_ID, env_kwargs={"dt_s": 10.0}, policy_file="unused",
                            load_learner=_still, obs_features=None, n_episodes=2, seed=3,
                            settings={"teacher": "zem-zev"}, progress=False)
    lab, roll = pd.planar_dagger_iteration(get_scenario(SCENARIO), request)
    assert set(lab["status"]) == {"law"} and lab["actions"].shape == (len(lab["obs"]), 1)
    assert len(lab["obs"]) > 10 and np.isfinite(lab["actions"]).all()
    assert roll["rollout_policy_only_episodes"] == 2.0 and roll["label_wall_s"] == 0.0
    assert np.abs(lab["actions"]).max() <= 1.0 and lab["actions"].std() > 0.0


def test_the_pinpoint_expert_labels_from_the_view_its_setting_names():
    """``privileged`` plans from the true state, ``navigated`` from the navigation solution;
    an unknown view is refused."""
    from agents.imitation.families.pinpoint import DaggerRolloutTeacher
    from guidance.law import Navigation, Truth

    class Expert:
        last_status = ["optimal", "optimal"]

        def reset(self, computer, case_ids):
            pass

        def labels(self, state_nd, t_s, active):
            self.seen = np.array(state_nd)
            return np.zeros((2, 2)), None, np.ones(2, dtype=bool)

    class Computer:
        @staticmethod
        def actions_from_controls(controls):
            return np.zeros((len(controls), 3), dtype=np.float32)

    nav = Navigation(obs=np.zeros((2, 9), np.float32), state_nd=np.full((2, 7), 2.0),
                     t_s=np.zeros(2), active=np.ones(2, dtype=bool))
    truth = Truth(state_nd=np.full((2, 7), 1.0), t_s=np.zeros(2))
    for view, want in (("privileged", 1.0), ("navigated", 2.0)):
        expert = Expert()
        roll = DaggerRolloutTeacher(expert, lambda obs: np.zeros((len(obs), 3), np.float32),
                                    np.zeros(2), view=view)
        roll.computer = Computer()
        roll.act_privileged(nav, truth)
        assert np.all(expert.seen == want), view
    with pytest.raises(ValueError, match="view = 'truth' is not allowed"):
        DaggerRolloutTeacher(Expert(), None, np.zeros(2), view="truth")
