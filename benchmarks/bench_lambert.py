"""Lambert solves per second against pykep; the [004] EA against pygmo and scipy.

``python benchmarks/bench_lambert.py [--quick] [--json FILE] [--problems N] [--seeds N]``

Part 1 — Lambert throughput, on the kep3 benchmark protocol (esa/kep3
``benchmark/lambert_problem_benchmark.cpp``): r1, r2 uniform in [−2, 2]³, tof in [2, 40],
μ in [0.9, 1.1], random direction; once with single-revolution solutions only and once with up
to 20 revolutions. Ours: :func:`lunar_env.lambert.solve_lambert` (dense output, padded to the
largest N of the batch) and :func:`~lunar_env.lambert.solve_lambert_flat` (one row per
solution, as pykep's lists), all problems in one batched call (best of 5; the serial and the
threaded kernel). pykep: ``pykep.lambert_problem`` called
from Python, one object per problem as a Python user writes it (best of 5, in a child process:
see lunar_env._pykep). Same problems, same run. Reported: problems/s and solutions/s, the
ratio per problem, the largest relative difference of v1 and v2 to pykep, and the failures
(non-converged solutions, solution sets that differ, or |Δv|/|v| > 1e-8).

Part 2 — optimisers on [004]'s eight problems (both tables) at an equal budget of objective
evaluations (a full EA run: 50 + 80·150 = 12 050): the EA (paper settings, with the stop rule
off so that it spends the budget, and as printed), pygmo's sade and cmaes (population 50),
and scipy's bounded scalar minimiser (Brent on [T_min, T_max], deterministic, one run; it stops
on its own tolerance). sade and cmaes stop on pygmo's default ftol = xtol = 1e-6 when their
population has converged (so the budget is a ceiling; ``--spend-budget`` sets both to 0). A run
*reaches the optimum* when its J is within 1e-3 m/s of the certified global minimum
(:func:`optimizers.problems.two_impulse.certify_global_minimum`).

The machine may be shared: times are as measured, ratios are taken in the same run.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

from lunar_env._pykep import pykep_available, pykep_lambert
from lunar_env.lambert import solve_lambert, solve_lambert_flat
from optimizers.evolutionary.ea import EA
from optimizers.problems.two_impulse import TwoImpulseProblem, certify_global_minimum
from optimizers.reproduce.wang2001 import PUBLISHED


def kep3_protocol(n: int, seed: int = 122012203):
    rng = np.random.default_rng(seed)
    return (rng.uniform(-2, 2, (n, 3)), rng.uniform(-2, 2, (n, 3)), rng.uniform(2, 40, n),
            rng.uniform(0.9, 1.1, n), rng.integers(0, 2, n).astype(bool))


def _best_time(f, repeat=5):
    best = np.inf
    out = None
    for _ in range(repeat):
        t = time.perf_counter()
        out = f()
        best = min(best, time.perf_counter() - t)
    return best, out


def bench_lambert(n: int, max_revs: int) -> dict:
    r1, r2, tof, mu, cw = kep3_protocol(n)
    solve_lambert(r1[:64], r2[:64], tof[:64], mu[:64], prograde=~cw[:64], max_revs=max_revs,
                  parallel=False)
    solve_lambert(r1[:64], r2[:64], tof[:64], mu[:64], prograde=~cw[:64], max_revs=max_revs,
                  parallel=True)  # compile / load both kernels outside the timing
    t_serial, ours = _best_time(lambda: solve_lambert(r1, r2, tof, mu, prograde=~cw,
                                                      max_revs=max_revs, parallel=False))
    t_par, _ = _best_time(lambda: solve_lambert(r1, r2, tof, mu, prograde=~cw,
                                                max_revs=max_revs, parallel=True))
    t_auto, _ = _best_time(lambda: solve_lambert(r1, r2, tof, mu, prograde=~cw,
                                                 max_revs=max_revs))
    solve_lambert_flat(r1[:64], r2[:64], tof[:64], mu[:64], prograde=~cw[:64],
                       max_revs=max_revs)
    t_flat, flat = _best_time(lambda: solve_lambert_flat(r1, r2, tof, mu, prograde=~cw,
                                                         max_revs=max_revs))
    n_sol = int(ours.valid.sum())
    res = {"n_problems": n, "max_revs": max_revs, "n_solutions": n_sol,
           "ours_serial_s": t_serial, "ours_threaded_s": t_par, "ours_default_s": t_auto,
           "ours_flat_s": t_flat, "flat_equals_dense": bool(
               np.array_equal(flat.v1_m_s, ours.v1_m_s[ours.valid])),
           "ours_problems_per_s": n / t_auto, "ours_solutions_per_s": n_sol / t_auto,
           "ours_failed": int(ours.failed.sum())}
    ok, why = pykep_available()
    if not ok:
        res["pykep"] = f"unavailable: {why}"
        return res
    ref = pykep_lambert(r1, r2, tof, mu, cw, max_revs, repeat=5)
    k = ours.valid.shape[1]
    ref_valid = ~np.isnan(ref["v1"][..., 0])
    set_mismatch = int(np.sum(ours.valid != ref_valid[:, :k]) + np.sum(ref_valid[:, k:]))
    both = ours.valid & ref_valid[:, :k]
    rel = [np.linalg.norm(m - t[:, :k], axis=-1) / np.linalg.norm(t[:, :k], axis=-1)
           for m, t in ((ours.v1_m_s, ref["v1"]), (ours.v2_m_s, ref["v2"]))]
    rel_max = float(max(r[both].max() for r in rel)) if both.any() else float("nan")
    n_bad = int(sum((r[both] > 1e-8).sum() for r in rel))
    res.update({
        "pykep_version": ref["version"], "pykep_s": ref["wall_s"],
        "pykep_problems_per_s": n / ref["wall_s"],
        "pykep_solutions_per_s": int(ref_valid.sum()) / ref["wall_s"],
        "ratio_per_problem_default": ref["wall_s"] / t_auto,
        "ratio_per_problem_serial": ref["wall_s"] / t_serial,
        "ratio_per_problem_threaded": ref["wall_s"] / t_par,
        "ratio_per_problem_flat": ref["wall_s"] / t_flat,
        "max_relative_difference": rel_max, "solution_set_mismatches": set_mismatch,
        "differences_above_1e-8": n_bad,
        "failures": res["ours_failed"] + set_mismatch + n_bad})
    return res


def _pygmo_run(name: str, problem, budget: int, seed: int, n_pop: int = 50,
               spend_budget: bool = False):
    import pygmo as pg

    gens = max(1, budget // n_pop - 1)
    # pygmo's default ftol = xtol = 1e-6 stop a converged population early; 0 spends the budget
    tol = 0.0 if spend_budget else 1e-6
    algo = (pg.sade(gen=gens, ftol=tol, xtol=tol, seed=seed) if name == "sade" else
            pg.cmaes(gen=gens, ftol=tol, xtol=tol, seed=seed, force_bounds=True))
    t = time.perf_counter()
    pop = pg.population(problem.to_pygmo(), size=n_pop, seed=seed)
    pop = pg.algorithm(algo).evolve(pop)
    return float(pop.champion_f[0]), float(pop.champion_x[0]), time.perf_counter() - t, \
        int(pop.problem.get_fevals())


def bench_optimisers(n_seeds: int, n_generations: int, n_scan: int,
                     spend_budget: bool = False) -> dict:
    from scipy.optimize import minimize_scalar

    budget = 50 + n_generations * 150
    rows = []
    for mode in ("transfer", "interception"):
        for pub in PUBLISHED[mode]:
            p = TwoImpulseProblem(pub["k"], mode)
            best = certify_global_minimum(p, n_scan=n_scan)["cost_m_s"]
            row = {"mode": mode, "k": pub["k"], "certified_cost": best, "algorithms": {}}

            def record(name, costs, walls, fevals, row=row, best=best):
                c = np.asarray(costs)
                row["algorithms"][name] = {
                    "cost": c.tolist(), "reached": int(np.sum(c - best <= 1e-3)),
                    "runs": len(c), "median_gap": float(np.median(c - best)),
                    "wall_s_mean": float(np.mean(walls)), "n_fevals_mean": float(np.mean(fevals))}

            for name, kw in (("EA (stop rule off)", dict(n_generations=n_generations,
                                                          stall_generations=n_generations + 1)),
                             ("EA as printed", dict(n_generations=n_generations))):
                rs = [EA(**kw).solve(p, seed=s) for s in range(n_seeds)]
                record(name, [r.fun for r in rs], [r.wall_s for r in rs],
                       [r.n_fevals for r in rs])
            for name in ("sade", "cmaes"):
                out = [_pygmo_run(name, p, budget, s, spend_budget=spend_budget)
                       for s in range(n_seeds)]
                record(f"pygmo {name}", [o[0] for o in out], [o[2] for o in out],
                       [o[3] for o in out])
            lo, hi = p.time_bounds_s
            n0 = p.n_fevals
            t = time.perf_counter()
            r = minimize_scalar(lambda x, p=p: p.fitness([x])[0], bounds=(lo, hi),
                                method="bounded", options={"maxiter": budget, "xatol": 1e-6})
            record("scipy minimize_scalar (bounded)", [float(r.fun)],
                   [time.perf_counter() - t], [p.n_fevals - n0])
            rows.append(row)
            print(f"  {mode:12s} K={pub['k']:<7g} certified {best:.4f}: " + "; ".join(
                f"{k} {v['reached']}/{v['runs']}" for k, v in row["algorithms"].items()),
                flush=True)
    return {"budget": budget, "n_seeds": n_seeds, "rows": rows}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="5 000 problems, 2 seeds, 20 EA generations (budget 3 050)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--problems", type=int, default=None, help="Lambert problems (50 000)")
    ap.add_argument("--seeds", type=int, default=None, help="runs per optimiser and row (10)")
    ap.add_argument("--part", choices=("all", "lambert", "optimisers"), default="all")
    ap.add_argument("--spend-budget", action="store_true",
                    help="sade and cmaes with ftol = xtol = 0 (slow: pygmo evaluates one by one)")
    args = ap.parse_args(argv)
    n = args.problems or (5_000 if args.quick else 50_000)
    seeds = args.seeds or (2 if args.quick else 10)
    gens = 20 if args.quick else 80
    out = {"lambert": [], "optimisers": None}
    print(f"Part 1: Lambert, kep3 protocol, {n} problems")
    for mr in ((0, 20) if args.part != "optimisers" else ()):
        r = bench_lambert(n, mr)
        out["lambert"].append(r)
        if isinstance(r.get("pykep"), str):
            print(f"  max_revs {mr}: ours {r['ours_problems_per_s']:.3g} problems/s; pykep "
                  f"{r['pykep']}")
            continue
        print(f"  max_revs {mr:2d}: {r['n_solutions']} solutions; pykep "
              f"{r['pykep_problems_per_s']:.3g} problems/s ({r['pykep_s']:.4f} s); ours dense "
              f"{r['ours_default_s']:.4f} s (×{r['ratio_per_problem_default']:.1f} per problem; "
              f"serial ×{r['ratio_per_problem_serial']:.1f}, threaded "
              f"×{r['ratio_per_problem_threaded']:.1f}), flat {r['ours_flat_s']:.4f} s "
              f"(×{r['ratio_per_problem_flat']:.1f}); max |Δv|/|v| "
              f"{r['max_relative_difference']:.1e}; failures {r['failures']}")
    if args.part == "lambert":
        return _write(args, out)
    print(f"Part 2: optimisers on [004], budget {50 + gens * 150} evaluations, {seeds} seeds")
    out["optimisers"] = bench_optimisers(seeds, gens, 5_001 if args.quick else 200_001,
                                         spend_budget=args.spend_budget)
    names = list(out["optimisers"]["rows"][0]["algorithms"])
    print(f"\n{'row':22s} " + " ".join(f"{nm[:22]:>24s}" for nm in names))
    for row in out["optimisers"]["rows"]:
        cells = [f"{v['reached']}/{v['runs']} gap {v['median_gap']:.3g}"
                 for v in row["algorithms"].values()]
        print(f"{row['mode'][:5]} K={row['k']:<14g} " + " ".join(f"{c:>24s}" for c in cells))
    walls = {nm: np.mean([r["algorithms"][nm]["wall_s_mean"] for r in out["optimisers"]["rows"]])
             for nm in names}
    print("mean wall time per run: " + ", ".join(f"{k} {v:.3f} s" for k, v in walls.items()))
    out["optimisers"]["mean_wall_s"] = walls
    return _write(args, out)


def _write(args, out) -> int:
    if args.json:
        d = os.path.dirname(os.path.abspath(args.json))
        os.makedirs(d, exist_ok=True)
        with open(args.json + ".tmp", "w") as fh:
            json.dump(out, fh, indent=2, default=float)
        os.replace(args.json + ".tmp", args.json)
        print(f"JSON: {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
