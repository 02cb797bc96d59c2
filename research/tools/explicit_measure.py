"""Measure guidance laws on the dispersed cases of an env: the issue-30 table.

::

    python -m research.tools.explicit_measure --env LunarSoftLanding-v0 --n 1000 \\
        --laws apollo zem-zev gravity-turn
    python -m research.tools.explicit_measure --env LunarPinpointLanding-v2 --n 1000 \\
        --gap-cases 200 --env-kwargs '{"throttle_channel": true}' --laws apollo zem-zev

Each law flies cases 0..n−1 of ``seed`` (:func:`guidance.flight.fly`; success is the
env's ``is_success``). The fuel gap is 100·(fuel − optimum)/optimum over the *successful*
cases among the first ``gap_cases`` (the env family's ``per_case_optimum``, computed for
those cases only: the pinpoint optimum costs ~1 s a case, cached on disk). Failures are sorted
by how they end (:func:`failure_modes`).
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import numpy as np

from guidance.flight import Rollout, fly
from guidance.registry import LawContext, build_law
from optimizers.optimum import optimum_family

__all__ = ["measure", "failure_modes", "markdown", "plot_tracks", "main"]


def failure_modes(out: Rollout, propellant_kg: np.ndarray, success_speed_m_s: float = 5.0,
                  success_miss_m: float = 500.0) -> dict[str, int]:
    """Counts of the ways the failed cases ended: ``propellant exhausted`` (fuel used within
    0.01 kg of the propellant loaded), ``no touchdown`` (truncated), ``fast`` (speed at the
    end above the success speed), ``miss`` (pinpoint: beyond the success miss), in that order
    of precedence."""
    fail = ~out.is_success
    dry = fail & (out.fuel_used_kg >= propellant_kg - 0.01)
    no_td = fail & ~dry & ~np.isfinite(out.touchdown_speed_m_s)
    fast = fail & ~dry & ~no_td & (out.touchdown_speed_m_s > success_speed_m_s)
    miss = fail & ~dry & ~no_td & ~fast & (np.nan_to_num(out.miss_distance_m) > success_miss_m)
    return {"propellant exhausted": int(dry.sum()), "no touchdown": int(no_td.sum()),
            "fast": int(fast.sum()), "miss": int(miss.sum())}


def measure(env_id: str, specs: list[str], n: int = 1000, seed: int = 2026,
            gap_cases: int | None = None, env_kwargs: dict[str, Any] | None = None
            ) -> list[dict[str, Any]]:
    """One row per law spec: success rate, touchdown-speed p99, miss p99, fuel gap p50/p99
    (%), µs per decision, failure modes; ``gap_cases`` (default n) cases carry the gap."""
    import gymnasium as gym

    import lunar_env  # noqa: F401
    from guidance.flight import initial_states

    env = gym.make(env_id, **(env_kwargs or {}))
    core = env.unwrapped
    scenario = core.scenario
    env.close()
    states = initial_states(env_id, n, seed, env_kwargs)
    s = scenario.scaling()
    m_col = 4 if states.shape[1] == 5 else 6
    propellant = states[:, m_col] * s.mass_kg - scenario.vehicle.dry_mass_kg
    k = n if gap_cases is None else min(int(gap_cases), n)
    optimum = optimum_family(scenario).per_case_optimum(scenario, states[:k], progress=False)
    context = LawContext(env_id=env_id, env_kwargs=dict(env_kwargs or {}), scenario=scenario)
    rows = []
    for spec in specs:
        law = build_law(spec, context)
        t0 = time.perf_counter()
        out = fly(env_id, law, n, seed=seed, env_kwargs=env_kwargs)
        wall = time.perf_counter() - t0
        ok = out.is_success
        gap = 100.0 * (out.fuel_used_kg[:k] - optimum.fuel_kg) / optimum.fuel_kg
        g_ok = ok[:k] & np.isfinite(gap)
        td = out.touchdown_speed_m_s[np.isfinite(out.touchdown_speed_m_s)]
        miss = out.miss_distance_m[np.isfinite(out.miss_distance_m)]
        rows.append({
            "law": spec, "env_id": env_id, "env_kwargs": dict(env_kwargs or {}), "n": n,
            "seed": seed, "success_rate": float(ok.mean()),
            "touchdown_speed_p99_m_s": float(np.percentile(td, 99)) if td.size else None,
            "miss_p99_m": float(np.percentile(miss, 99)) if miss.size else None,
            "gap_cases": k, "n_gap": int(g_ok.sum()),
            "fuel_gap_p50_pct": float(np.percentile(gap[g_ok], 50)) if g_ok.any() else None,
            "fuel_gap_p99_pct": float(np.percentile(gap[g_ok], 99)) if g_ok.any() else None,
            "fuel_mean_kg": float(np.mean(out.fuel_used_kg)),
            "us_per_decision": float(out.us_per_decision), "wall_s": wall,
            "failures": failure_modes(out, propellant),
            "failed_cases": np.nonzero(~ok)[0][:20].tolist()})
    return rows


def markdown(rows: list[dict[str, Any]]) -> str:
    """The rows as a Markdown table."""
    def f(x, fmt):
        return "–" if x is None else format(x, fmt)

    lines = ["| law | engine | cases | success % | td speed p99 (m/s) | miss p99 (m) | "
             "fuel gap p50 / p99 (%) [cases] | µs / decision | failures |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        engine = "throttled" if r["env_kwargs"].get("throttle_channel") else "constant"
        fails = ", ".join(f"{k} {v}" for k, v in r["failures"].items() if v) or "–"
        lines.append(
            f"| {r['law']} | {engine} | {r['n']} | {100 * r['success_rate']:.1f} | "
            f"{f(r['touchdown_speed_p99_m_s'], '.2f')} | {f(r['miss_p99_m'], '.1f')} | "
            f"{f(r['fuel_gap_p50_pct'], '+.2f')} / {f(r['fuel_gap_p99_pct'], '+.2f')} "
            f"[{r['n_gap']}] | {r['us_per_decision']:.1f} | {fails} |")
    return "\n".join(lines)


def plot_tracks(env_id: str, specs: list[str], path, case: int = 0, seed: int = 2026,
                env_kwargs: dict[str, Any] | None = None):
    """Plot case ``case`` flown by each law: height above the terminal surface against the
    range to go (planar: against the downrange flown) and speed against time; written
    atomically to ``path`` (PNG)."""
    import gymnasium as gym
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import lunar_env  # noqa: F401
    from guidance.frames import pinpoint_frame, planar_frame
    from lunar_env.scenarios import PlanarScenario
    from optimizers.common.checkpoint import save_figure_atomic

    env = gym.make(env_id, **(env_kwargs or {}))
    scenario = env.unwrapped.scenario
    env.close()
    s = scenario.scaling()
    context = LawContext(env_id=env_id, env_kwargs=dict(env_kwargs or {}), scenario=scenario)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
    for spec in specs:
        out = fly(env_id, build_law(spec, context), case + 1, seed=seed, env_kwargs=env_kwargs,
                  record=[case], record_final=True)
        rec = out.records[case]
        y = rec["state_nd"]
        if isinstance(scenario, PlanarScenario):
            f = planar_frame(y, s, scenario.surface_radius_m)
            x_km = (y[:, 2] - y[0, 2]) * scenario.surface_radius_m / 1e3
            xlabel = "downrange flown (km)"
        else:
            f = pinpoint_frame(y, s, np.asarray(scenario.plane_normal()),
                               scenario.target_position_m(), scenario.body.spin_rate_rad_s)
            x_km = np.linalg.norm(f.r_to_target[:, :2], axis=1) / 1e3
            xlabel = "range to the target (km)"
        ok = "landed" if out.is_success[case] else "failed"
        label = f"{spec} ({ok})"
        ax1.plot(x_km, f.height_m / 1e3, label=label)
        ax2.plot(rec["t_s"], np.linalg.norm(f.v, axis=1), label=label)
    if not isinstance(scenario, PlanarScenario):
        ax1.invert_xaxis()
    ax1.set(xlabel=xlabel, ylabel="height above the terminal surface (km)")
    ax2.set(xlabel="time (s)", ylabel="speed relative to the surface (m/s)")
    engine = "throttled" if (env_kwargs or {}).get("throttle_channel") else "constant thrust"
    fig.suptitle(f"{env_id}, {engine}, case {case} (seed {seed})")
    ax1.legend(fontsize=7)
    ax1.grid(alpha=0.3)
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    out_path = save_figure_atomic(fig, path, dpi=110)
    plt.close(fig)
    return out_path


def main(argv: list[str] | None = None) -> int:
    """``python -m research.tools.explicit_measure`` (see the module docstring)."""
    p = argparse.ArgumentParser(prog="python -m research.tools.explicit_measure",
                                description=__doc__.split("\n")[0])
    p.add_argument("--env", default="LunarSoftLanding-v0")
    p.add_argument("--laws", nargs="+", default=["apollo", "zem-zev", "gravity-turn"])
    p.add_argument("--n", type=int, default=1000)
    p.add_argument("--seed", type=int, default=2026)
    p.add_argument("--gap-cases", type=int, default=None,
                   help="cases whose per-case optimum gives the fuel gap (default: all)")
    p.add_argument("--env-kwargs", default=None, help="JSON dict of env arguments")
    p.add_argument("--json", default=None, help="also write the rows to this JSON file")
    p.add_argument("--plot", default=None,
                   help="only plot case 0 of each law to this PNG (no table)")
    args = p.parse_args(argv)
    kw = json.loads(args.env_kwargs) if args.env_kwargs else None
    if kw is not None and not isinstance(kw, dict):
        p.error(f"--env-kwargs {args.env_kwargs!r} must be a JSON object")
    if args.plot:
        written = plot_tracks(args.env, args.laws, args.plot, seed=args.seed, env_kwargs=kw)
        print(f"Written: {written}")
        return 0
    rows = measure(args.env, args.laws, args.n, args.seed, args.gap_cases, kw)
    print(markdown(rows))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
