"""``python -m optimizers.indirect.cli``: the numbers of :mod:`optimizers.indirect.planar`'s
docstring, measured (nominal optimum and its DOP853 check, the independent direct methods, the
paper-comparison variants, the timing of a batch of dispersed states)."""

from __future__ import annotations

import math
import time

import numpy as np

from ..transcription.collocation import solve_planar_min_time_collocation
from .batch import solve_many
from .planar import solve_planar_min_fuel

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    """``python -m optimizers.indirect.cli [--scenario zhu2007] [--n 1000] [--workers 1]
    [--json FILE]``: nominal optimum with its DOP853 check, the independent collocation value,
    the paper-comparison variants, and the timing of a batch of dispersed states."""
    import argparse
    import dataclasses
    import json

    from lunar_env.scenarios import get_scenario

    ap = argparse.ArgumentParser(prog="python -m optimizers.indirect.cli", description=main.__doc__)
    ap.add_argument("--scenario", default="zhu2007")
    ap.add_argument("--n", type=int, default=1000, help="dispersed states to solve (0: none)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--seed", type=int, default=2007)
    ap.add_argument("--json", default=None, help="write the measured values to this file")
    args = ap.parse_args(argv)
    sc = get_scenario(args.scenario)
    out: dict = {"scenario": sc.name}

    t0 = time.perf_counter()
    sol = solve_planar_min_fuel(sc)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    again = solve_planar_min_fuel(sc)
    second = time.perf_counter() - t0
    print(f"{sc.name}: {sol.message}")
    print(f"  optimum fuel {sol.fuel_kg:.6f} kg, tf {sol.tf_s:.6f} s, final angle "
          f"{math.degrees(sol.thrust_angle_at(sol.tf_s)):.3f} deg")
    print("  terminal errors (DOP853 replay): " + ", ".join(
        f"{k} {v:.2e}" for k, v in sol.terminal_errors.items()))
    print(f"  wall: first call {first:.3f} s (CasADi build + collocation start), "
          f"second {second:.3f} s")
    out["pontryagin"] = {"fuel_kg": sol.fuel_kg, "tf_s": sol.tf_s, "success": sol.success,
                         "terminal_errors": sol.terminal_errors, "wall_first_s": first,
                         "wall_second_s": second, "costates0": sol.costates0.tolist()}
    del again

    t0 = time.perf_counter()
    col = solve_planar_min_time_collocation(sc, n_intervals=100)
    print(f"  independent: Hermite-Simpson collocation (100 intervals, IPOPT) {col.fuel_kg:.6f} "
          f"kg, tf {col.tf_s:.6f} s ({col.message}, {time.perf_counter() - t0:.2f} s); "
          f"difference {col.fuel_kg - sol.fuel_kg:+.2e} kg")
    out["collocation"] = {"fuel_kg": col.fuel_kg, "tf_s": col.tf_s, "success": col.success}
    from ..transcription.polynomial_shooting import solve_planar_min_time_polynomial

    out["direct_shooting"] = {}
    # Its first guess (φ rising from 0 to π/2) is a landing's; run it on the landing case only.
    for degree in (3, 7) if sc.name == "zhu2007" else ():
        ds = solve_planar_min_time_polynomial(sc, degree=degree)
        print(f"  independent: direct shooting, degree-{degree} polynomial angle, compiled RK4 "
              f"(SLSQP) {ds.fuel_kg:.6f} kg ({ds.message}, {ds.wall_s:.2f} s); difference "
              f"{ds.fuel_kg - sol.fuel_kg:+.2e} kg")
        out["direct_shooting"][f"degree_{degree}"] = {"fuel_kg": ds.fuel_kg, "tf_s": ds.tf_s,
                                                      "success": ds.success}

    if sc.name == "zhu2007":
        variants = {
            "g0 = 9.80665": dataclasses.replace(
                sc, vehicle=dataclasses.replace(sc.vehicle, g0_m_s2=9.80665)),
            "mu = 4902.8026e9": dataclasses.replace(
                sc, body=dataclasses.replace(sc.body, mu_m3_s2=4902.8026e9)),
        }
        out["variants"] = {}
        print("  paper 000 reports 277.5765 kg; variants:")
        for name, var in variants.items():
            v = solve_planar_min_fuel(var, check="grid")
            out["variants"][name] = v.fuel_kg
            print(f"    {name:18s} {v.fuel_kg:.4f} kg")
        x = np.array([sc.initial.radius_m, sc.initial.radial_velocity_m_s, 0.0,
                      sc.initial.tangential_velocity_m_s, sc.vehicle.mass_kg])
        fuels = []
        for dv in (-0.1, 0.1):
            fuels.append(solve_planar_min_fuel(sc, x + np.array([0, 0, 0, dv, 0]), guess=sol,
                                               check="grid").fuel_kg)
        sens = (fuels[1] - fuels[0]) / 0.2
        out["dfuel_dvt0_kg_per_m_s"] = sens
        print(f"    d fuel / d v_t0    {sens:.4f} kg per m/s -> the gap "
              f"{sol.fuel_kg - 277.5765:.4f} kg is worth {(sol.fuel_kg - 277.5765) / sens:.3f} m/s")

    if args.n > 0:
        rng = np.random.default_rng(args.seed)
        states = sc.sample_initial(rng, args.n)
        t0 = time.perf_counter()
        sols = solve_many(sc, states, n_workers=args.workers, progress=True)
        wall = time.perf_counter() - t0
        ok = np.array([s.success for s in sols])
        fuel = np.array([s.fuel_kg for s in sols])
        per = np.array([s.wall_s for s in sols])
        print(f"  {args.n} dispersed states (seed {args.seed}, {args.workers} worker(s)): "
              f"{ok.sum()} solved, batch wall {wall:.2f} s = {1e3 * wall / args.n:.2f} ms/state "
              f"(median solve {1e3 * np.median(per):.2f} ms, max {1e3 * per.max():.1f} ms); "
              f"fuel {fuel.min():.3f}..{fuel.max():.3f} kg")
        out["batch"] = {"n": args.n, "n_success": int(ok.sum()), "wall_s": wall,
                        "ms_per_state": 1e3 * wall / args.n,
                        "median_solve_ms": float(1e3 * np.median(per)),
                        "fuel_kg_min": float(fuel.min()), "fuel_kg_max": float(fuel.max())}
    if args.json:
        from ..common.checkpoint import atomic_write_bytes

        atomic_write_bytes(args.json, json.dumps(out, indent=2).encode())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
