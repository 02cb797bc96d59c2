"""SCvx (convex re-planning) against the project's Pontryagin and GPM + shooting solvers.

``python benchmarks/bench_convex.py [--quick] [--json FILE] [--cases N] [--nodes K] [--iters I]``

Part 1 — open-loop optimum, nominal start, timed in the same run:

- zhu2007 (planar): SCvx (:class:`optimizers.transcription.convex.SuccessiveConvexification`,
  K nodes, constant engine) — its first solve (cvxpy compilation included) and a second cold
  solve on the built problem — against Pontryagin shooting
  (:func:`optimizers.indirect.planar.solve_planar_min_fuel`, the certifier);
- peng2012 (3D): SCvx against the serial GPM + direct shooting
  (:func:`optimizers.transcription.serial.solve_serial`, [001]) and the dense Legendre–Gauss
  collocation certifier (:func:`optimizers.certification.certified_optimum`).

Every SCvx answer is certified (:func:`optimizers.certification.certify`: DOP853 replay and the
fuel gap to the certified optimum); also reported: the throttled engine's fuel (the relaxation's
tightness) and wall-time ratios SCvx / peer.

Part 2 — re-planning. The convex law (``convex:every=10``, :mod:`guidance.laws.convex`) flies N
dispersed cases of each env (``LunarSoftLanding-v0``, ``LunarPinpointLanding-v2``) with
:func:`guidance.flight.fly`; per re-plan after each lander's first plan: wall time median
and p90 (and the process CPU time); the share of all re-plans' wall time spent inside Clarabel;
SCvx iterations; the landing rate; and the fuel gap to each case's optimum (the env family's
per-case solver: Pontryagin planar, GPM + shooting pinpoint, cached on disk). Cases: the
evaluation's seed (2026) by default.

BLAS runs on one thread and Clarabel is single-threaded, so the process CPU time of a re-plan
is its one-core cost; it is reported beside the wall time (``--pin`` also pins the process to
one CPU). The machine may be shared: times are as measured, ratios are taken in the same run.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402


def _pin_one_core() -> str:
    if hasattr(os, "sched_setaffinity"):
        cpu = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpu})
        return f"pinned to CPU {cpu}"
    return "not pinned (no sched_setaffinity)"


@contextlib.contextmanager
def _clarabel_timer():
    """Benchmark instrumentation: wall time inside cvxpy's hand-over to Clarabel (its data
    update and solve; the problem is already stuffed), summed into the yielded list's first
    entry. (Clarabel's own ``solve_time`` reads above the wall time around it here, so it is
    not used.)"""
    from cvxpy.reductions.solvers.conic_solvers.clarabel_conif import CLARABEL

    total = [0.0]
    original = CLARABEL.solve_via_data

    def timed(self, *args, **kwargs):
        t = time.perf_counter()
        try:
            return original(self, *args, **kwargs)
        finally:
            total[0] += time.perf_counter() - t

    CLARABEL.solve_via_data = timed
    try:
        yield total
    finally:
        CLARABEL.solve_via_data = original


def _scvx(ocp, n_nodes: int, engine: str = "constant") -> dict:
    from optimizers.certification import certify
    from optimizers.transcription.convex import SuccessiveConvexification

    solver = SuccessiveConvexification(n_nodes, engine=engine)
    t0 = time.perf_counter()
    first = solver.solve(ocp)
    first_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    with _clarabel_timer() as clarabel_s:
        res = solver.solve(ocp)
    cold_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    warm = solver.solve(ocp, res.guess())
    warm_s = time.perf_counter() - t0
    cert = certify(res, ocp, rtol=1e-10)
    return {"engine": engine, "n_nodes": n_nodes, "success": bool(res.success),
            "fuel_kg": res.fuel_kg, "tf_s": res.tf_s, "n_iter": res.n_iter,
            "first_solve_s": first_s, "build_s": first.extra["build_s"], "cold_solve_s": cold_s,
            "clarabel_s": clarabel_s[0], "warm_resolve_s": warm_s,
            "warm_iter": warm.n_iter, "tightness": res.extra["tightness"],
            "min_throttle": res.extra["min_throttle"], "replay_success": cert.replay_success,
            "replay_errors": cert.replay_terminal_errors, "optimum_fuel_kg": cert.optimum_fuel_kg,
            "fuel_gap_pct": cert.fuel_gap_pct}


def bench_planar(n_nodes: int) -> dict:
    from optimizers.indirect.planar import solve_planar_min_fuel
    from optimizers.problems.planar_ocp import PlanarOCP

    ocp = PlanarOCP("zhu2007")
    t0 = time.perf_counter()
    pmp = solve_planar_min_fuel(ocp, check="reference")
    pmp_s = time.perf_counter() - t0
    out = {"pontryagin": {"fuel_kg": pmp.fuel_kg, "wall_s": pmp_s, "success": pmp.success},
           "scvx": _scvx(ocp, n_nodes), "scvx_throttled": _scvx(ocp, n_nodes, "throttled")}
    out["ratio_cold_to_pontryagin"] = out["scvx"]["cold_solve_s"] / pmp_s
    return out


def bench_pinpoint(n_nodes: int) -> dict:
    from lunar_env import get_scenario
    from optimizers.certification import certified_optimum
    from optimizers.problems.pinpoint import PinpointOCP
    from optimizers.transcription.serial import solve_serial

    ocp = PinpointOCP(get_scenario("peng2012"))
    t0 = time.perf_counter()
    serial = solve_serial("peng2012")
    serial_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    dense = certified_optimum(ocp)
    dense_s = time.perf_counter() - t0
    out = {"gpm_shooting": {"fuel_kg": serial.fuel_kg, "wall_s": serial_s,
                            "success": serial.success},
           "dense_collocation": {"fuel_kg": dense.fuel_kg, "wall_s": dense_s,
                                 "success": dense.success},
           "scvx": _scvx(ocp, n_nodes), "scvx_throttled": _scvx(ocp, n_nodes, "throttled")}
    out["ratio_cold_to_gpm_shooting"] = out["scvx"]["cold_solve_s"] / serial_s
    out["ratio_cold_to_dense"] = out["scvx"]["cold_solve_s"] / dense_s
    return out


def bench_replanning(env_id: str, n_cases: int, spec: str, seed: int) -> dict:
    import gymnasium as gym

    import lunar_env  # noqa: F401
    from guidance.flight import fly, initial_states
    from guidance.registry import LawContext, build_law
    from optimizers.optimum import optimum_family

    env = gym.make(env_id)
    scenario = env.unwrapped.scenario
    law = build_law(spec, LawContext(env_id, {}, scenario))
    env.close()
    t0 = time.perf_counter()
    with _clarabel_timer() as clarabel_s:
        out = fly(env_id, law, n_cases, seed=seed)
    wall = time.perf_counter() - t0
    # fuel gap to each case's optimum (the family's per-case solver, cached for pinpoint)
    optimum = optimum_family(scenario).per_case_optimum(
        scenario, initial_states(env_id, n_cases, seed), progress=False)
    both = out.is_success & np.isfinite(optimum.fuel_kg)
    gap = out.fuel_used_kg[both] - optimum.fuel_kg[both]
    gap_pct = 100.0 * gap / optimum.fuel_kg[both]
    log = np.array([r for r in law.replan_log if not r[5]], dtype=float).reshape(-1, 6)
    wall_ms, cpu_ms = 1e3 * log[:, 0], 1e3 * log[:, 1]
    # share of all re-plans' wall time (first plans included) spent in Clarabel
    share = clarabel_s[0] / max(sum(r[0] for r in law.replan_log), 1e-12)
    speed = out.touchdown_speed_m_s
    miss = out.miss_distance_m
    return {"env_id": env_id, "spec": spec, "n_cases": n_cases, "seed": seed,
            "fuel_gap_p50_kg": float(np.median(gap)) if gap.size else None,
            "fuel_gap_p99_kg": float(np.percentile(gap, 99)) if gap.size else None,
            "fuel_gap_p50_pct": float(np.median(gap_pct)) if gap.size else None,
            "fuel_gap_p99_pct": float(np.percentile(gap_pct, 99)) if gap.size else None,
            "n_gap_cases": int(gap.size),
            "success_rate": float(np.mean(out.is_success)),
            "n_success": int(np.sum(out.is_success)),
            "touchdown_speed_p50_m_s": float(np.nanmedian(speed)),
            "touchdown_speed_max_m_s": float(np.nanmax(speed)),
            "miss_p50_m": float(np.nanmedian(miss)) if np.isfinite(miss).any() else None,
            "miss_max_m": float(np.nanmax(miss)) if np.isfinite(miss).any() else None,
            "fuel_p50_kg": float(np.nanmedian(out.fuel_used_kg)),
            "n_replans": int(len(log)), "n_failed": int(law.n_failed),
            "replan_ms_p50": float(np.median(wall_ms)), "replan_ms_p90":
            float(np.percentile(wall_ms, 90)), "replan_cpu_ms_p50": float(np.median(cpu_ms)),
            "replan_cpu_ms_p90": float(np.percentile(cpu_ms, 90)),
            "clarabel_share": float(share),
            "iters_mean": float(np.mean(log[:, 4])), "us_per_decision": out.us_per_decision,
            "wall_s": wall, "failed_cases": [int(i) for i in np.flatnonzero(~out.is_success)]}


def _print_scvx(s: dict, t: dict) -> None:
    """The SCvx lines of one case (constant and throttled engine)."""
    print(f"  SCvx constant     {s['fuel_kg']:9.4f} kg  {s['cold_solve_s'] * 1e3:8.0f} ms cold "
          f"({s['n_iter']} it, Clarabel {s['clarabel_s'] * 1e3:.0f} ms; first solve with "
          f"compile {s['first_solve_s']:.2f} s; warm re-solve {s['warm_resolve_s'] * 1e3:.0f}"
          f" ms) gap {s['fuel_gap_pct']:+.4f} % replay ok {s['replay_success']} "
          f"tightness {s['tightness']:.7f}")
    print(f"  SCvx throttled    {t['fuel_kg']:9.4f} kg  gap {t['fuel_gap_pct']:+.4f} % "
          f"min throttle {t['min_throttle']:.4f} tightness {t['tightness']:.7f}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="2 cases per env in part 2")
    ap.add_argument("--json", default=None)
    ap.add_argument("--cases", type=int, default=None, help="cases per env (default 10)")
    ap.add_argument("--nodes", type=int, default=30, help="SCvx nodes K (default 30)")
    ap.add_argument("--every", type=float, default=10.0, help="re-planning period (s)")
    ap.add_argument("--iters", type=int, default=2, help="SCvx iterations per re-plan")
    ap.add_argument("--seed", type=int, default=2026,
                    help="case set of part 2 (default 2026, the evaluation's)")
    ap.add_argument("--pin", action="store_true",
                    help="pin the process to one CPU (with other processes on the cores this can "
                         "only hurt the wall times; the CPU times are one-core figures either way)")
    ap.add_argument("--part", choices=("all", "optimum", "replan"), default="all")
    args = ap.parse_args(argv)
    n_cases = args.cases or (2 if args.quick else 10)
    pin = _pin_one_core() if args.pin else "not pinned"
    print(f"bench_convex: {pin}; load average {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} CPUs (times as measured on a possibly shared machine)")
    res: dict = {"n_nodes": args.nodes}
    if args.part in ("all", "optimum"):
        res["zhu2007"] = p = bench_planar(args.nodes)
        s, t = p["scvx"], p["scvx_throttled"]
        print(f"\nzhu2007 (planar), K = {args.nodes}")
        print(f"  Pontryagin        {p['pontryagin']['fuel_kg']:9.4f} kg  "
              f"{p['pontryagin']['wall_s'] * 1e3:8.0f} ms")
        _print_scvx(s, t)
        print(f"  ratio SCvx cold / Pontryagin: {p['ratio_cold_to_pontryagin']:.2f}")
        res["peng2012"] = q = bench_pinpoint(args.nodes)
        s, t = q["scvx"], q["scvx_throttled"]
        print(f"\npeng2012 (3D), K = {args.nodes}")
        print(f"  GPM + shooting    {q['gpm_shooting']['fuel_kg']:9.4f} kg  "
              f"{q['gpm_shooting']['wall_s'] * 1e3:8.0f} ms")
        print(f"  dense collocation {q['dense_collocation']['fuel_kg']:9.4f} kg  "
              f"{q['dense_collocation']['wall_s'] * 1e3:8.0f} ms (the certifier)")
        _print_scvx(s, t)
        print(f"  ratio SCvx cold / GPM + shooting: {q['ratio_cold_to_gpm_shooting']:.3f}; "
              f"/ dense collocation: {q['ratio_cold_to_dense']:.3f}")
    if args.part in ("all", "replan"):
        spec = f"convex:every={args.every:g},nodes={args.nodes},iters={args.iters}"
        res["replanning"] = []
        for env_id in ("LunarSoftLanding-v0", "LunarPinpointLanding-v2"):
            r = bench_replanning(env_id, n_cases, spec, args.seed)
            res["replanning"].append(r)
            miss = "" if r["miss_max_m"] is None else f", miss max {r['miss_max_m']:.1f} m"
            print(f"\n{env_id} {spec}: {r['n_success']}/{n_cases} landed (touchdown speed "
                  f"p50 {r['touchdown_speed_p50_m_s']:.2f}, max "
                  f"{r['touchdown_speed_max_m_s']:.2f} m/s{miss}); {r['n_replans']} re-plans: "
                  f"wall median {r['replan_ms_p50']:.0f} ms, p90 {r['replan_ms_p90']:.0f} ms "
                  f"(CPU median {r['replan_cpu_ms_p50']:.0f} ms, p90 "
                  f"{r['replan_cpu_ms_p90']:.0f} ms), "
                  f"Clarabel share {100 * r['clarabel_share']:.0f} %, "
                  f"{r['iters_mean']:.2f} SCvx iterations on average; "
                  f"{r['us_per_decision'] / 1e3:.1f} ms per decision")
            if r["n_gap_cases"]:
                print(f"  fuel gap to the per-case optimum ({r['n_gap_cases']} cases): p50 "
                      f"{r['fuel_gap_p50_kg']:+.2f} kg ({r['fuel_gap_p50_pct']:+.3f} %), p99 "
                      f"{r['fuel_gap_p99_kg']:+.2f} kg ({r['fuel_gap_p99_pct']:+.3f} %)")
    if args.json:
        d = os.path.dirname(os.path.abspath(args.json))
        os.makedirs(d, exist_ok=True)
        tmp = args.json + ".tmp"
        with open(tmp, "w") as fh:
            json.dump(res, fh, indent=2, default=float)
        os.replace(tmp, args.json)
        print(f"JSON: {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
