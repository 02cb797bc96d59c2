"""Env families: each consumer's registry answers for a scenario's family, and nothing else
branches on the family."""

from __future__ import annotations

import numpy as np
import pytest

from agents.features import FEATURE_FAMILIES
from agents.imitation.families import IMITATION_FAMILIES
from agents.rl.starts import START_FAMILIES
from guidance.evaluation.compare import baseline_laws
from guidance.evaluation.plots import PLOT_FAMILIES
from guidance.families import GUIDANCE_FAMILIES, guidance_family
from guidance.families.pinpoint import PinpointGuidance
from guidance.families.planar import PlanarGuidance
from guidance.law import GuidanceLaw
from guidance.laws.baselines import (
    BASELINE_FAMILIES,
    PinpointOpenLoopLaw,
    PlanarBaselines,
    PlanarOpenLoopLaw,
)
from guidance.laws.pontryagin_pinpoint import PinpointPontryaginExpert
from guidance.laws.pontryagin_planar import PlanarReplanningLaw
from lunar_env import get_scenario
from lunar_env.families import FamilyRegistry, family_name
from optimizers.optimum import OPTIMUM_FAMILIES, PerCaseOptimum

REGISTRIES = (GUIDANCE_FAMILIES, BASELINE_FAMILIES, OPTIMUM_FAMILIES, PLOT_FAMILIES,
              FEATURE_FAMILIES,
              START_FAMILIES, IMITATION_FAMILIES)


def test_each_scenario_and_env_has_exactly_its_family():
    import gymnasium as gym

    import lunar_env  # noqa: F401

    assert isinstance(guidance_family(get_scenario("zhu2007")), PlanarGuidance)
    assert isinstance(guidance_family(get_scenario("peng2012")), PinpointGuidance)
    for env_id, fam in (("LunarSoftLanding-v0", "planar"), ("LunarPinpointLanding-v2",
                                                              "pinpoint")):
        env = gym.make(env_id)
        assert family_name(env) == fam
        env.close()
    with pytest.raises(TypeError, match="names no env family"):
        family_name(object())


@pytest.mark.parametrize("registry", REGISTRIES, ids=lambda r: r.kind)
def test_every_consumer_registers_both_families_lazily(registry):
    assert registry.names()[:2] == ("planar", "pinpoint")
    assert registry.of(get_scenario("zhu2007")) is registry.get("planar")
    with pytest.raises(KeyError, match="registered: planar, pinpoint"):
        registry.get("throttled")


def test_a_registry_refuses_a_second_registration_and_builds_classes_once():
    reg = FamilyRegistry("test")

    class Thing:
        built = 0

        def __init__(self):
            Thing.built += 1

    reg.register("planar", Thing)
    with pytest.raises(ValueError, match="registered already"):
        reg.register("planar", Thing)
    assert reg.get("planar") is reg.get("planar") and Thing.built == 1
    reg.register("pinpoint", "lunar_env.families:FamilyRegistry.__init__", replace=True)
    with pytest.raises(ValueError, match="must be a non-empty string"):
        reg.register("", Thing)


def test_baseline_laws_follow_the_family_defaults_and_the_counts_asked():
    sc = get_scenario("zhu2007")
    opt = PerCaseOptimum(np.zeros(30), np.zeros(30), [None] * 30)
    rows = baseline_laws(sc, opt, 30)
    assert [type(law) for law, _ in rows] == [PlanarOpenLoopLaw, PlanarReplanningLaw]
    assert [n for _, n in rows] == [30, PlanarBaselines.default_expert_cases]
    assert [n for _, n in baseline_laws(sc, opt, 5)] == [5, 5]
    assert baseline_laws(sc, opt, 5, open_loop=False, n_expert_cases=0) == []
    pp = get_scenario("peng2012")
    rows = baseline_laws(pp, PerCaseOptimum(np.zeros(3), np.zeros(3), [None] * 3), 3)
    assert isinstance(rows[0][0], PinpointOpenLoopLaw)
    assert isinstance(rows[1][0], PinpointPontryaginExpert) and rows[1][1] == 3
    assert all(isinstance(law, GuidanceLaw) for law, _ in rows)


