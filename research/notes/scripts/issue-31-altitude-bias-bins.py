"""Issue 31: a pinpoint campaign's success by the sign and size of each case's navigation
altitude bias (or its downrange or crossrange position bias).

``python research/notes/scripts/issue-31-altitude-bias-bins.py CAMPAIGN_DIR [--at-gate]
[--axis up|downrange|crossrange]``

``CAMPAIGN_DIR`` is a campaign's ``--out`` (``campaign.json`` and ``cases.csv``). Each case's
navigation position bias is re-drawn as the campaign drew it (a vector env of each chunk's
cases reset with ``seed + first``: :func:`agents.evaluation.campaign._starts`; nothing is
flown), and every law's success rate is printed per bin of the up component (m; navigated
altitude = true altitude + bias). Only campaigns at error scale 1 of their model.
``--at-gate``: the bias where the pinpoint v2 gate is (2 km up, under the radar: the bias times
:func:`lunar_env.uncertainty.radar_weight` there, 1/30 under ``standard``), in bins of metres
there (the terminal's view: a fall from rest crosses below 5 m/s from 0-7.7 m).
``--axis downrange`` / ``crossrange``: bin that component of the bias instead (m; navigated
position = true + bias: a negative downrange bias is a lander further downrange than it
believes, which learns it when the radar locks), in the bins of the altitude's.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

BINS_M = (-400.0, -100.0, -50.0, -20.0, 0.0, 20.0, 50.0, 100.0, 400.0)
GATE_BINS_M = (-30.0, -8.0, -6.0, -4.0, -2.0, 0.0, 2.0, 4.0, 6.0, 8.0, 30.0)
GATE_ALTITUDE_M = 2000.0


AXES = ("up", "downrange", "crossrange")


def position_bias_m(summary: dict, axis: int = 0) -> np.ndarray:
    """Component ``axis`` (0 up, 1 downrange, 2 crossrange) of the navigation position bias (m)
    of every case of a campaign."""
    from agents.evaluation.campaign import _starts

    from lunar_env.uncertainty import UncertaintyModel

    model = UncertaintyModel(**summary["uncertainty_model"])
    kwargs = {**summary["env_kwargs"], "uncertainty": model}
    n, chunk, seed = int(summary["cases"]), int(summary.get("chunk", 100)), int(summary["seed"])
    out = []
    for first in range(0, n, chunk):
        _, _, errors, _ = _starts(summary["env"], kwargs, min(chunk, n - first), seed + first)
        out.append(np.asarray(errors.nav_position_bias_m)[:, axis])
    return np.concatenate(out)


def main(argv: list[str]) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("campaign_dir", type=Path)
    p.add_argument("--at-gate", action="store_true")
    p.add_argument("--axis", choices=AXES, default="up")
    args = p.parse_args(argv)
    if args.at_gate and args.axis != "up":
        p.error("--at-gate bins the altitude bias (--axis up) only")
    at_gate, axis, out_dir = args.at_gate, args.axis, args.campaign_dir
    summary = json.loads((out_dir / "campaign.json").read_text())
    bias = position_bias_m(summary, AXES.index(axis))
    bins = BINS_M
    if at_gate:
        from lunar_env.uncertainty import UncertaintyModel, radar_weight

        model = UncertaintyModel(**summary["uncertainty_model"])
        bias = bias * float(radar_weight(model, np.array([GATE_ALTITUDE_M]))[0][0])
        bins = GATE_BINS_M
    rows = list(csv.DictReader((out_dir / "cases.csv").open()))
    edges = list(zip(bins[:-1], bins[1:], strict=True))
    print(f"{axis + ' bias (m)':23s}" + "".join(f"{f'[{lo:g}, {hi:g})':>13s}" for lo, hi in edges))
    counts = [int(((bias >= lo) & (bias < hi)).sum()) for lo, hi in edges]
    print("cases                  " + "".join(f"{c:>13d}" for c in counts))
    for law in summary["laws"]:
        ok = np.zeros(len(bias), dtype=bool)
        for r in rows:
            if r["law"] == law:
                ok[int(r["case"])] = r["success"] == "True"
        rates = [100.0 * ok[(bias >= lo) & (bias < hi)].mean() for lo, hi in edges]
        print(f"{law[:22]:22s} " + "".join(f"{x:12.0f}%" for x in rates))


if __name__ == "__main__":
    main(sys.argv[1:])
