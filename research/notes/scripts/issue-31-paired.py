"""Issue 31: two laws paired on a campaign's cases, and each law's landings by engine error.

``python research/notes/scripts/issue-31-paired.py CASES_CSV [--pairs 'A|B' ...] [--laws LAW ...]
[--scale S]``

Reads a campaign's ``cases.csv`` (``python -m agents.campaign ... --out DIR`` writes
``DIR/cases.csv``; law names as its ``law`` column, e.g. ``ppo:thr4_ctrl_126M_s1``) and prints

- per law, the success rate of the cases whose thrust draw is more than 1σ weak (below 0.98 of
  nominal: `standard`'s σ is 2 %), within 1σ, and more than 1σ strong;
- per pair ``A|B``, the discordant cases (only A lands / only B lands) and McNemar's exact
  test on them (two-sided binomial test at 1/2), the paired comparison of the notes.

``--scale S`` pairs the flights of the robustness curve's scale S instead (every error × S,
on the curve's cases), read from the campaign's store beside ``CASES_CSV`` (``DIR/store``);
the engine bins are then left out (``cases.csv`` holds the × 1 draws).
"""

from __future__ import annotations

import argparse
import csv
import json
from collections import defaultdict
from pathlib import Path

from scipy.stats import binomtest

from lunar_env.uncertainty import get_uncertainty
from optimizers.common.executor import ResultStore, TaskKey

THRUST_SIGMA = get_uncertainty("standard").thrust_scale


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("cases_csv", type=Path)
    p.add_argument("--pairs", nargs="*", default=[],
                   help="LAW_A|LAW_B (law names hold ':', so '|' separates them)")
    p.add_argument("--laws", nargs="*", default=None, help="laws to bin (default: all)")
    p.add_argument("--scale", type=float, default=1.0,
                   help="pair the curve's flights at this error scale (from DIR/store)")
    args = p.parse_args(argv)
    success: dict[str, dict[int, bool]] = defaultdict(dict)
    thrust: dict[int, float] = {}
    with args.cases_csv.open() as f:
        for row in csv.DictReader(f):
            case = int(row["case"])
            success[row["law"]][case] = row["success"] == "True"
            thrust[case] = float(row["thrust_scale"])
    source = str(args.cases_csv)
    if args.scale == 1.0:
        _print_engine_bins(success, thrust, args.laws or sorted(success), source)
    else:
        success = _curve_success(args.cases_csv.parent, sorted(success), args.scale)
        source = f"{args.cases_csv.parent / 'store'} at scale {args.scale:g}"
    for pair in args.pairs:
        a, sep, b = pair.partition("|")
        if not sep or a not in success or b not in success:
            raise SystemExit(f"pair {pair!r}: give two laws of {source} as 'A|B'; it has: "
                             f"{', '.join(sorted(success))}")
        only_a = sum(success[a][c] and not success[b][c] for c in success[a])
        only_b = sum(success[b][c] and not success[a][c] for c in success[a])
        pvalue = binomtest(only_a, only_a + only_b).pvalue if only_a + only_b else 1.0
        print(f"{a} vs {b}: only the first lands {only_a}, only the second {only_b}, "
              f"McNemar p = {pvalue:.2g}")
    return 0


def _print_engine_bins(success: dict[str, dict[int, bool]], thrust: dict[int, float],
                       laws: list[str], source: str) -> None:
    """Per law, the success rate by the drawn thrust error: > 1σ weak, within, > 1σ strong."""
    bins = {"weak > 1σ": lambda t: t < 1.0 - THRUST_SIGMA,
            "within 1σ": lambda t: abs(t - 1.0) <= THRUST_SIGMA,
            "strong > 1σ": lambda t: t > 1.0 + THRUST_SIGMA}
    print(f"{'law':32s} " + " ".join(f"{b:>14s}" for b in bins))
    for law in laws:
        if law not in success:
            raise SystemExit(f"law {law!r} is not in {source}; it has: "
                             f"{', '.join(sorted(success))}")
        cells = []
        for test in bins.values():
            hits = [s for c, s in success[law].items() if test(thrust[c])]
            cells.append(f"{100.0 * sum(hits) / len(hits):7.1f} % ({len(hits)})")
        print(f"{law:32s} " + " ".join(f"{c:>14s}" for c in cells))


def _curve_success(out_dir: Path, laws: list[str], scale: float) -> dict[str, dict[int, bool]]:
    """Per law, case -> landed, for the curve's flights at ``scale`` in ``out_dir/store``."""
    from guidance.campaign.run import scale_text

    summary = json.loads((out_dir / "campaign.json").read_text())
    seed = summary["seed"]
    store = ResultStore.existing(out_dir / "store")
    success: dict[str, dict[int, bool]] = {}
    for law in laws:
        # the law's tasks: its label and fingerprint, the scale, the cases flown at it
        fingerprint = summary.get("law_identity", {}).get(law, {}).get("fingerprint", "")
        n = summary["cases"] if scale == 1.0 else next(
            (p["cases"] for p in summary["robustness_curve"].get(law, ())
             if p["scale"] == scale), 0)
        problem = f"{law}#{fingerprint}@x{scale_text(scale)}/n{n}"
        k, rows = 0, {}
        while (key := TaskKey(problem, seed, k)) in store:
            part = store.get(key)
            cases, landed = part["case"], part["success"]
            rows.update({int(c): bool(s) for c, s in zip(cases, landed, strict=True)})
            k += 1
        if rows:
            success[law] = rows
    if not success:
        raise SystemExit(f"no flights at scale {scale:g} in {out_dir / 'store'}")
    return success


if __name__ == "__main__":
    raise SystemExit(main())
