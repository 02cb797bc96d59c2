"""Issue 31: a campaign's robustness curves with the seeds of one configuration drawn together.

``python research/notes/scripts/issue-31-grouped-curve.py JSON[,JSON...] OUT_PNG GROUP=PREFIX ...``

Each ``GROUP=PREFIX`` draws, in one colour and under the label ``GROUP``, every law of the
campaign JSON (``python -m agents.campaign --json``) whose name starts with ``PREFIX``; the
laws no prefix matches are left out. A campaign's own plot (``robustness.png``) draws one
colour per law, which repeats after ten laws. Several campaign JSONs (comma-separated; of
one env and one uncertainty set, e.g. a throttled and an unthrottled campaign of the same
cases) are drawn together; a law name in two of them is refused.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def grouped_curves(summary: dict, groups: list[tuple[str, str]]) -> dict[str, list[list]]:
    """For each group label, the (scales, success %) of every law whose name starts with the
    group's prefix. Raises ``ValueError`` for a prefix that matches no law."""
    curves = summary["robustness_curve"]
    out: dict[str, list[list]] = {}
    for label, prefix in groups:
        laws = [name for name in curves if name.startswith(prefix)]
        if not laws:
            raise ValueError(f"group {label}={prefix!r} matches no law of {sorted(curves)}")
        out[label] = [[[p["scale"] for p in curves[name]],
                       [100.0 * p["success_rate"] for p in curves[name]]] for name in laws]
    return out


def merged_summaries(summaries: list[dict]) -> dict:
    """One summary whose robustness curves are those of every summary given. Raises
    ``ValueError`` for summaries of different envs or uncertainty sets, or a law in two."""
    first = summaries[0]
    curves: dict[str, list] = {}
    for s in summaries:
        if (s["env"], s["uncertainty"]) != (first["env"], first["uncertainty"]):
            raise ValueError(f"campaigns of {s['env']} / {s['uncertainty']!r} and "
                             f"{first['env']} / {first['uncertainty']!r} cannot share a plot")
        for name, curve in s["robustness_curve"].items():
            if name in curves:
                raise ValueError(f"law {name!r} is in two of the campaigns")
            curves[name] = curve
    return {**first, "robustness_curve": curves}


def main(argv: list[str]) -> None:
    if len(argv) < 3:
        raise SystemExit(__doc__)
    summary = merged_summaries([json.loads(Path(p).read_text()) for p in argv[0].split(",")])
    groups = []
    for item in argv[2:]:
        label, eq, prefix = item.partition("=")
        if not eq or not label or not prefix:
            raise SystemExit(f"{item!r} is not GROUP=PREFIX")
        groups.append((label, prefix))
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for k, (label, lines) in enumerate(grouped_curves(summary, groups).items()):
        for i, (scales, success) in enumerate(lines):
            ax.plot(scales, success, "o-", color=f"C{k}", alpha=0.8, ms=3,
                    label=f"{label} ({len(lines)})" if i == 0 else None)
    n = next(iter(summary["robustness_curve"].values()))[0]["cases"]
    ax.set_xlabel(f"error scale (× '{summary['uncertainty']}')")
    ax.set_ylabel(f"success (%, {n} cases per point)")
    ax.set_title(summary["env"])
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    out = Path(argv[1])
    fd, tmp = tempfile.mkstemp(suffix=".png", dir=out.parent)
    os.close(fd)
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, out)
    print(out)


if __name__ == "__main__":
    main(sys.argv[1:])