def test_start_noise_exists_only_where_the_family_defines_it():
    pp = get_scenario("peng2012")
    fam = START_FAMILIES.of(pp)
    sig = fam.start_noise_nd(pp, {"position_m": 500.0, "velocity_m_s": 5.0})
    s = pp.scaling()
    assert sig == pytest.approx((500.0 / s.length_m, 5.0 / s.velocity_m_s))
    y = np.tile(pp.state_nd(scaling=s), (4, 1))
    moved = fam.perturb_starts(y, sig, np.random.default_rng(0))
    assert np.all(moved[:, 6] == y[:, 6]) and not np.array_equal(moved[:, :6], y[:, :6])
    with pytest.raises(ValueError, match="velocity_m_s"):
        fam.start_noise_nd(pp, {"velocity_m_s": -1.0})
    with pytest.raises(ValueError, match="planar"):
        START_FAMILIES.of(get_scenario("zhu2007")).start_noise_nd(get_scenario("zhu2007"),
                                                                  {"position_m": 1.0})


def test_each_family_answers_its_features_and_shaping():
    from agents.rl.shaping import FAMILY_POTENTIALS

    for name in FEATURE_FAMILIES.names():
        fam = FEATURE_FAMILIES.get(name)
        lo, hi = fam.bounds(list(fam.widths))
        assert len(lo) == len(hi) == sum(fam.widths.values())
        assert all(a < b for a, b in zip(lo, hi, strict=True))
        assert len(FAMILY_POTENTIALS[name]) == 1
    assert FAMILY_POTENTIALS["planar"] != FAMILY_POTENTIALS["pinpoint"]


def test_touchdown_family_shares_the_pinpoint_frame_and_encodes_its_throttle_range():
    """v3 (family ``pinpoint_touchdown``): the pinpoint frame (height above the site on the
    surface), and thrust commands encoded with the throttle on the engine's [0.2, 1]."""
    import gymnasium as gym

    import lunar_env  # noqa: F401
    from guidance.families.touchdown import TouchdownGuidance
    from guidance.law import FlightComputer, ThrustCommand

    env = gym.make("LunarPinpointLanding-v3").unwrapped
    assert family_name(env) == "pinpoint_touchdown"
    assert isinstance(guidance_family(env), TouchdownGuidance)
    fc = FlightComputer.of(env, "LunarPinpointLanding-v3")
    assert fc.throttled and fc.target_radius_m == pytest.approx(env.scenario.body.radius_m)
    up = np.array([[0.0, 0.0, 1.0], [-1.0, 0.1, 0.2]])
    act = fc.encode(ThrustCommand(up, np.array([0.5, 0.05])))
    u = env.task.controls_from_actions(act)
    assert u[0, 0] == pytest.approx(np.pi / 2, abs=1e-6) and u[0, 2] == pytest.approx(0.5)
    assert u[1, 2] == pytest.approx(0.2)  # below the floor: the floor
    # the thrust direction the dynamics fly, (radial, along, cross) -> (along, cross, up)
    from lunar_env.dynamics import moon3d_thrust_terms

    e_r, e_t, e_n, _ = moon3d_thrust_terms(u[:, 0], u[:, 1], 1.0)
    e = np.stack([e_t, e_n, e_r], axis=1)
    np.testing.assert_allclose(e[1], up[1] / np.linalg.norm(up[1]), atol=1e-6)
    # the observation is this frame's target-relative state: the lander relative to the site
    env.reset(seed=0)
    for _ in range(20):
        env.step(np.array([0.2, 0.1, 0.3], np.float32))
    frame = fc.frame_of(env.state_nd[None])
    q = env.observation_quantities(env.observation_from_state(env.state_nd[None],
                                                              np.array([env.t_s])))
    np.testing.assert_allclose([q["along_m"][0], q["cross_m"][0], q["altitude_m"][0]],
                               -frame.r_to_target[0], rtol=2e-6)
    np.testing.assert_allclose([q["v_along_m_s"][0], q["v_cross_m_s"][0], q["v_up_m_s"][0]],
                               frame.v[0], rtol=2e-6)
    assert frame.height_m[0] == pytest.approx(q["altitude_m"][0], rel=2e-6)
