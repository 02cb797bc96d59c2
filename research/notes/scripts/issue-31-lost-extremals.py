"""Issue 31: why a pinpoint window-law flight crossed the gate fast; re-flies cases of a campaign
and prints, per case, where the extremal the law flew last converged and how long it then flew
a stale one.

``python research/notes/scripts/issue-31-lost-extremals.py CAMPAIGN_DIR [--cases K ...]
[--law SPEC] [--min-speed V]``

``CAMPAIGN_DIR`` is a campaign's ``--out`` (``campaign.json``, ``cases.csv``) that flew
``--law`` (default: the window law of the thirteenth session,
``feedback:thrust_reserve=0.05,stop_above_m=12,estimate_thrust=1,terminal_window=1``). Without
``--cases`` it re-flies that law's failures that crossed faster than ``--min-speed`` (5.8 m/s:
above the window's band edges) within the env's success miss. Case k is reset seed k at the
campaign's error scale 1 (as the campaign flies it); the re-flown touchdown speed is printed
beside the campaign's, so a changed law or model shows. Per case: the last decision whose
flown engine's extremal converged ("optimal" or "nearest": time, navigated height above the
gate, speed), the decisions after it that flew a stale or braking guess ("stale" /
"fallback"), whether the terminal window flew, and where the last decision was.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

DEFAULT_LAW = "feedback:thrust_reserve=0.05,stop_above_m=12,estimate_thrust=1,terminal_window=1"


class LoggedLaw:
    """The law ``spec`` built once for ``env_id`` (its CasADi window solvers take seconds to
    build), flown case by case with a per-decision log."""

    def __init__(self, env_id: str, env_kwargs: dict, spec: str) -> None:
        import gymnasium as gym
        from agents.common.law_specs import LawContext, build_law

        env = gym.make(env_id, **env_kwargs).unwrapped
        scenario = env.scenario
        self.success_miss_m = float(env.task.success_miss_m)
        self.env_id, self.env_kwargs = env_id, env_kwargs
        self.law = build_law(spec, LawContext(env_id=env_id, env_kwargs=env_kwargs,
                                              scenario=scenario))
        if not hasattr(self.law, "planned"):
            raise ValueError(f"law {spec!r} is not a thrust-reserve law "
                             "(feedback:thrust_reserve=R,...): it has no engines to report")
        self.frame_args = (scenario.scaling(), np.asarray(scenario.plane_normal()),
                           np.asarray(scenario.target_position_m()),
                           float(scenario.body.spin_rate_rad_s))
        self.log: list[tuple] = []
        act = type(self.law).act
        self.law.act = lambda nav: self._logged(act, nav)

    def _logged(self, act, nav):
        from agents.experts.explicit.frames import pinpoint_frame

        law = self.law
        experts = {"reserve": law.planned, "full": law.full, "low": law.low}
        before = dict(law.decisions)
        action = act(law, nav)
        mode = next(k for k, n in law.decisions.items() if n != before[k])
        status = experts[mode].last_status[0] if mode in experts else "-"
        f = pinpoint_frame(nav.state_nd, *self.frame_args)
        self.log.append((float(np.ravel(nav.t_s)[0]), mode, status, float(f.height_m[0]),
                         float(np.linalg.norm(f.v[0]))))
        return action

    def fly(self, uncertainty, case: int) -> tuple[dict, list]:
        """One flight of case ``case`` (reset seed): (outcome, per-decision log of (t s,
        engine flown, its status, navigated height m, speed m/s))."""
        from agents.common.rollout import fly

        self.log = []
        out = fly(self.env_id, self.law, 1, seed=case,
                  env_kwargs={**self.env_kwargs, "uncertainty": uncertainty})
        return {"speed": float(out.touchdown_speed_m_s[0]),
                "miss": float(out.miss_distance_m[0])}, self.log


def main(argv: list[str]) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("campaign_dir", type=Path)
    p.add_argument("--cases", type=int, nargs="+")
    p.add_argument("--law", default=DEFAULT_LAW)
    p.add_argument("--min-speed", type=float, default=5.8)
    args = p.parse_args(argv)
    summary = json.loads((args.campaign_dir / "campaign.json").read_text())
    rows = {int(r["case"]): r for r in csv.DictReader((args.campaign_dir / "cases.csv").open())
            if r["law"] == args.law}
    if not rows:
        p.error(f"law {args.law!r} is not in {args.campaign_dir / 'cases.csv'}")
    from lunar_env.uncertainty import UncertaintyModel
    from optimizers.indirect.pinpoint_feedback import (
        STATUS_FALLBACK,
        STATUS_NEAREST,
        STATUS_OPTIMAL,
        STATUS_STALE,
    )

    flights = LoggedLaw(summary["env"], summary["env_kwargs"], args.law)
    cases = args.cases or [k for k, r in sorted(rows.items())
                           if r["success"] == "False"
                           and float(r["touchdown_speed_m_s"]) > args.min_speed
                           and float(r["miss_distance_m"]) <= flights.success_miss_m]
    model = UncertaintyModel(**summary["uncertainty_model"])
    lost = 0
    for case in cases:
        outcome, log = flights.fly(model, case)
        solved = [k for k, e in enumerate(log) if e[2] in (STATUS_OPTIMAL, STATUS_NEAREST)]
        last = solved[-1] if solved else -1
        stale = sum(e[2] in (STATUS_STALE, STATUS_FALLBACK) for e in log[last + 1:])
        window = any(e[1] == "window" for e in log)
        lost += stale > 0 and (last < 0 or log[last][3] > 100.0)
        t, _, _, h, v = log[last] if last >= 0 else (np.nan,) * 5
        print(f"case {case:4d}: {outcome['speed']:6.2f} m/s (campaign "
              f"{float(rows[case]['touchdown_speed_m_s']):6.2f}), miss {outcome['miss']:4.0f} m;"
              f" last converged {t:4.0f} s, {h:6.0f} m up at {v:5.1f} m/s, then {stale:2d} "
              f"stale of {len(log) - last - 1:2d}; window {'yes' if window else 'no '}; last "
              f"decision {log[-1][3]:6.1f} m up at {log[-1][4]:5.1f} m/s")
    print(f"{lost} of {len(cases)} flew a stale extremal from more than 100 m above the gate")


if __name__ == "__main__":
    main(sys.argv[1:])
