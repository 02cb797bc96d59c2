"""Evaluation reports: the Markdown table, the JSON and the trajectory plots.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from guidance.evaluation.plots import plot_comparison
from optimizers.common.checkpoint import atomic_write_bytes

if TYPE_CHECKING:
    pass


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


def write_report(report: dict[str, Any], out_dir: str | Path) -> dict[str, Path]:
    """Write ``comparison.md``, ``comparison.json`` and ``trajectories.png`` into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    md = markdown_table(report)
    atomic_write_bytes(out / "comparison.md", (md + "\n").encode())
    atomic_write_bytes(out / "comparison.json",
                       json.dumps(_json_report(report), indent=1).encode())
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
        atomic_write_bytes(json_path, json.dumps(_json_report(report), indent=1).encode())
    print()
    print(markdown_table(report))
    print()
    print("Written: " + ", ".join(str(p) for p in paths.values()))
    return paths
