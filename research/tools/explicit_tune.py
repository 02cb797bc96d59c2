"""Tune the augmented Apollo law's gain k_r and t_go margin: Optuna on the executor.

::

    python -m research.tools.explicit_tune --quick                       # planar, 8 trials
    python -m research.tools.explicit_tune --env LunarSoftLanding-v0 --trials 24 --cases 300
    python -m research.tools.explicit_tune --env LunarPinpointLanding-v2 \\
        --env-kwargs '{"throttle_channel": true}' --cases 100 --trials 12

The search space is k_r ∈ [6, 16] and the t_go margin μ ∈ [−0.05, 0.10] (t_go = (1 + μ)·t_rule,
:mod:`guidance.laws.apollo`). Each trial flies ``cases`` dispersed cases of a *tuning*
seed (default 7, not the evaluation's 2026, so that the tuned law is judged on cases it never
saw) and scores

    score = 100 · (failure rate) · 10 + mean fuel gap (%) over the successful cases,

to be minimised: one failure per hundred cases weighs as much as ten points of fuel gap, so
the search first lands every case, then saves fuel. The fuel gap is to each case's optimum
(the env family's ``per_case_optimum``, solved once for the tuning cases).

Trials run as tasks of :mod:`optimizers.common.executor` (``--workers`` local processes, or a
Ray cluster with ``--address``); the study asks ``workers`` trials at a time (Optuna's ask/tell;
TPE sampler, seeded) and tells each result as it arrives.
"""

from __future__ import annotations

import argparse
import json
import math
from typing import Any

import numpy as np

__all__ = ["trial_score", "tune", "main", "KR_RANGE", "MARGIN_RANGE", "FAILURE_WEIGHT"]

#: search interval of the gain k_r
KR_RANGE = (6.0, 16.0)
#: search interval of the t_go margin μ
MARGIN_RANGE = (-0.05, 0.10)
#: points of score per percent of failed cases (a failure costs 10 % of fuel gap)
FAILURE_WEIGHT = 10.0


def trial_score(env_id: str, env_kwargs: dict[str, Any] | None, spec: str, n: int, seed: int,
                optimal_fuel_kg: list[float]) -> dict[str, float]:
    """Fly the law ``spec`` on cases 0..n−1 of ``seed`` (an executor task: module level,
    picklable arguments) and score it (module docstring).

    Returns
    -------
    dict
        ``score``, ``success_rate``, ``gap_mean_pct`` (NaN when nothing landed), ``wall_s``.
    """
    import time

    import gymnasium as gym

    import lunar_env  # noqa: F401
    from guidance.flight import fly
    from guidance.registry import LawContext, build_law

    env = gym.make(env_id, **(env_kwargs or {}))
    scenario = env.unwrapped.scenario
    env.close()
    law = build_law(spec, LawContext(env_id, dict(env_kwargs or {}), scenario))
    t0 = time.perf_counter()
    out = fly(env_id, law, n, seed=seed, env_kwargs=env_kwargs)
    opt = np.asarray(optimal_fuel_kg, dtype=float)
    gap = 100.0 * (out.fuel_used_kg - opt) / opt
    ok = out.is_success & np.isfinite(gap)
    gap_mean = float(np.mean(gap[ok])) if ok.any() else math.nan
    fail_pct = 100.0 * (1.0 - float(np.mean(out.is_success)))
    # nothing landed: the worst score plus the gap bound, so that the sampler still sees order
    score = FAILURE_WEIGHT * fail_pct + (gap_mean if ok.any() else 100.0)
    return {"score": score, "success_rate": float(np.mean(out.is_success)),
            "gap_mean_pct": gap_mean, "wall_s": time.perf_counter() - t0}


def _spec(base: str, k_r: float, margin: float) -> str:
    sep = "," if ":" in base else ":"  # options join the base's own options, if any
    return f"{base}{sep}kr={k_r:.3f},tgo_margin={margin:.4f}"


