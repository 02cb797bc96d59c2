"""Issue 31, tenth session: the reserve law's thrust-acceleration estimate against the truth.

Flies ``feedback:thrust_reserve=R,stop_above_m=4,estimate_thrust=1`` on the first N cases of the
campaign's ``standard`` set (case k: reset seed k, as ``python -m agents.campaign`` draws them)
and compares each lander's final estimate with its true scale: the thrust error times the
navigated over the true mass at the last decision (the model's acceleration uses the navigated
mass). Prints the error percentiles and success by the engine's true scale.

    python research/notes/scripts/issue-31-thrust-estimate.py [N] [R]
"""

from __future__ import annotations

import sys

import gymnasium as gym
import numpy as np
from agents.common.rollout import fly
from agents.experts.pinpoint.expert import PinpointReserveExpert

import lunar_env  # noqa: F401

ENV_ID = "LunarPinpointLanding-v2"


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 50
    reserve = float(sys.argv[2]) if len(sys.argv) > 2 else 0.05
    env_kwargs = {"dt_s": 2.0, "throttle_channel": True, "uncertainty": "standard"}
    sc = gym.make(ENV_ID).unwrapped.scenario
    law = PinpointReserveExpert(sc, reserve, stop_above_m=4.0, estimate_thrust=True)
    out = fly(ENV_ID, law, n, seed=0, env_kwargs=env_kwargs, record=range(n))
    thrust = out.episode_errors.thrust_scale
    mass_ratio = np.array([out.records[i]["navigation_state_nd"][-1, 6]
                           / out.records[i]["state_nd"][-1, 6] for i in range(n)])
    truth = thrust * mass_ratio
    err = 100.0 * (law.estimator.scale - truth)
    print(f"{n} cases, reserve {reserve}: success {100 * out.is_success.mean():.1f} %")
    print("estimate - truth (points of %): p5 / p50 / p95 / max |.| = "
          + " / ".join(f"{v:+.3f}" for v in np.percentile(err, [5, 50, 95]))
          + f" / {np.abs(err).max():.3f}; thrust error alone: p5 / p95 "
          + " / ".join(f"{100 * (v - 1):+.2f}" for v in np.percentile(thrust, [5, 95])))
    print("decisions by engine:", law.decisions)
    for lo, hi in ((0.0, 0.98), (0.98, 1.02), (1.02, 9.0)):
        m = (truth >= lo) & (truth < hi)
        if m.any():
            print(f"true scale [{lo}, {hi}): {m.sum()} cases, "
                  f"{100 * out.is_success[m].mean():.0f} % landed")


if __name__ == "__main__":
    main()
