"""Env families (agents.experts): one object answers each family's questions."""

from __future__ import annotations

import numpy as np
import pytest

from agents.common.families import FAMILIES, family_of
from agents.common.law import GuidanceLaw
from agents.experts.family import PerCaseOptimum
from agents.experts.pinpoint.expert import PinpointPontryaginExpert
from agents.experts.pinpoint.family import PinpointFamily
from agents.experts.planar.expert import PlanarOpenLoopLaw, PlanarReplanningLaw
from agents.experts.planar.family import PlanarFamily
from lunar_env import get_scenario


def test_each_scenario_and_env_has_exactly_its_family():
    import gymnasium as gym

    import lunar_env  # noqa: F401

    assert isinstance(family_of(get_scenario("zhu2007")), PlanarFamily)
    assert isinstance(family_of(get_scenario("peng2012")), PinpointFamily)
    for env_id, fam in (("LunarSoftLanding-v0", "planar"), ("LunarPinpointLanding-v2",
                                                              "pinpoint")):
        env = gym.make(env_id)
        assert family_of(env).name == fam
        env.close()
    with pytest.raises(TypeError, match="registered families: " + ", ".join(FAMILIES)):
        family_of(object())


def test_baseline_laws_follow_the_family_defaults_and_the_counts_asked():
    sc = get_scenario("zhu2007")
    fam = family_of(sc)
    opt = PerCaseOptimum(np.zeros(30), np.zeros(30), [None] * 30)
    rows = fam.baseline_laws(sc, opt, 30)
    assert [type(law) for law, _ in rows] == [PlanarOpenLoopLaw, PlanarReplanningLaw]
    assert [n for _, n in rows] == [30, PlanarFamily.default_expert_cases]
    assert [n for _, n in fam.baseline_laws(sc, opt, 5)] == [5, 5]
    assert fam.baseline_laws(sc, opt, 5, open_loop=False, n_expert_cases=0) == []
    pp = get_scenario("peng2012")
    rows = family_of(pp).baseline_laws(pp, PerCaseOptimum(np.zeros(3), np.zeros(3), [None] * 3),
                                       3)
    assert isinstance(rows[1][0], PinpointPontryaginExpert) and rows[1][1] == 3
    assert all(isinstance(law, GuidanceLaw) for law, _ in rows)


def test_start_noise_exists_only_where_the_family_defines_it():
    pp = get_scenario("peng2012")
    fam = family_of(pp)
    sig = fam.start_noise_nd(pp, {"position_m": 500.0, "velocity_m_s": 5.0})
    s = pp.scaling()
    assert sig == pytest.approx((500.0 / s.length_m, 5.0 / s.velocity_m_s))
    y = np.tile(pp.state_nd(scaling=s), (4, 1))
    moved = fam.perturb_starts(y, sig, np.random.default_rng(0))
    assert np.all(moved[:, 6] == y[:, 6]) and not np.array_equal(moved[:, :6], y[:, :6])
    with pytest.raises(ValueError, match="velocity_m_s"):
        fam.start_noise_nd(pp, {"velocity_m_s": -1.0})
    with pytest.raises(ValueError, match="planar"):
        family_of(get_scenario("zhu2007")).start_noise_nd(get_scenario("zhu2007"),
                                                          {"position_m": 1.0})


def test_the_registry_is_lazy_string_keyed_and_each_family_answers_its_features():
    from agents.common.families import FAMILY_ENTRY_POINTS, family_named

    assert tuple(FAMILY_ENTRY_POINTS) == FAMILIES == ("planar", "pinpoint")
    assert family_named("planar") is family_of(get_scenario("zhu2007"))
    with pytest.raises(KeyError, match="registered families"):
        family_named("throttled")
    for name in FAMILIES:
        fam = family_named(name)
        widths = fam.feature_widths()
        lo, hi = fam.feature_bounds(list(widths))
        assert len(lo) == len(hi) == sum(widths.values())
        assert all(a < b for a, b in zip(lo, hi, strict=True))
        assert len(fam.shaping_potentials()) == 1
    assert family_named("planar").shaping_potentials() != family_named(
        "pinpoint").shaping_potentials()
