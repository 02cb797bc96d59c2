"""Paired comparison of two campaigns flown on the same cases: per law, the success rates, the
cases only one of them lands, and McNemar's exact two-sided p-value.

    python research/tools/paired_campaigns.py BEFORE_DIR AFTER_DIR [--law NAME ...]
        [--pair BEFORE_LAW AFTER_LAW ...]

Each directory is a campaign's ``--out`` (its ``cases.csv``). Rows are paired on (law, case);
laws present in both are compared, and each ``--pair`` compares a law of BEFORE with another of
AFTER (e.g. two runs of one recipe).
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from pathlib import Path


def _rows(path: Path, rename: dict[str, str] | None = None) -> dict[tuple[str, int], bool]:
    rename = rename or {}
    with open(path / "cases.csv", newline="") as fh:
        return {(rename.get(r["law"], r["law"]), int(r["case"])): r["success"] == "True"
                for r in csv.DictReader(fh)}


def mcnemar_exact(b: int, c: int) -> float:
    """Two-sided exact McNemar p-value of b and c discordant pairs."""
    n = b + c
    if n == 0:
        return 1.0
    k = min(b, c)
    tail = sum(math.comb(n, i) for i in range(k + 1)) / 2.0 ** n
    return min(1.0, 2.0 * tail)


def compare(before: Path, after: Path, laws=None, pairs: dict[str, str] | None = None
            ) -> list[dict]:
    a, b = _rows(before, pairs), _rows(after)
    names = sorted({law for law, _ in a} & {law for law, _ in b})
    out = []
    for law in names:
        if laws and law not in laws:
            continue
        cases = sorted({c for name, c in a if name == law} & {c for name, c in b if name == law})
        only_a = sum(a[(law, c)] and not b[(law, c)] for c in cases)
        only_b = sum(b[(law, c)] and not a[(law, c)] for c in cases)
        out.append({"law": law, "cases": len(cases),
                    "before": sum(a[(law, c)] for c in cases) / len(cases),
                    "after": sum(b[(law, c)] for c in cases) / len(cases),
                    "only_before": only_a, "only_after": only_b,
                    "p": mcnemar_exact(only_a, only_b)})
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("before", type=Path)
    p.add_argument("after", type=Path)
    p.add_argument("--law", action="append", default=None)
    p.add_argument("--pair", action="append", nargs=2, default=[],
                   metavar=("BEFORE_LAW", "AFTER_LAW"))
    args = p.parse_args(argv)
    pairs = dict(args.pair)
    print(f"{'law':<60s} {'cases':>5s} {'before':>7s} {'after':>7s} {'only b':>6s} "
          f"{'only a':>6s} {'McNemar p':>10s}")
    for r in compare(args.before, args.after, args.law, pairs):
        print(f"{r['law'][:60]:<60s} {r['cases']:5d} {100 * r['before']:6.1f}% "
              f"{100 * r['after']:6.1f}% {r['only_before']:6d} {r['only_after']:6d} "
              f"{r['p']:10.2g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
