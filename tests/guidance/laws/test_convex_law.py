"""Convex re-planning law (guidance.laws.convex): built by name, options validated, flies the
soft-landing env to touchdown."""

from __future__ import annotations

import numpy as np
import pytest

from guidance.flight import fly
from guidance.laws.convex import ConvexReplanningLaw
from guidance.registry import LawContext, build_law, parse_law_spec
from lunar_env import get_scenario

pytest.importorskip("cvxpy")

PLANAR = "LunarSoftLanding-v0"


def _context(env_id: str = PLANAR, scenario: str = "zhu2007") -> LawContext:
    return LawContext(env_id, {}, get_scenario(scenario))


def test_spec_with_options_builds_the_law():
    law = build_law("convex:every=2,nodes=40,iters=3,engine=constant", _context())
    assert isinstance(law, ConvexReplanningLaw)
    assert law.every_s == 2.0 and law.solver.n_nodes == 40 and law.iters == 3
    assert law.name == "convex:every=2,nodes=40,iters=3,engine=constant"
    assert build_law("convex", _context()).name == "convex"
    assert parse_law_spec("convex:every=2").options == {"every": "2"}


@pytest.mark.parametrize("spec, name", [
    ("convex:nodes=1", "n_nodes"), ("convex:every=-1", "every"), ("convex:every=0", "every"),
    ("convex:iters=0", "iters"), ("convex:engine=ion", "engine"), ("convex:speed=3", "speed"),
    ("convex:nodes=abc", "nodes"), ("convex:some/path", "argument"),
])
def test_bad_options_raise_a_value_error_naming_them(spec, name):
    with pytest.raises(ValueError, match=name):
        build_law(spec, _context())


def test_throttled_engine_needs_the_throttle_channel():
    law = ConvexReplanningLaw(get_scenario("zhu2007"), engine="throttled")
    with pytest.raises(ValueError, match="throttle channel"):
        fly(PLANAR, law, 1, seed=0)


def test_flies_a_dispersed_soft_landing_to_touchdown():
    law = build_law("convex:every=60,nodes=20", _context())
    out = fly(PLANAR, law, 1, seed=7)
    assert out.is_success.all(), out.touchdown_speed_m_s
    # every 60 s, then at least three times over each remaining horizon near the end
    assert law.n_replans >= 12 and law.n_failed == 0
    assert len(law.replan_log) == law.n_replans and law.replan_log[0][-1]  # first plan flagged
    assert np.all(np.isfinite(out.fuel_used_kg))
    # every case re-planned from its own navigated start: fuel within a few % of the nominal
    nominal = law.nominal_plan().fuel_kg
    assert np.all(np.abs(out.fuel_used_kg - nominal) < 0.1 * nominal)
