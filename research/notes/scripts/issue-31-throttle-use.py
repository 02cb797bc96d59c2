"""Issue 31: how far below full thrust a throttled pinpoint law flies (its thrust margin).

``python research/notes/scripts/issue-31-throttle-use.py LAW... [--cases N] [--uncertainty SET]``

Flies each law (a campaign spec: ``ppo:RUN``, ``apollo``, ...) on the first N cases (seed 0)
of ``LunarPinpointLanding-v2`` with ``{"dt_s": 2.0, "throttle_channel": true}``, records
every decision (``agents.common.rollout.fly(record=...)``) and prints the throttle it
commanded, ``(a₂ + 1)/2`` of full thrust (the env's mapping): its 5th percentile, median and
95th percentile over all decisions of all cases, and the share of decisions at ≥ 99.5 %.
Laws that plan from the per-case optimum (``open-loop``, ``feedback``) are refused: the
explicit laws and the learned ones are what this measures.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from agents.common.law_specs import LawContext, build_law
from agents.common.rollout import fly

ENV_ID = "LunarPinpointLanding-v2"
ENV_KWARGS = {"dt_s": 2.0, "throttle_channel": True}
#: law names that need the per-case optimum (and the scenario) to be built
PLANNED_LAWS = ("open-loop", "feedback", "convex")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("laws", nargs="+", help="campaign law specs")
    p.add_argument("--cases", type=int, default=40)
    p.add_argument("--uncertainty", default="none", help="none, standard or stress")
    args = p.parse_args(argv)
    planned = [spec for spec in args.laws if spec.split(":")[0] in PLANNED_LAWS]
    if planned:
        p.error(f"{planned}: laws that plan from the per-case optimum are not flown here; "
                f"give ppo:RUN, apollo, zem-zev, ...")
    kwargs = {**ENV_KWARGS, "uncertainty": args.uncertainty}
    ctx = LawContext(env_id=ENV_ID, env_kwargs=dict(ENV_KWARGS), scenario=None,
                     nominal_optimum=None)
    print(f"{'law':36s} success  throttle p5    p50    p95  share >= 99.5 %")
    for spec in args.laws:
        law = build_law(spec, ctx)
        ro = fly(ENV_ID, law, args.cases, seed=0, env_kwargs=kwargs, record=range(args.cases))
        # the env clips a finite action into [-1, 1] before mapping it
        throttle = np.concatenate([(np.clip(ro.records[i]["action"][:, 2], -1.0, 1.0) + 1.0) / 2
                                   for i in range(args.cases)])
        p5, p50, p95 = np.percentile(throttle, [5, 50, 95])
        print(f"{spec:36s} {100 * ro.is_success.mean():6.1f} %  {100 * p5:9.1f} "
              f"{100 * p50:6.1f} {100 * p95:6.1f}  {100 * np.mean(throttle >= 0.995):6.1f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
