"""The touchdown family's baselines and plots (``LunarPinpointLanding-v3``): registered for the
family, the replay's step across a plan's end, the expert's settings, the plots drawn."""

import math

import numpy as np
import pytest

from guidance.evaluation.plots import PLOT_FAMILIES, plot_comparison
from guidance.evaluation.plots.touchdown import TouchdownPlots, optimum_altitude_track
from guidance.flight import PolicyResult
from guidance.laws.baselines import BASELINE_FAMILIES
from guidance.laws.touchdown_baselines import (
    TouchdownBaselines,
    TouchdownOpenLoopLaw,
    TouchdownReplanningLaw,
    plan_step_controls,
)
from guidance.registry import LawContext, build_law
from lunar_env import get_scenario
from optimizers.optimum import PerCaseOptimum
from optimizers.optimum.touchdown import TouchdownOptimum

SC = get_scenario("peng2012_touchdown")


def _vertical_plan(tf_s=10.0, throttle=1.0):
    """A one-arc plan thrusting straight up (orbital frame: radial first) for ``tf_s`` at
    ``throttle``, from the scenario's start (its states only feed the plots)."""
    n = 3
    s = SC.scaling()
    x0 = np.asarray(SC.state_nd(scaling=s), dtype=float)
    states = np.tile(x0, (n + 1, 1))
    states[:, :3] *= (1.0 - np.linspace(0.0, 0.001, n + 1))[:, None]
    return TouchdownOptimum(True, 1.0, tf_s, levels=np.array([throttle]),
                            durations_s=np.array([tf_s]), nodes=np.array([n]),
                            directions=np.tile([1.0, 0.0, 0.0], (n, 1)), states_nd=states)


def test_the_touchdown_family_has_its_baselines_and_plots():
    fam = BASELINE_FAMILIES.of(SC)
    assert isinstance(fam, TouchdownBaselines)
    assert isinstance(fam.expert_law(SC), TouchdownReplanningLaw)
    opt = PerCaseOptimum(np.zeros(2), np.zeros(2), [_vertical_plan(), _vertical_plan()])
    assert isinstance(fam.open_loop_law(opt), TouchdownOpenLoopLaw)
    assert isinstance(PLOT_FAMILIES.of(SC), TouchdownPlots)
    ctx = LawContext(env_id="LunarPinpointLanding-v3", env_kwargs={}, scenario=SC,
                     nominal_optimum=lambda: opt)
    assert isinstance(build_law("open-loop", ctx), TouchdownOpenLoopLaw)
    law = build_law("feedback:every=20,min_tgo=5", ctx)
    assert isinstance(law, TouchdownReplanningLaw)
    assert (law.every_s, law.min_tgo_s) == (20.0, 5.0)


def test_a_step_across_the_plans_end_averages_the_plan_and_the_after_plan_thrust():
    plan = _vertical_plan(tf_s=10.0, throttle=1.0)
    inside = plan_step_controls(plan, 2.0, 1.0, SC)
    np.testing.assert_allclose(inside, [math.pi / 2, inside[1], 1.0], atol=1e-12)
    # half the step at full thrust up, half at the minimum throttle up
    across = plan_step_controls(plan, 9.5, 1.0, SC)
    assert across[0] == pytest.approx(math.pi / 2)
    assert across[2] == pytest.approx(0.5 * 1.0 + 0.5 * SC.throttle_min)
    after = plan_step_controls(plan, 12.0, 1.0, SC)
    np.testing.assert_allclose(after, [math.pi / 2, math.pi, SC.throttle_min])


@pytest.mark.parametrize("kw, message", [({"every_s": 0.0}, r"every = 0\.0 s"),
                                         ({"every_s": float("nan")}, r"every = nan s"),
                                         ({"min_tgo_s": -1.0}, r"min_tgo = -1\.0 s")])
def test_the_expert_refuses_bad_settings_by_name(kw, message):
    with pytest.raises(ValueError, match=message):
        TouchdownReplanningLaw(SC, **kw)
    ctx = LawContext(env_id="LunarPinpointLanding-v3", env_kwargs={}, scenario=SC)
    with pytest.raises(ValueError, match="unknown option"):
        build_law("feedback:thrust_reserve=0.05", ctx)


def test_the_plots_draw_the_optimum_and_a_flight(tmp_path):
    plan = _vertical_plan()
    t, alt = optimum_altitude_track(plan, SC)
    assert t[0] == 0.0 and t[-1] == pytest.approx(plan.tf_s) and alt[-1] == 0.0
    assert np.all(np.diff(t) >= 0.0)
    s = SC.scaling()
    x0 = np.asarray(SC.state_nd(scaling=s), dtype=float)
    trace = {"t_s": np.arange(4.0), "state_nd": np.tile(x0, (4, 1)),
             "action": np.tile([0.0, 0.0, 1.0], (3, 1)).astype(np.float32)}
    res = PolicyResult(np.ones(1, bool), np.ones(1), np.ones(1), np.ones(1), np.ones(1), 3,
                       0.0, np.zeros(1), name="law", case_ids=np.arange(1), traces={0: trace})
    path = plot_comparison({"scenario": SC, "results": [res], "optimal_solutions": [plan]},
                           tmp_path / "cmp.png")
    assert path.exists() and path.stat().st_size > 0
    assert TouchdownPlots.labels[2] == "throttle"
