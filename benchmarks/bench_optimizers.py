"""ASAGA against pygmo's sade, cmaes and pso on the [000] landing; batched fitness vs scipy.

``python benchmarks/bench_optimizers.py [--quick] [--json FILE] [--seeds N] [--budget N]``

Part 1 — optimisers. The same problem (:class:`~optimizers.problems.PlanarLandingProblem`,
zhu2007, cubic through 10 node angles + tf) and the same evaluation budget for every algorithm
(default: the mean number of evaluations of a full ASAGA run with the paper's settings), 10 seeds
each. sade, cmaes and pso handle no constraints, so they minimise the *same penalty* as ASAGA
(eq. 11 of [000]) through :class:`~optimizers.problems.PenalisedProblem`, with ASAGA's final
weights held fixed (σ1 = 50, σ2 = 10; ASAGA itself ramps them up from 5 and 1 as in the paper).
Population 20 for all (ASAGA's M). Reported per algorithm: fuel gap of the final best to the
Pontryagin optimum (solved here), terminal speed and radius errors, success rate (|dV| < 0.5 m/s
and |dr| < 1 m, the paper's convergence), wall time per run. pygmo calls ``fitness`` one
candidate at a time; ASAGA evaluates each generation in one batched call.

Part 2 — fitness throughput. ``batch_fitness`` of 1000 random candidates (one compiled, batched
RK4 call, 100 steps) against a loop of scipy ``solve_ivp`` (RK45, rtol 1e-8, atol 1e-11; the
same equations, :func:`lunar_env.dynamics.planar_eom`) over the same candidates; both accuracies
are measured against DOP853 at rtol 1e-12 and printed, and the ratio of the times.

Part 3 — the [003] problem (:class:`~optimizers.problems.ThrustDesignProblem`: tf, thrust T
and a cubic ψ; wang2003). FGA with the paper's settings, ASAGA as printed and its
``temperature_scale="spread"`` variant, and pygmo's sga, sade and cmaes at the budget of one
full FGA run (default 100 020 evaluations; ``--quick``: 300 generations), 10 seeds (quick 2).
The pygmo algorithms minimise the FGA's penalty (weight 1, SI) through
:class:`~optimizers.problems.PenalisedProblem`; ASAGA runs as many generations as fit in the
budget. Reported: success rate (|dV| < 0.5 m/s, |dr| < 1 m), fuel gap of the landing runs to
the certified optimum over T (Pontryagin), median terminal errors, wall time, and each
algorithm's wall time as a ratio to pygmo sga's, timed in the same run.

The machine may be shared: times are as measured, ratios are taken in the same run.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

from lunar_env import get_scenario
from lunar_env.dynamics import planar_eom
from lunar_env.integrators import PLANAR, integrate_reference
from optimizers.evolutionary.asaga import ASAGA
from optimizers.problems.landing import PlanarLandingProblem
from optimizers.problems.penalised import PenalisedProblem


def _pygmo_run(name: str, pen: PenalisedProblem, budget: int, seed: int, n_pop: int = 20):
    import pygmo as pg

    gens = max(1, budget // n_pop - 1)  # the initial population costs n_pop evaluations
    if name == "sade":
        algo = pg.sade(gen=gens, seed=seed)
    elif name == "cmaes":
        algo = pg.cmaes(gen=gens, seed=seed, force_bounds=True)
    elif name == "pso":
        algo = pg.pso(gen=gens, seed=seed)
    else:
        raise ValueError(name)
    t = time.perf_counter()
    pop = pg.population(pen.to_pygmo(), size=n_pop, seed=seed)
    pop = pg.algorithm(algo).evolve(pop)
    wall = time.perf_counter() - t
    return np.asarray(pop.champion_x), wall, int(pop.problem.get_fevals())


def _summarise(problem: PlanarLandingProblem, xs, walls, fevals, optimum):
    F = problem.batch_fitness(np.asarray(xs))
    speed = np.hypot(F[:, 1], F[:, 2])
    dr = np.abs(F[:, 3])
    ok = np.array([problem.assess(x, f).success for x, f in zip(xs, F, strict=True)])
    gap = F[:, 0] - optimum
    return {
        "success_rate": float(ok.mean()),
        "gap_kg_mean": float(gap.mean()), "gap_kg_median": float(np.median(gap)),
        "gap_kg_best_converged": float(gap[ok].min()) if ok.any() else None,
        "gap_kg_median_converged": float(np.median(gap[ok])) if ok.any() else None,
        "speed_m_s_median": float(np.median(speed)), "speed_m_s_mean": float(speed.mean()),
        "radius_err_m_median": float(np.median(dr)), "radius_err_m_mean": float(dr.mean()),
        "wall_s_mean": float(np.mean(walls)), "n_fevals_mean": float(np.mean(fevals)),
        "fuel_kg": [float(v) for v in F[:, 0]], "speed_m_s": [float(v) for v in speed],
        "radius_err_m": [float(v) for v in F[:, 3]],
    }


def bench_optimizers(n_seeds: int, budget: int | None, n_generations: int) -> dict:
    from optimizers.indirect.planar import solve_planar_min_fuel

    scenario = get_scenario("zhu2007")
    problem = PlanarLandingProblem(scenario)
    problem.fitness(np.r_[np.zeros(10), 600.0])  # compile
    sol = solve_planar_min_fuel(scenario)
    optimum = float(sol.fuel_kg)
    print(f"Pontryagin optimum: {optimum:.5f} kg ({sol.message})")
    out = {"optimum_fuel_kg": optimum, "algorithms": {}}
    variants = [("ASAGA (paper, normalised f)", "normalised"),
                ("ASAGA (f in SI units)", "si")]
    asaga_fevals = None
    for label, units in variants:
        xs, walls, fev = [], [], []
        variant = PlanarLandingProblem(scenario, penalty_units=units)
        for s in range(n_seeds):
            r = ASAGA(n_generations=n_generations).solve(variant, seed=s)
            xs.append(r.x)
            walls.append(r.wall_s)
            fev.append(r.n_fevals)
        out["algorithms"][label] = _summarise(problem, xs, walls, fev, optimum)
        if asaga_fevals is None:
            asaga_fevals = int(np.mean(fev))
        print(f"  {label}: done ({np.mean(walls):.2f} s/run)", flush=True)
    budget = budget or asaga_fevals
    out["budget_fevals"] = budget
    for name in ("sade", "cmaes", "pso"):
        xs, walls, fev = [], [], []
        for s in range(n_seeds):
            pen = PenalisedProblem(problem)
            x, w, n = _pygmo_run(name, pen, budget, seed=s)
            xs.append(x)
            walls.append(w)
            fev.append(n)
        out["algorithms"][f"pygmo {name}"] = _summarise(problem, xs, walls, fev, optimum)
        print(f"  pygmo {name}: done ({np.mean(walls):.2f} s/run)", flush=True)
    return out


def bench_fitness(n_candidates: int, n_scipy: int) -> dict:
    problem = PlanarLandingProblem()
    lb, ub = problem.get_bounds()
    rng = np.random.default_rng(0)
    X = lb + (ub - lb) * rng.random((n_candidates, lb.size))
    t_kernel = {}
    for label, par in (("threaded", True), ("serial", False)):
        prob = PlanarLandingProblem(parallel=par)
        F = prob.batch_fitness(X)  # compile / load the cached kernel
        n_rep = 5
        t = time.perf_counter()
        for _ in range(n_rep):
            F = prob.batch_fitness(X)
        t_kernel[label] = (time.perf_counter() - t) / n_rep
    t_batch = t_kernel["threaded"]

    thrust, c = problem.params.thrust_nd, problem.params.exhaust_velocity_nd

    def scipy_one(x, rtol, atol, method):
        from scipy.integrate import solve_ivp

        coef = problem.parameterisation.time_coefficients(np.deg2rad(x[None, :-1]), 0.0,
                                                          problem.scaling.time_nd(x[-1]))[0]
        poly = coef[::-1].copy()
        tf = float(problem.scaling.time_nd(x[-1]))

        def f(t, y):
            phi = np.polyval(poly, t)
            return planar_eom(y[0], y[1], y[3], y[4], phi, 1.0, thrust, c)

        return solve_ivp(f, (0.0, tf), problem.y0_nd, method=method, rtol=rtol, atol=atol).y[:, -1]

    t = time.perf_counter()
    Y = np.array([scipy_one(x, 1e-8, 1e-11, "RK45") for x in X[:n_scipy]])
    t_scipy = (time.perf_counter() - t) / n_scipy * n_candidates
    # accuracy of both against the DOP853 reference on a few candidates
    # (candidates with tf < 650 s: beyond ~653 s the propellant runs out, which the RK4 kernel
    # models and the plain reference below does not)
    err_rk4, err_scipy = [], []
    for i in np.flatnonzero(X[:n_scipy, -1] < 650.0)[:5]:
        ctrl, tf_nd = problem.control(X[i:i + 1])
        ref = integrate_reference(PLANAR, problem.y0_nd, (0.0, float(tf_nd[0])),
                                  lambda t, ctrl=ctrl: ctrl(np.array([[t]]))[0, 0],
                                  problem.params).y[:, -1]
        e_ref = problem.terminal_errors_from_state(ref[None])
        e_s = problem.terminal_errors_from_state(Y[i][None])
        err_rk4.append(max(abs(F[i, 1] - e_ref["radial_velocity_m_s"][0]),
                           abs(F[i, 2] - e_ref["tangential_velocity_m_s"][0])))
        err_scipy.append(max(abs(e_s["radial_velocity_m_s"][0] - e_ref["radial_velocity_m_s"][0]),
                             abs(e_s["tangential_velocity_m_s"][0]
                                 - e_ref["tangential_velocity_m_s"][0])))
    return {"n_candidates": n_candidates, "n_scipy_timed": n_scipy,
            "batch_fitness_s": t_batch, "batch_fitness_serial_s": t_kernel["serial"],
            "scipy_loop_s": t_scipy, "ratio": t_scipy / t_batch,
            "ratio_serial_kernel": t_scipy / t_kernel["serial"],
            "rk4_velocity_error_m_s_max": float(max(err_rk4)),
            "scipy_velocity_error_m_s_max": float(max(err_scipy))}


def bench_wang2003(n_seeds: int, n_gen_fga: int) -> dict:
    """Part 3: FGA, ASAGA (printed, spread) and pygmo sga/sade/cmaes on [003]'s problem."""
    import pygmo as pg

    from optimizers.evolutionary.fga import FGA
    from optimizers.problems.thrust_design import ThrustDesignProblem
    from optimizers.reproduce.wang2003 import optimal_thrust

    problem = ThrustDesignProblem()
    problem.fitness(np.array([220.0, 3.0, 0.0, 0.0, 10.0, 20.0]))  # compile
    opt = optimal_thrust((2500.0, 3500.0))
    optimum = opt["fuel_kg"]
    print(f"[003] certified optimum over T: {optimum:.4f} kg at {opt['thrust_n'] / 1e3:.4f} kN")
    budget = 20 + n_gen_fga * 10
    probe = ASAGA(n_generations=10).solve(problem, seed=0)
    asaga_gen = max(1, int(round(budget / (probe.n_fevals / 10))))
    out = {"optimum_fuel_kg": optimum, "optimal_thrust_n": opt["thrust_n"],
           "budget_fevals": budget, "asaga_generations": asaga_gen, "algorithms": {}}

    def run_ours(make):
        xs, walls, fev = [], [], []
        for s in range(n_seeds):
            r = make().solve(problem, seed=s)
            xs.append(r.x)
            walls.append(r.wall_s)
            fev.append(r.n_fevals)
        return xs, walls, fev

    def run_pygmo(name):
        gens = max(1, budget // 20 - 1)
        xs, walls, fev = [], [], []
        for s in range(n_seeds):
            kw = {"force_bounds": True} if name == "cmaes" else {}
            algo = getattr(pg, name)(gen=gens, seed=s, **kw)
            pen = PenalisedProblem(problem, weight=1.0)
            t = time.perf_counter()
            pop = pg.algorithm(algo).evolve(pg.population(pen.to_pygmo(), size=20, seed=s))
            walls.append(time.perf_counter() - t)
            xs.append(np.asarray(pop.champion_x))
            fev.append(int(pop.problem.get_fevals()))
        return xs, walls, fev

    entries = [("FGA (paper)", lambda: run_ours(lambda: FGA(n_generations=n_gen_fga))),
               ("ASAGA (printed)", lambda: run_ours(lambda: ASAGA(n_generations=asaga_gen))),
               ("ASAGA (spread T)", lambda: run_ours(
                   lambda: ASAGA(n_generations=asaga_gen, temperature_scale="spread"))),
               ("pygmo sga", lambda: run_pygmo("sga")),
               ("pygmo sade", lambda: run_pygmo("sade")),
               ("pygmo cmaes", lambda: run_pygmo("cmaes"))]
    for label, fn in entries:
        xs, walls, fev = fn()
        out["algorithms"][label] = _summarise(problem, xs, walls, fev, optimum)
        print(f"  {label}: done ({np.mean(walls):.2f} s/run)", flush=True)
    ref = out["algorithms"]["pygmo sga"]["wall_s_mean"]
    for s in out["algorithms"].values():
        s["wall_ratio_to_sga"] = s["wall_s_mean"] / ref
    return out


def _print_table(opt: dict, n_seeds: int, ref_name: str, ratio: bool = False) -> None:
    print(f"\nSame problem, budget {opt['budget_fevals']} evaluations/run, {n_seeds} seeds; "
          f"gap to the {ref_name} {opt['optimum_fuel_kg']:.4f} kg")
    hdr = (f"{'algorithm':<28} {'success':>8} {'gap mean kg':>12} {'gap med kg':>11} "
           f"{'gap med conv':>13} "
           f"{'|dV| med m/s':>13} {'|dr| med m':>11} {'wall s/run':>11} {'evals':>7}"
           + (f" {'wall/sga':>9}" if ratio else ""))
    print(hdr)
    print("-" * len(hdr))
    for name, s in opt["algorithms"].items():
        conv = s["gap_kg_median_converged"]
        conv = "—" if conv is None else f"{conv:.4f}"
        print(f"{name:<28} {s['success_rate']:>8.0%} {s['gap_kg_mean']:>12.4f} "
              f"{s['gap_kg_median']:>11.4f} {conv:>13} {s['speed_m_s_median']:>13.3g} "
              f"{s['radius_err_m_median']:>11.3g} {s['wall_s_mean']:>11.2f} "
              f"{s['n_fevals_mean']:>7.0f}"
              + (f" {s['wall_ratio_to_sga']:>9.2f}" if ratio else ""))
    print("(success: |dV| < 0.5 m/s and |dr| < 1 m; 'gap med conv': median over the successful "
          "runs; gaps of unsuccessful runs can be negative: they did not land)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="3 seeds, 60 generations, 200 scipy")
    ap.add_argument("--json", default=None)
    ap.add_argument("--seeds", type=int, default=None)
    ap.add_argument("--budget", type=int, default=None,
                    help="evaluations per run for the pygmo algorithms (default: ASAGA's)")
    ap.add_argument("--part", choices=("all", "zhu2007", "fitness", "wang2003"), default="all",
                    help="run one part only (default all)")
    args = ap.parse_args(argv)
    n_seeds = args.seeds or (3 if args.quick else 10)
    n_gen = 60 if args.quick else 300
    print(f"bench_optimizers: {n_seeds} seeds, ASAGA {n_gen} generations "
          f"(machine may be loaded; {os.cpu_count()} CPUs)")
    res = {}
    if args.part in ("all", "zhu2007"):
        res["optimizers"] = bench_optimizers(n_seeds, args.budget, n_gen)
    if args.part in ("all", "fitness"):
        res["fitness"] = bench_fitness(1000, 100 if args.quick else 1000)
    if args.part in ("all", "wang2003"):
        res["wang2003"] = bench_wang2003(args.seeds or (2 if args.quick else 10),
                                         300 if args.quick else 10_000)

    if "optimizers" in res:
        _print_table(res["optimizers"], n_seeds, "Pontryagin optimum")
    if "fitness" in res:
        f = res["fitness"]
        print(f"\nbatch_fitness of {f['n_candidates']} candidates: "
              f"{f['batch_fitness_s'] * 1e3:.1f} ms (threaded kernel; serial kernel "
              f"{f['batch_fitness_serial_s'] * 1e3:.1f} ms); scipy solve_ivp loop (RK45, rtol "
              f"1e-8; {f['n_scipy_timed']} timed, scaled): {f['scipy_loop_s']:.2f} s; ratio "
              f"{f['ratio']:.0f}x (serial kernel: {f['ratio_serial_kernel']:.0f}x)")
        print(f"terminal-velocity error vs DOP853 1e-12: RK4 "
              f"{f['rk4_velocity_error_m_s_max']:.1e} m/s, solve_ivp "
              f"{f['scipy_velocity_error_m_s_max']:.1e} m/s")
    if "wang2003" in res:
        w = res["wang2003"]
        print(f"\n[003] problem (ASAGA {w['asaga_generations']} generations to match the budget)")
        _print_table(w, args.seeds or (2 if args.quick else 10),
                     "certified optimum over T", ratio=True)
    if args.json:
        d = os.path.dirname(os.path.abspath(args.json))
        os.makedirs(d, exist_ok=True)
        tmp = args.json + ".tmp"
        with open(tmp, "w") as fh:
            json.dump(res, fh, indent=2)
        os.replace(tmp, args.json)
        print(f"JSON: {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
