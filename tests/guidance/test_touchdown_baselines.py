"""The touchdown family's optimiser baselines (guidance.laws.touchdown_open_loop): the replay of
the certified optimum, the refused expert, the evaluation plot and the normalised score's
anchors on ``LunarPinpointLanding-v3``."""

from __future__ import annotations

import numpy as np
import pytest

from guidance.evaluation.plots import PLOT_FAMILIES
from guidance.laws.baselines import BASELINE_FAMILIES
from guidance.laws.touchdown_open_loop import NO_EXPERT, TouchdownOpenLoopLaw, step_controls
from lunar_env import get_scenario

ENV_ID = "LunarPinpointLanding-v3"
SC = get_scenario("peng2012_touchdown")


@pytest.fixture(scope="module")
def nominal():
    """The certified optimum from the nominal start (cached on disk)."""
    from optimizers.optimum.touchdown import touchdown_ocp, touchdown_optima

    x0 = touchdown_ocp(SC).x0_nd[None]
    opt = touchdown_optima(SC, x0, progress=False)[0]
    assert opt.success
    return x0, opt


def test_step_controls_are_the_optimums_step_means(nominal):
    """All steps in one evaluation give what the optimum's own per-step mean gives, also for the
    steps that straddle a throttle switch (7 s and 31 s into the nominal flight); after
    touchdown the law is the minimum throttle straight up."""
    _, opt = nominal
    t0 = np.array([0.0, 6.5, 7.0, 30.4, 100.0, opt.tf_s - 1.0])
    got = step_controls(opt, t0, 1.0, SC)
    want = np.array([opt.mean_controls(t, 1.0, SC) for t in t0])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert got[1, 2] < 1.0 and got[0, 2] == pytest.approx(1.0)  # the switch averaged in
    after = step_controls(opt, [opt.tf_s, opt.tf_s + 5.0], 1.0, SC)
    np.testing.assert_allclose(after[:, [0, 2]], [[np.pi / 2, SC.throttle_min]] * 2, atol=1e-9)
    last = step_controls(opt, [opt.tf_s - 0.25], 1.0, SC)[0]  # a quarter of the step on the plan
    assert SC.throttle_min < last[2] < opt.mean_controls(opt.tf_s - 0.25, 1.0, SC)[2]


def test_open_loop_replay_lands_the_nominal_start(nominal):
    """The registered baseline flies the nominal optimum to a success at 0.25 s decisions and
    to a touchdown within metres at the env's 1 s (the hold's error), with the optimum's
    propellant."""
    from guidance.flight import fly

    x0, opt = nominal
    fam = BASELINE_FAMILIES.get("pinpoint_touchdown")
    for dt, success, miss_m in ((0.25, True, 1.0), (1.0, None, 5.0)):
        out = fly(ENV_ID, TouchdownOpenLoopLaw([opt]), 1, seed=0, env_kwargs={"dt_s": dt},
                  reset_options={"state_nd": x0})
        assert out.miss_distance_m[0] < miss_m
        assert abs(out.fuel_used_kg[0] - opt.fuel_kg) < 0.5
        if success is not None:
            assert bool(out.is_success[0]) is success
    assert fam.default_expert_cases == 0
    assert type(fam.open_loop_law(type("O", (), {"solutions": [opt]})())) is TouchdownOpenLoopLaw


def test_uncertified_case_brakes_and_the_expert_is_refused_with_its_reason():
    from guidance.registry import LawContext, build_law
    from optimizers.optimum.touchdown import TouchdownOptimum

    fam = BASELINE_FAMILIES.get("pinpoint_touchdown")
    with pytest.raises(ValueError, match="no closed-loop expert") as exc:
        fam.expert_law(SC)
    assert str(exc.value) == NO_EXPERT
    with pytest.raises(ValueError, match="no closed-loop expert"):
        build_law("feedback", LawContext(env_id=ENV_ID, env_kwargs={}, scenario=SC))
    from guidance.flight import fly

    failed = TouchdownOptimum(False, float("nan"), float("nan"), message="x")
    out = fly(ENV_ID, TouchdownOpenLoopLaw([failed]), 1, seed=0, record=[0],
              env_kwargs={"dt_s": 2.0})
    act = out.records[0]["action"]
    assert not out.is_success[0] and np.all(act == act[0])
    # full thrust against the motion: α = 0 on [-50°, 90°], β = 180° on [0°, 360°], throttle 1
    np.testing.assert_allclose(act[0], [2 * 50 / 140 - 1, 0.0, 1.0], atol=1e-6)


def test_score_anchors_and_plot_of_an_evaluation(tmp_path):
    """``compare`` on v3: the open-loop optimum is the score's 100 and the random law its 0 on
    every case; the table and the plot are written."""
    from guidance.evaluation.compare import compare
    from guidance.evaluation.report import write_report

    rep = compare(ENV_ID, [], n_states=2, seed=2026, env_kwargs={"dt_s": 2.0}, progress=False,
                  trace_cases=1)
    rows = {r["policy"]: r for r in rep["rows"]}
    assert set(rows) == {"optimum, open loop", "random"}
    assert rows["optimum, open loop"]["score"] == pytest.approx(100.0)
    assert rows["random"]["score"] == pytest.approx(0.0)
    ref = rep["score_references"]
    assert np.all(ref["optimum_return"] > ref["random_return"] + 10.0)
    paths = write_report(rep, tmp_path)
    assert paths["plot"].exists()
    assert PLOT_FAMILIES.names().count("pinpoint_touchdown") == 1
