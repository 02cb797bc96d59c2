"""The guidance-law contract (guidance.law): what a law is given, what it may not see, and
how a new law is flown by the evaluation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from guidance.evaluation.compare import compare
from guidance.flight import fly, rollout
from guidance.law import (
    PRIVILEGED_MARK,
    ActionSequenceLaw,
    CallableLaw,
    FlightComputer,
    GuidanceLaw,
    Navigation,
    PrivilegedLaw,
    ThrustCommand,
    Truth,
    law_label,
)

ENV_ID = "LunarSoftLanding-v0"


class ConstantAttitude(GuidanceLaw):
    """The module docstring's example: a new law in ten lines."""

    name = "constant attitude"

    def __init__(self, action):
        self.action = np.asarray(action, dtype=np.float32)

    def act(self, nav):
        return np.broadcast_to(self.action, (nav.n, self.action.size)).copy()


class Recorder(GuidanceLaw):
    name = "recorder"

    def __init__(self):
        self.calls: list[Navigation] = []

    def reset(self, computer, case_ids):
        super().reset(computer, case_ids)
        self.case_ids = np.asarray(case_ids)

    def act(self, nav):
        self.calls.append(nav)
        return np.zeros((nav.n, 1), dtype=np.float32)


class Teacher(PrivilegedLaw):
    name = "teacher"

    def __init__(self):
        self.truths: list[Truth] = []

    def act_privileged(self, nav, truth):
        self.truths.append(truth)
        return np.zeros((nav.n, 1), dtype=np.float32)


def test_a_new_law_is_flown_by_the_evaluation_beside_the_baselines():
    """Each new law's row is that law's own flight of the evaluation's cases: one that crashes
    everywhere (a fixed attitude) and one that lands (ZEM/ZEV), beside the baselines."""
    from guidance.explicit import K_R_ZEM_ZEV
    from guidance.laws.apollo import AugmentedApolloLaw

    new_laws = (lambda: ConstantAttitude([0.2]),
                lambda: AugmentedApolloLaw(k_r=K_R_ZEM_ZEV, name="zem-zev"))
    rep = compare(ENV_ID, [make() for make in new_laws], n_states=3, seed=11,
                  n_expert_states=0, progress=False)
    names = [r["policy"] for r in rep["rows"]]
    # the random law flies last: the normalised score's 0 reference
    assert names == ["constant attitude", "zem-zev", "Pontryagin open loop", "random"]
    # the same cases flown directly (case i: sub-env seeded 11 + i)
    n_landed = []
    for row, make in zip(rep["rows"][:2], new_laws, strict=True):
        own = fly(ENV_ID, make(), 3, seed=11)
        n_landed.append(int(np.sum(own.is_success)))
        assert row["n_cases"] == 3 and row["success_rate"] * 3 == n_landed[-1]
        assert row["fuel_mean_kg"] == float(np.nanmean(own.fuel_used_kg)) > 0.0
        assert row["return_mean"] == float(np.mean(own.episode_return))
        assert row["n_cases_in_score"] == 3
    assert n_landed == [0, 3]
    # the open-loop optimum lands every case at the optimum's fuel
    assert rep["rows"][2]["success_rate"] == 1.0
    assert abs(rep["rows"][2]["fuel_gap_pct"]) < 0.05
    # score: the optimum's replay is 100 and the random law 0 by definition
    assert rep["rows"][2]["score"] == pytest.approx(100.0)
    assert rep["rows"][3]["score"] == pytest.approx(0.0)


def test_an_ordinary_law_gets_the_flight_computer_and_navigation_only():
    law = Recorder()
    fly(ENV_ID, law, 4, seed=3)
    comp = law.computer
    assert isinstance(comp, FlightComputer)
    assert comp.env_id == ENV_ID and comp.dt_s > 0 and comp.gate_range_m is None
    assert comp.physical_constants()["thrust_n"] > 0
    np.testing.assert_array_equal(law.case_ids, np.arange(4))
    nav = law.calls[0]
    assert {f.name for f in dataclasses.fields(nav)} == {
        "obs", "state_nd", "t_s", "active", "episode_start", "sensors", "frame_of"}
    assert nav.obs.shape == (4, 5) and nav.state_nd.shape == (4, 5)
    np.testing.assert_array_equal(nav.t_s, np.zeros(4))
    assert nav.active.all() and nav.episode_start.all() and set(nav.sensors) == {"imu"}
    # the IMU at an episode's first decision: nothing flown yet (no errors in this env)
    np.testing.assert_array_equal(nav.sensors["imu"], 0.0)
    assert np.all(np.linalg.norm(law.calls[1].sensors["imu"], axis=1) > 1.0)  # braking
    assert not law.calls[1].episode_start.any()
    # the guidance frame, in SI: (downrange, up), the mass estimate and the height
    f = nav.frame
    assert f.v.shape == (4, 2) and f.free_axes == (0,)
    assert np.all((f.height_m > 10e3) & (f.height_m < 20e3))
    assert np.all((f.mass_kg > 500) & (f.mass_kg < 700))
    # the observation decodes to the navigation solution's quantities
    q = comp.observation_quantities(nav.obs)
    assert set(q) >= {"altitude_m", "radial_velocity_m_s", "propellant_kg", "time_s"}
    # later decisions: landers that ended are inactive, and their rows keep being passed
    assert any(not c.active.all() for c in law.calls[1:])


