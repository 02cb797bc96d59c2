"""Issue 31: which error of `standard` costs a pinpoint law its landings: leave one out.

``python research/notes/scripts/issue-31-leave-one-out.py LAW... [--cases N] [--env-kwargs JSON]
[--json FILE]``

Flies each law (a campaign spec: ``ppo:RUN``, ``apollo``, ...) on the first N cases (seed 0)
of ``LunarPinpointLanding-v2`` under the full `standard` set, then under the same set with one
error (or group) set to zero: the navigation altitude bias, the thrust error, both, every
navigation error, every plant error (thrust, Isp, misalignment, mass), the entry errors. The
cases are the campaign's (``agents.evaluation.campaign.fly_chunk``: the same resets, the same
law construction): ``UncertaintyModel`` draws the same standard normals whatever the σ, so
each case keeps every other error when one is zeroed, and the full-set row reproduces the
campaign's success rate for those cases (flown in the campaign's chunks of 100). Only the
env's verdict is counted (no omniscient reference is solved: that is the campaign's job), so
a law costs seconds per variant. Prints success % per (law, variant) and writes the table as
JSON (atomically) with ``--json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from agents.evaluation.campaign import fly_chunk

from agents.common.runs import write_text_atomic
from lunar_env.uncertainty import get_uncertainty

ENV_ID = "LunarPinpointLanding-v2"
Z3 = (0.0, 0.0, 0.0)
_STD = get_uncertainty("standard")
#: the variants: changes to `standard` (its fields) that zero one error or group
VARIANTS: dict[str, dict] = {
    "standard": {},
    "no nav alt bias": {"nav_position_bias_m": (0.0, *_STD.nav_position_bias_m[1:])},
    "no thrust err": {"thrust_scale": 0.0},
    "neither": {"nav_position_bias_m": (0.0, *_STD.nav_position_bias_m[1:]),
                "thrust_scale": 0.0},
    "no navigation": {"nav_position_bias_m": Z3, "nav_velocity_bias_m_s": Z3,
                      "nav_position_noise_m": Z3, "nav_velocity_noise_m_s": Z3},
    "no plant": {"thrust_scale": 0.0, "isp_scale": 0.0, "misalignment_rad": 0.0, "mass_kg": 0.0},
    "no entry": {"entry_position_m": Z3, "entry_velocity_m_s": Z3},
}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("laws", nargs="+", help="campaign law specs")
    p.add_argument("--cases", type=int, default=1000)
    # the campaign's chunks: a policy's batched network output differs in its last bits
    # between batch sizes, enough to flip a marginal case
    p.add_argument("--chunk", type=int, default=100)
    p.add_argument("--env-kwargs", default='{"dt_s": 2.0, "throttle_channel": true}')
    p.add_argument("--json", type=Path, default=None)
    args = p.parse_args(argv)
    env_kwargs = json.loads(args.env_kwargs)
    table: dict[str, dict[str, float]] = {}
    print(f"{'law':36s} " + " ".join(f"{v:>15s}" for v in VARIANTS))
    for law in args.laws:
        row = table.setdefault(law, {})
        for name, changes in VARIANTS.items():
            model = _STD.replace(**changes) if changes else _STD
            success = [s for first in range(0, args.cases, args.chunk)
                       for s in fly_chunk(law, ENV_ID, env_kwargs, model.as_dict(), 1.0, first,
                                          min(args.chunk, args.cases - first), 0)["success"]]
            row[name] = 100.0 * float(np.mean(success))
        print(f"{law:36s} " + " ".join(f"{row[v]:15.1f}" for v in VARIANTS), flush=True)
    if args.json:
        out = {"env": ENV_ID, "env_kwargs": env_kwargs, "cases": args.cases,
               "chunk": args.chunk, "seed": 0,
               "variants": {k: {f: list(v) if isinstance(v, tuple) else v
                                for f, v in ch.items()} for k, ch in VARIANTS.items()},
               "success_pct": table}
        write_text_atomic(args.json, json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
