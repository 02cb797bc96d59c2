"""Evaluation reports: the Markdown table, the JSON and the trajectory plots.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from optimizers.common.checkpoint import save_figure_atomic

if TYPE_CHECKING:
    from agents.evaluation.result import PolicyResult


def _fmt(x: float, spec: str) -> str:
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def markdown_table(report: dict[str, Any]) -> str:
    """The comparison as a Markdown table (one row per policy)."""
    # a miss-distance column where some law reports one (an env with a landing target)
    has_miss = any(math.isfinite(r["miss_distance_mean_m"]) for r in report["rows"])
    head = ["policy", "cases", "success %", "touchdown speed mean / p95 (m/s)"]
    if has_miss:
        head.append("miss mean (m)")
    head += ["fuel mean (kg)", "gap to optimum (%)", "final-time gap (%)", "score",
             "µs / decision"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in report["rows"]:
        cells = [r["policy"], str(r["n_cases"]), _fmt(100 * r["success_rate"], ".1f"),
                 f"{_fmt(r['touchdown_speed_mean_m_s'], '.2f')} / "
                 f"{_fmt(r['touchdown_speed_p95_m_s'], '.2f')}"]
        if has_miss:
            cells.append(_fmt(r["miss_distance_mean_m"], ".0f"))
        cells += [_fmt(r["fuel_mean_kg"], ".2f"), _fmt(r.get("fuel_gap_pct"), "+.2f"),
                  _fmt(r.get("final_time_gap_pct", float("nan")), "+.2f"),
                  _fmt(r.get("score", float("nan")), ".1f"),
                  _fmt(r["us_per_decision"], ".1f")]
        lines.append("| " + " | ".join(cells) + " |")
    opt = report.get("optimum", {})
    if opt.get("solver"):
        lines.append("")
        lines.append(f"Per-case optimum ({opt['solver']}): {opt['converged']}/"
                     f"{report['n_states']} converged, mean {opt['fuel_mean_kg']:.2f} kg, "
                     f"{opt['wall_s']:.1f} s. Gap: mean over successful cases of "
                     "100·(fuel − optimum)/optimum. Score: mean over cases of "
                     "100·(return − random)/(optimum − random), 0 = uniform-random actions, "
                     "100 = the per-case optimum's replay.")
    return "\n".join(lines)


def _json_report(report: dict[str, Any]) -> dict[str, Any]:
    out = {k: report[k] for k in ("env_id", "seed", "n_states", "env_kwargs", "rows", "optimum")}
    out["per_case"] = {
        r.name: {"success": r.is_success.astype(int).tolist(),
                 "touchdown_speed_m_s": [None if not math.isfinite(v) else v
                                         for v in r.touchdown_speed_m_s.tolist()],
                 "fuel_used_kg": [None if not math.isfinite(v) else v
                                  for v in r.fuel_used_kg.tolist()],
                 "episode_return": [None if not math.isfinite(v) else v
                                    for v in r.episode_return.tolist()]}
        for r in report["results"]}
    sols = report.get("optimal_solutions")
    if sols is not None:
        out["per_case"]["optimum_fuel_kg"] = [float(s.fuel_kg) if s.success else None
                                              for s in sols]
        out["per_case"]["optimum_tf_s"] = [float(s.tf_s) if s.success else None
                                           for s in sols]
    return out


def plot_comparison(report: dict[str, Any], path: str | Path) -> Path:
    """Trajectory (altitude vs downrange) and thrust angle vs time of each policy and the optimum
    for the traced cases; saved as a PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from agents.common.families import family_of

    scenario = report["scenario"]
    family = family_of(scenario)
    results: list[PolicyResult] = report["results"]
    cases = sorted(set().union(*[set(r.traces) for r in results])) if results else []
    if not cases:
        raise ValueError("no traced cases to plot")
    fig, axes = plt.subplots(len(cases), 2, figsize=(12, 3.6 * len(cases)), squeeze=False)
    sols = report.get("optimal_solutions")
    for row, cid in enumerate(cases):
        ax_tr, ax_u = axes[row]
        if sols is not None and getattr(sols[cid], "success", False):
            family.plot_optimum(ax_tr, ax_u, sols[cid], scenario)
        for res in results:
            trace = res.traces.get(cid)
            if trace is None or len(trace["state_nd"]) == 0:
                continue
            family.plot_flight(ax_tr, ax_u, trace, scenario, res.name)
        # a trajectory that passed below the surface (an env failure, reported in the table as
        # no touchdown) must not squash the others: clip the view just below the surface
        tops = [ln.get_ydata().max() for ln in ax_tr.get_lines() if len(ln.get_ydata())]
        if tops:
            hi = 1.05 * max(max(tops), 1e-3)
            ax_tr.set_ylim(-0.05 * hi, hi)
        x_label, y_label, u_label = family.plot_labels
        ax_tr.set_xlabel(x_label)
        ax_tr.set_ylabel(y_label)
        ax_tr.set_title(f"case {cid}: trajectory")
        ax_u.set_xlabel("time (s)")
        ax_u.set_ylabel(u_label)
        ax_u.set_title(f"case {cid}: control")
        ax_tr.grid(alpha=0.3)
        ax_u.grid(alpha=0.3)
        ax_u.legend(fontsize=8)
    fig.tight_layout()
    path = save_figure_atomic(fig, path, dpi=110)
    plt.close(fig)
    return path


def write_report(report: dict[str, Any], out_dir: str | Path) -> dict[str, Path]:
    """Write ``comparison.md``, ``comparison.json`` and ``trajectories.png`` into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    md = markdown_table(report)
    from agents.common.runs import write_text_atomic

    write_text_atomic(out / "comparison.md", md + "\n")
    write_text_atomic(out / "comparison.json", json.dumps(_json_report(report), indent=1))
    paths = {"markdown": out / "comparison.md", "json": out / "comparison.json"}
    try:
        paths["plot"] = plot_comparison(report, out / "trajectories.png")
    except ValueError:
        pass
    return paths




def publish_report(report: dict, out: str | Path, json_path: str | None = None) -> dict:
    """Write the report files to ``out`` (and the JSON to ``json_path``), print the table.

    Returns the written paths.
    """
    paths = write_report(report, out)
    if json_path:
        from agents.common.runs import write_text_atomic

        write_text_atomic(json_path, json.dumps(_json_report(report), indent=1))
    print()
    print(markdown_table(report))
    print()
    print("Written: " + ", ".join(str(p) for p in paths.values()))
    return paths