def test_a_privileged_law_is_given_the_truth_and_marked_in_tables():
    teacher = Teacher()
    fly(ENV_ID, teacher, 2, seed=3, max_steps=5_000)
    assert teacher.truths and teacher.truths[0].state_nd.shape == (2, 5)
    assert law_label(teacher) == "teacher" + PRIVILEGED_MARK
    assert law_label(ConstantAttitude([0.0])) == "constant attitude"
    res = rollout(ENV_ID, Teacher(), 2, seed=3, trace_cases=0)
    assert res.name.endswith(PRIVILEGED_MARK)
    # privilege is a protocol of its own: a teacher has no ``act`` to refuse
    assert not hasattr(teacher, "act") and not isinstance(teacher, GuidanceLaw)


def test_a_law_must_implement_act():
    class Nothing(GuidanceLaw):
        pass

    with pytest.raises(TypeError, match="abstract"):
        Nothing()


def test_non_finite_actions_are_refused_with_the_law_named():
    bad = CallableLaw(lambda nav: np.full((nav.n, 1), np.nan, np.float32), name="bad law")
    with pytest.raises(FloatingPointError, match="bad law"):
        fly(ENV_ID, bad, 2, seed=0)


def test_action_sequences_replay_per_case_and_hold_the_last_action():
    law = ActionSequenceLaw([np.array([[0.1], [0.2]]), np.array([[0.3]])])
    comp = FlightComputer.of(_env(), ENV_ID)
    law.reset(comp, np.arange(2))

    def nav(start):
        return Navigation(np.zeros((2, 5), np.float32), np.zeros((2, 5)), np.zeros(2),
                          np.ones(2, bool), np.asarray(start, bool))

    np.testing.assert_allclose(law.act(nav([1, 1])), [[0.1], [0.3]], rtol=0, atol=1e-7)
    np.testing.assert_allclose(law.act(nav([0, 0])), [[0.2], [0.3]], rtol=0, atol=1e-7)
    np.testing.assert_allclose(law.act(nav([0, 0])), [[0.2], [0.3]], rtol=0, atol=1e-7)
    # row 0 starts a new episode (an autoreset): its replay starts again, row 1's does not
    np.testing.assert_allclose(law.act(nav([1, 0])), [[0.1], [0.3]], rtol=0, atol=1e-7)


def _env():
    import gymnasium as gym

    import lunar_env  # noqa: F401

    return gym.make(ENV_ID).unwrapped


@pytest.mark.parametrize("env_id, n_angles", [("LunarSoftLanding-v0", 1),
                                              ("LunarPinpointLanding-v2", 2)])
def test_a_thrust_command_is_encoded_by_the_env_and_the_replays_fly_its_throttle(
        env_id, n_angles):
    # Bug fixed: the open-loop replays gave angle-only actions to an env with a throttle
    # channel, and a campaign on it stopped with "action has shape (10, 2)".
    import gymnasium as gym

    from guidance.laws.baselines import PinpointOpenLoopLaw, PlanarOpenLoopLaw

    env = gym.make(env_id, throttle_channel=True)
    computer = FlightComputer.of(env, env_id)
    assert computer.throttled and computer.n_axes == n_angles + 1
    up = np.zeros((3, n_angles + 1))
    up[:, -1] = 1.0  # straight up, half throttle
    a = computer.encode(ThrustCommand(up, np.full(3, 0.5)))
    assert a.shape == (3, n_angles + 1) and a.dtype == np.float32
    np.testing.assert_array_equal(a[:, -1], 0.0)
    full = computer.encode(ThrustCommand(up))  # no throttle given: full thrust
    np.testing.assert_array_equal(full[:, -1], 1.0)
    plain = FlightComputer.of(gym.make(env_id), env_id)
    assert not plain.throttled and plain.encode(ThrustCommand(up)).shape == (3, n_angles)
    failed = dataclasses.make_dataclass("FailedSolve", [("success", bool)])(False)
    law = (PlanarOpenLoopLaw if n_angles == 1 else PinpointOpenLoopLaw)([failed] * 3)
    law.reset(computer, np.arange(3))
    nav = Navigation(obs=np.zeros((3,) + env.observation_space.shape), state_nd=None,
                     t_s=np.zeros(3), active=np.ones(3, dtype=bool),
                     episode_start=np.ones(3, dtype=bool))
    act = law.act(nav)
    assert act.shape == (3, n_angles + 1) and env.action_space.contains(act[0])
    assert np.all(act[:, -1] == 1.0)


def test_the_docstring_law_lands_a_planar_lander_from_its_guidance_frame():
    """The contract's example: a law that reads only ``nav.frame`` and commands a thrust
    direction and throttle flies both env families through their encoders."""

    class VerticalBraking(GuidanceLaw):
        name = "vertical braking"

        def act(self, nav):
            f = nav.frame
            a = -f.v / 20.0 - f.g
            throttle = np.linalg.norm(a, axis=1) * f.mass_kg / self.computer.thrust_n
            return ThrustCommand(direction=a, throttle=throttle)

    for env_id in ("LunarSoftLanding-v0", "LunarPinpointLanding-v2"):
        out = fly(env_id, VerticalBraking(), 3, seed=0, env_kwargs={"throttle_channel": True})
        assert np.all(np.isfinite(out.fuel_used_kg)) and np.all(out.fuel_used_kg > 0)