def tune(env_id: str = "LunarSoftLanding-v0", env_kwargs: dict[str, Any] | None = None,
         n_trials: int = 24, n_cases: int = 300, seed: int = 7, sampler_seed: int = 0,
         workers: int = 1, address: str | None = None, base: str = "apollo",
         progress: bool = True) -> dict[str, Any]:
    """Run the search; return the best parameters, the textbook settings' score on the same
    cases and every trial.

    Parameters
    ----------
    env_id, env_kwargs
        The env (``throttle_channel`` selects the engine).
    n_trials : int
        Trials (the first one is the textbook Apollo, k_r = 12, μ = 0; the second ZEM/ZEV).
    n_cases : int
        Dispersed cases per trial.
    seed : int
        Seed of the tuning cases.
    sampler_seed : int
        Seed of Optuna's TPE sampler.
    workers, address
        Executor (:func:`optimizers.common.executor.get_executor`).
    base : str
        Law spec the parameters are added to (``apollo``, or with fixed options such as
        ``apollo:tgo=rocket,aim=5``; the gain is tuned, so ``zem-zev`` is the same family).
    """
    import gymnasium as gym
    import optuna

    import lunar_env  # noqa: F401
    from guidance.flight import initial_states
    from optimizers.common.executor import Task, TaskKey, get_executor
    from optimizers.optimum import optimum_family

    # by its module's name: under ``python -m`` this module is __main__, which workers cannot
    # import
    from research.tools.explicit_tune import trial_score as task_fn

    if n_trials < 2 or n_cases < 1:
        raise ValueError(f"n_trials = {n_trials!r} must be >= 2 and n_cases = {n_cases!r} "
                         ">= 1")
    env = gym.make(env_id, **(env_kwargs or {}))
    scenario = env.unwrapped.scenario
    env.close()
    states = initial_states(env_id, n_cases, seed, env_kwargs)
    optimum = optimum_family(scenario).per_case_optimum(scenario, states, progress=progress)
    opt_fuel = [float(x) for x in optimum.fuel_kg]
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(direction="minimize",
                                sampler=optuna.samplers.TPESampler(seed=sampler_seed,
                                                                   n_startup_trials=6))
    # the textbook laws first: the search starts from (and is compared with) them
    study.enqueue_trial({"kr": 12.0, "tgo_margin": 0.0})
    study.enqueue_trial({"kr": 6.0, "tgo_margin": 0.0})
    trials: list[dict[str, Any]] = []
    with get_executor(address, workers) as ex:
        done = 0
        while done < n_trials:
            batch = [study.ask() for _ in range(min(max(workers, 1), n_trials - done))]
            tasks = []
            for tr in batch:
                k_r = tr.suggest_float("kr", *KR_RANGE)
                margin = tr.suggest_float("tgo_margin", *MARGIN_RANGE)
                spec = _spec(base, k_r, margin)
                tasks.append(Task(TaskKey(f"tune-{env_id}", seed, tr.number), task_fn,
                                  (env_id, env_kwargs, spec, n_cases, seed, opt_fuel)))
            by_number = {tr.number: tr for tr in batch}
            for task, res in ex.imap_unordered(tasks):
                tr = by_number[task.key.index]
                study.tell(tr, res["score"])
                row = {"trial": tr.number, **tr.params, **res}
                trials.append(row)
                if progress:
                    print(f"trial {tr.number}: k_r={tr.params['kr']:.3f} "
                          f"μ={tr.params['tgo_margin']:+.4f} success "
                          f"{100 * res['success_rate']:.1f} % gap {res['gap_mean_pct']:+.3f} % "
                          f"score {res['score']:.3f} ({res['wall_s']:.0f} s)", flush=True)
            done += len(batch)
    best = study.best_trial
    textbook = next(t for t in trials if t["trial"] == 0)
    return {"env_id": env_id, "env_kwargs": dict(env_kwargs or {}), "n_cases": n_cases,
            "seed": seed, "best": {"kr": best.params["kr"],
                                   "tgo_margin": best.params["tgo_margin"],
                                   "score": best.value,
                                   "spec": _spec(base, best.params["kr"],
                                                 best.params["tgo_margin"])},
            "textbook": textbook, "trials": sorted(trials, key=lambda t: t["trial"])}


def main(argv: list[str] | None = None) -> int:
    """``python -m research.tools.explicit_tune`` (see the module docstring)."""
    p = argparse.ArgumentParser(prog="python -m research.tools.explicit_tune",
                                description=__doc__.split("\n")[0])
    p.add_argument("--env", default="LunarSoftLanding-v0")
    p.add_argument("--env-kwargs", default=None, help="JSON dict of env arguments")
    p.add_argument("--trials", type=int, default=24)
    p.add_argument("--cases", type=int, default=300)
    p.add_argument("--seed", type=int, default=7, help="seed of the tuning cases")
    p.add_argument("--sampler-seed", type=int, default=0)
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--address", default=None, help="Ray cluster (default: local processes)")
    p.add_argument("--base", default="apollo",
                   help="law spec the tuned kr and tgo_margin are added to, e.g. "
                        "'apollo:tgo=rocket,aim=5' (default apollo)")
    p.add_argument("--quick", action="store_true", help="8 trials of 40 cases (a smoke run)")
    p.add_argument("--json", default=None, help="write the result to this JSON file")
    args = p.parse_args(argv)
    kw = json.loads(args.env_kwargs) if args.env_kwargs else None
    if kw is not None and not isinstance(kw, dict):
        p.error(f"--env-kwargs {args.env_kwargs!r} must be a JSON object")
    trials, cases = (8, 40) if args.quick else (args.trials, args.cases)
    res = tune(args.env, kw, trials, cases, args.seed, args.sampler_seed, args.workers,
               args.address, base=args.base)
    b, t = res["best"], res["textbook"]
    print(f"textbook ({args.base}, k_r=12, μ=0): score {t['score']:.3f}, success "
          f"{100 * t['success_rate']:.1f} %, gap {t['gap_mean_pct']:+.3f} %")
    print(f"tuned    {b['spec']}: score {b['score']:.3f}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(res, fh, indent=1, default=float)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
