"""The explicit laws' descent phases on ``LunarPinpointLanding-v3``: the measurement that chose
the defaults of :class:`guidance.laws.apollo.DescentPhases`.

``python benchmarks/bench_phases.py [--cases N] [--seed S] [--uncertainty U] [--json FILE]
[--grid default|small]``

Flies ``apollo`` and ``zem-zev`` with the defaults and one phase option changed at a time on
development cases ``seed .. seed + N - 1`` (default seed 10 000, distinct from the campaigns'
seed-0 cases, so the defaults are not tuned on the cases they are evaluated on) under the
``standard`` uncertainty set, and prints per variant: success rate, touchdown speed p50 and
p99, miss p50 and p99, propellant p50 and the µs per decision, and the variant with the
highest success (ties: the lower propellant p50).

Run pinned (``NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1``); each variant's flights are one
batched vector env (a few seconds for 200 cases).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

#: the variants of the measurement (law spec options of ``apollo``/``zem-zev``): the defaults
#: (empty), then one option changed at a time
VARIANTS = {
    "default": ("", "hg_speed=230", "hg_speed=270", "hg_speed=290", "low_gate=30", "rate=1.5",
                "high_gate=0"),
    "small": ("", "high_gate=0"),
}


def measure(law: str, options: str, cases: int, seed: int, uncertainty: str) -> dict:
    """One variant's figures on the development cases."""
    import gymnasium as gym

    import lunar_env  # noqa: F401
    from guidance.flight import fly
    from guidance.registry import LawContext, build_law

    env_id = "LunarPinpointLanding-v3"
    spec = f"{law}:{options}" if options else law
    scenario = gym.make(env_id).unwrapped.scenario
    built = build_law(spec, LawContext(env_id=env_id, env_kwargs={}, scenario=scenario))
    t0 = time.perf_counter()
    ro = fly(env_id, built, cases, seed=seed, env_kwargs={"uncertainty": uncertainty})
    speed = np.where(np.isnan(ro.touchdown_speed_m_s), np.inf, ro.touchdown_speed_m_s)
    miss = np.where(np.isnan(ro.miss_distance_m), np.inf, ro.miss_distance_m)
    return {"spec": spec, "success": float(np.mean(ro.is_success)),
            "speed_p50_m_s": float(np.percentile(speed, 50)),
            "speed_p99_m_s": float(np.percentile(speed, 99, method="higher")),
            "miss_p50_m": float(np.percentile(miss, 50)),
            "miss_p99_m": float(np.percentile(miss, 99, method="higher")),
            "fuel_p50_kg": float(np.nanmedian(ro.fuel_used_kg)),
            "us_per_decision": float(ro.us_per_decision),
            "wall_s": time.perf_counter() - t0}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--cases", type=int, default=200)
    p.add_argument("--seed", type=int, default=10_000)
    p.add_argument("--uncertainty", default="standard")
    p.add_argument("--grid", choices=sorted(VARIANTS), default="default")
    p.add_argument("--laws", nargs="+", default=["zem-zev", "apollo"])
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)
    rows = []
    for law in args.laws:
        for options in VARIANTS[args.grid]:
            r = measure(law, options, args.cases, args.seed, args.uncertainty)
            rows.append(r)
            print(f"{r['spec']:<44s} success {100 * r['success']:5.1f}%  v p50 "
                  f"{r['speed_p50_m_s']:5.2f} p99 {r['speed_p99_m_s']:8.2f}  miss p50 "
                  f"{r['miss_p50_m']:6.1f} p99 {r['miss_p99_m']:8.1f}  fuel p50 "
                  f"{r['fuel_p50_kg']:6.1f}  {r['us_per_decision']:5.0f} µs/dec", flush=True)
        best = max((r for r in rows if r["spec"].split(":")[0] == law),
                   key=lambda r: (r["success"], -r["fuel_p50_kg"]))
        print(f"best {law}: {best['spec']}", flush=True)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"cases": args.cases, "seed": args.seed,
                       "uncertainty": args.uncertainty, "rows": rows}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
