"""Issue 31: does an altitude margin save the pinpoint agents from the navigation altitude bias?

``python research/notes/scripts/issue-31-altitude-margin.py RUN [--margins 0 150 250 350]
[--cases 400] [--uncertainty JSON_OR_NAME] [--json FILE]``

A trained pinpoint policy (``RUN``) lands 89-100 % of the cases whose navigation believes
it *lower* than it is, and 0 % of those that believe it higher by more than ~20 m
(``research/notes/issue-31.md``, "The altitude bias, by sign"). The wrapper law here shifts the
navigated altitude the policy sees down by a margin Δ (and the target's radial offset up by
the same), scaled as the navigation error itself shrinks
(:func:`lunar_env.uncertainty.radar_weight`: 1 above the radar lock altitude, then
``radar_lock_fraction`` × altitude / lock altitude, floored): a law designed for its
sensors that plans for a lander Δ lower than its navigation says until the radar has
measured the altitude. It sees the
navigation solution only (the guidance-law contract). Every margin flies the same cases
(``agents.evaluation.compare.rollout``, case i = sub-env seeded ``seed + i``); the env
decides success.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
from agents.common.law import GuidanceLaw, Navigation

from agents.common.runs import write_text_atomic
from lunar_env.uncertainty import radar_weight, resolve_uncertainty

ENV_ID = "LunarPinpointLanding-v2"
#: bins of the navigation altitude bias (m) for the per-bin success
BIAS_BINS_M = (-400.0, -100.0, -20.0, 20.0, 100.0, 400.0)


class AltitudeMargin(GuidanceLaw):
    """``inner`` flown on observations whose altitude is ``margin_m`` × the navigation error's
    multiplier lower (the target's radial offset as much higher)."""

    def __init__(self, inner: GuidanceLaw, margin_m: float, model) -> None:
        self.inner, self.margin_m, self.model = inner, float(margin_m), model
        self.name = f"{inner.name} margin {margin_m:g} m"

    def reset(self, computer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self.inner.reset(computer, case_ids)
        # the observation is linear in the quantities: one unit of each channel
        unit = computer.decode(np.eye(9))
        self.altitude_per_unit_m = float(unit["altitude_m"][0])
        self.radial_per_unit_m = float(unit["target_radial_m"][1])
        self.gate_altitude_m = float(computer.scenario.target.altitude_m)

    def act(self, nav: Navigation) -> np.ndarray:
        if self.margin_m == 0.0:
            return self.inner.act(nav)
        h = self.computer.decode(nav.obs)["altitude_m"] + self.gate_altitude_m
        delta = self.margin_m * radar_weight(self.model, h)[0]  # the position multiplier
        obs = np.array(nav.obs, dtype=np.float32, copy=True)
        obs[:, 0] -= (delta / self.altitude_per_unit_m).astype(np.float32)
        obs[:, 1] += (delta / self.radial_per_unit_m).astype(np.float32)
        return self.inner.act(replace(nav, obs=obs))


def main(argv: list[str]) -> None:
    from agents.common.sb3_law import SB3Law
    from agents.evaluation.compare import rollout

    from agents.common.runs import read_run

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run")
    ap.add_argument("--margins", type=float, nargs="+", default=[0.0, 150.0, 250.0, 350.0])
    ap.add_argument("--cases", type=int, default=400)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--uncertainty", default="standard",
                    help="a set name or a JSON dict of UncertaintyModel fields")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    unc = args.uncertainty
    unc = json.loads(unc) if unc.lstrip().startswith("{") else unc
    model = resolve_uncertainty(unc)
    hp = read_run(args.run)[1]
    env_kwargs = {**(hp.get("env_kwargs") or {}), "uncertainty": model}
    inner = SB3Law.from_path(Path(args.run), name=Path(args.run).name)
    # each case's navigation altitude bias, drawn as the rollout draws it (nothing flown)
    from agents.evaluation.campaign import _starts

    bias_m = np.asarray(_starts(ENV_ID, env_kwargs, args.cases, args.seed)[2]
                        .nav_position_bias_m)[:, 0]
    edges = list(zip(BIAS_BINS_M[:-1], BIAS_BINS_M[1:], strict=True))
    rows = []
    print(f"{'margin (m)':>10s} {'success':>9s} {'gate v p50':>11s} {'miss p50':>9s} "
          f"{'fuel p50':>9s}   success by altitude bias (m): "
          + " ".join(f"[{lo:g}, {hi:g})" for lo, hi in edges), flush=True)
    for margin in args.margins:
        res = rollout(ENV_ID, AltitudeMargin(inner, margin, model), args.cases, args.seed,
                      env_kwargs, trace_cases=0)
        row = {"margin_m": margin, "cases": args.cases,
               "success_rate": float(np.mean(res.is_success)),
               "gate_speed_p50_m_s": float(np.nanmedian(res.touchdown_speed_m_s)),
               "miss_p50_m": float(np.nanmedian(res.miss_distance_m)),
               "fuel_p50_kg": float(np.nanmedian(res.fuel_used_kg)),
               "success_by_altitude_bias": [
                   {"bias_m": [lo, hi], "cases": int(((bias_m >= lo) & (bias_m < hi)).sum()),
                    "success_rate": float(np.mean(res.is_success[(bias_m >= lo)
                                                                 & (bias_m < hi)]))}
                   for lo, hi in edges if ((bias_m >= lo) & (bias_m < hi)).any()]}
        rows.append(row)
        bins = " ".join(f"{100 * b['success_rate']:.0f}%" for b in row["success_by_altitude_bias"])
        print(f"{margin:10.0f} {100 * row['success_rate']:8.1f}% "
              f"{row['gate_speed_p50_m_s']:11.2f} {row['miss_p50_m']:9.0f} "
              f"{row['fuel_p50_kg']:9.2f}   {bins}", flush=True)
    if args.json:
        out = {"run": str(args.run), "env": ENV_ID, "seed": args.seed,
               "uncertainty": model.as_dict(), "rows": rows}
        write_text_atomic(args.json, json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main(sys.argv[1:])
