"""An evaluation of paper 003's lander at a chosen thrust level solves the per-case optimum at that
thrust."""

from __future__ import annotations

ENV_ID = "LunarSoftLanding-v0"


def test_evaluate_compares_with_the_per_case_optimum_at_that_thrust():
    from guidance.evaluation.compare import compare

    rep = compare(ENV_ID, [], n_states=1, n_expert_states=0, progress=False,
                  env_kwargs={"scenario": "wang2003", "thrust_n": 2929.0})
    assert rep["optimum"]["converged"] == 1
    # near the nominal case's optimum over T (223.52 kg), within the dispersion's reach
    assert 200.0 < rep["optimum"]["fuel_mean_kg"] < 245.0
    replay = [r for r in rep["rows"] if r["policy"] == "Pontryagin open loop"][0]
    assert replay["success_rate"] == 1.0
