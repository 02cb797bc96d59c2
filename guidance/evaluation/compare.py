"""Compare policies with the optimiser baselines over one seeded set of dispersed initial states.

::

    python -m agents.evaluate --model runs/ppo/LunarSoftLanding-v0_1          # + baselines
    python -m agents.evaluate --model a/model.zip --model b/ --n-states 200 --out results/cmp
    python -m agents.evaluate --no-open-loop --expert-states 0 --model runs/ppo/...

Every law flies the **same** initial states: the native vector env is reset with one seed,
and sub-env ``i`` draws its initial state with seed ``seed + i`` (the Gymnasium vector-env
convention the env follows), so case ``i`` is the same for every law and for any batch size
that contains it. For each case the per-case optimum is computed from the very initial state
the env drew, by the env family (:mod:`agents.experts`): Pontryagin indirect shooting for the
planar soft landing, [001]'s serial GPM + shooting for the pinpoint landing.

Laws (:mod:`guidance.law`)
-------------------------------
- the laws given (e.g. :class:`agents.laws.SB3Law`: a trained model with its
  ``VecNormalize`` statistics, deterministic actions, one batched forward pass);
- the family's baselines: the replay of each case's optimal control history (open loop), and
  the closed-loop expert, which re-solves the optimum from the navigation solution at every
  decision. It costs a solve per decision, so by default it flies only the family's
  ``default_expert_cases`` first cases (its fuel gap is measured on those cases' optima).
  Privileged laws (teachers that read the truth) are marked in the table.

Metrics (one row per policy)
----------------------------
- ``success_rate``: touchdown with the env's success criterion (``info["is_success"]``);
- ``touchdown_speed_m_s`` mean and 95th percentile over cases that touched down;
- ``miss_distance_m`` mean (pinpoint env only);
- ``fuel_kg`` mean over all cases; ``fuel_gap_pct``: mean over *successful* cases of
  100·(fuel − optimal fuel)/optimal fuel (decision: a crash can use less fuel than the optimum,
  so averaging over failures would reward them; the all-case gap is in the JSON too);
- ``score``: the env's benchmark score (:mod:`guidance.evaluation.score`), the mean over cases
  of 100·(return − random)/(optimum − random), where "random" is the return of a
  uniform-random action law flown on the same cases (the ``random`` row) and "optimum" that of
  the replay of the case's optimum (the open-loop row; flown for the reference even with
  ``open_loop=False``); 0 is random, 100 the per-case optimum; ``return_mean`` is the mean
  episode return (the env's rewards, unshaped);
- ``us_per_decision``: wall time of the policy's action computation divided by the number of
  decisions of landers still flying (batched policies amortise one forward pass over the
  batch; the expert's time is one re-plan per decision).

Outputs: a Markdown table (printed and ``comparison.md``), ``comparison.json`` and
``trajectories.png`` (trajectory and thrust angle of each policy beside the optimum for a few
cases) in the output directory.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from guidance.evaluation.score import RandomLaw, normalised_score
from guidance.flight import PolicyResult, initial_states, rollout
from guidance.law import Law, law_label
from guidance.laws.baselines import BASELINE_FAMILIES
from optimizers.optimum import optimum_family

__all__ = ["compare", "baseline_laws", "DEFAULT_ENV_ID", "DEFAULT_N_STATES", "DEFAULT_SEED"]

DEFAULT_ENV_ID = "LunarSoftLanding-v0"
DEFAULT_N_STATES = 1000
DEFAULT_SEED = 2026


# ----------------------------------------------------------------------------- comparison


def _summary(res: PolicyResult, opt_fuel: np.ndarray | None,
             opt_tf: np.ndarray | None = None, random_return: np.ndarray | None = None,
             optimum_return: np.ndarray | None = None) -> dict[str, Any]:
    td = np.isfinite(res.touchdown_speed_m_s)
    row: dict[str, Any] = {
        "policy": res.name,
        "n_cases": int(len(res.case_ids)),
        "success_rate": float(np.mean(res.is_success)),
        "touchdown_rate": float(np.mean(td)),
        "touchdown_speed_mean_m_s": float(np.mean(res.touchdown_speed_m_s[td])) if td.any()
        else float("nan"),
        "touchdown_speed_p95_m_s": float(np.percentile(res.touchdown_speed_m_s[td], 95))
        if td.any() else float("nan"),
        "miss_distance_mean_m": float(np.nanmean(res.miss_distance_m))
        if np.isfinite(res.miss_distance_m).any() else float("nan"),
        "fuel_mean_kg": float(np.nanmean(res.fuel_used_kg)),
        "us_per_decision": float(res.us_per_decision),
        "n_decisions": int(res.n_decisions),
        "policy_wall_s": float(res.policy_wall_s),
    }
    gap_s = gap_all = float("nan")
    n_gap = 0
    if opt_fuel is not None:
        opt = opt_fuel[res.case_ids]
        ok = np.isfinite(opt) & np.isfinite(res.fuel_used_kg)
        gap = 100.0 * (res.fuel_used_kg - opt) / opt
        if ok.any():
            gap_all = float(np.mean(gap[ok]))
        oks = ok & res.is_success
        n_gap = int(oks.sum())
        if oks.any():
            gap_s = float(np.mean(gap[oks]))
        row["optimal_fuel_mean_kg"] = float(np.nanmean(opt))
    row["fuel_gap_pct"] = gap_s
    # final-time gap: mean over successful cases of 100·(episode time − optimal tf)/optimal tf
    row["final_time_gap_pct"] = float("nan")
    if opt_tf is not None:
        tf = opt_tf[res.case_ids]
        okt = np.isfinite(tf) & np.isfinite(res.episode_time_s) & res.is_success
        if okt.any():
            row["final_time_gap_pct"] = float(np.mean(
                100.0 * (res.episode_time_s[okt] - tf[okt]) / tf[okt]))
    row["fuel_gap_pct_all_cases"] = gap_all
    row["n_cases_in_gap"] = n_gap
    row["return_mean"] = float(np.mean(res.episode_return))
    row["score"] = float("nan")
    row["n_cases_in_score"] = 0
    if random_return is not None and optimum_return is not None:
        sc = normalised_score(res.episode_return, random_return[res.case_ids],
                              optimum_return[res.case_ids])
        row["score"] = sc.mean
        row["n_cases_in_score"] = sc.n_cases
    return row


def baseline_laws(scenario, optimum, n_states: int, *, open_loop: bool = True,
                  n_expert_cases: int | None = None) -> list[tuple[Law, int]]:
    """The optimiser baselines of an evaluation: the open-loop optimum on every case and the
    family's closed-loop expert on the first ``n_expert_cases`` (None: the family's default;
    0: none)."""
    family = BASELINE_FAMILIES.of(scenario)
    rows: list[tuple[Law, int]] = []
    if open_loop:
        rows.append((family.open_loop_law(optimum), n_states))
    n_exp = family.default_expert_cases if n_expert_cases is None else n_expert_cases
    n_exp = n_states if n_exp is None else min(int(n_exp), n_states)
    if n_exp > 0:
        rows.append((family.expert_law(scenario), n_exp))
    return rows


def compare(env_id: str, laws: list[Law], n_states: int = DEFAULT_N_STATES,
            seed: int = DEFAULT_SEED, env_kwargs: dict[str, Any] | None = None,
            open_loop: bool = True, n_expert_states: int | None = None,
            trace_cases: int = 3, progress: bool = True,
            optimum_workers: int = 1, optimum_executor=None) -> dict[str, Any]:
    """Fly ``laws`` and the env family's optimiser baselines over one case set; return the
    report dict.

    ``n_expert_states``: cases flown by the family's closed-loop expert (None: the family's
    ``default_expert_cases``; 0: none). ``open_loop``: also fly the replay of each case's
    optimum. ``optimum_executor`` (:mod:`optimizers.common.executor`, e.g. Ray) runs the
    per-case optima (default: this process, or ``optimum_workers`` processes where the family
    uses them).

    Keys: ``env_id``, ``seed``, ``n_states``, ``rows`` (one summary per law, see the module
    docstring), ``optimum`` (per-case optimal fuel summary and solver wall time), ``results``
    (the :class:`PolicyResult` objects, not JSON-serialised), ``optimal_solutions``,
    ``family`` (its name).
    """
    import gymnasium as gym

    import lunar_env  # noqa: F401

    states = initial_states(env_id, n_states, seed, env_kwargs)
    env = gym.make(env_id, **(env_kwargs or {}))
    scenario = env.unwrapped.scenario
    env.close()
    optimum = optimum_family(scenario).per_case_optimum(
        scenario, states, progress=progress, workers=optimum_workers,
        executor=optimum_executor)
    flights = [(law, n_states) for law in laws]
    baselines = baseline_laws(scenario, optimum, n_states, open_loop=open_loop,
                              n_expert_cases=n_expert_states)
    flights += baselines
    random_law = RandomLaw()
    flights.append((random_law, n_states))
    runs: list[PolicyResult] = []
    for law, n in flights:
        if progress:
            print(f"Evaluating {law_label(law)} on {n} cases...", flush=True)
        runs.append(rollout(env_id, law, n, seed, env_kwargs,
                            trace_cases=0 if law is random_law else trace_cases))
    # the score's references: the random law's and the optimum replay's returns on every case
    random_return = runs[-1].episode_return
    if open_loop:
        optimum_return = runs[len(laws)].episode_return
    else:
        optimum_return = rollout(env_id, BASELINE_FAMILIES.of(scenario).open_loop_law(optimum),
                                 n_states, seed, env_kwargs, trace_cases=0).episode_return
    optimum_return = np.where(np.isfinite(optimum.fuel_kg), optimum_return, np.nan)
    rows = [_summary(r, optimum.fuel_kg, optimum.tf_s, random_return, optimum_return)
            for r in runs]
    return {"env_id": env_id, "seed": seed, "n_states": n_states,
            "env_kwargs": dict(env_kwargs or {}), "rows": rows, "optimum": optimum.info,
            "results": runs, "optimal_solutions": optimum.solutions,
            "score_references": {"random_return": random_return,
                                 "optimum_return": optimum_return},
            "initial_states_nd": states, "scenario": scenario, "family": scenario.family}
