"""Median true horizontal and vertical speed of a law's landers where they first cross each
height (m), split by success:

    python research/notes/scripts/issue-56-height-profile.py SPEC ENV_KWARGS_JSON N [SEED]
"""

import json
import sys

import gymnasium as gym
import numpy as np

from guidance.flight import fly
from guidance.registry import LawContext, build_law

ENV_ID = "LunarPinpointLanding-v3"
HEIGHTS_M = (1000, 500, 300, 200, 100, 50, 30, 15, 5)


def main() -> None:
    spec, env_kwargs, n = sys.argv[1], json.loads(sys.argv[2]), int(sys.argv[3])
    seed = int(sys.argv[4]) if len(sys.argv) > 4 else 0
    env = gym.make(ENV_ID, **env_kwargs).unwrapped
    law = build_law(spec, LawContext(env_id=ENV_ID, env_kwargs=env_kwargs,
                                     scenario=env.scenario))
    out = fly(ENV_ID, law, n, seed=seed, env_kwargs=env_kwargs, record=range(n))
    rows: dict[int, list] = {h: [] for h in HEIGHTS_M}
    for i, rec in out.records.items():
        y = rec["state_nd"]
        q = env.observation_quantities(env.task.observation_of_states(y, np.zeros(len(y))))
        v_h = np.hypot(q["v_along_m_s"], q["v_cross_m_s"])
        for h in HEIGHTS_M:
            below = np.flatnonzero(q["altitude_m"] < h)
            if len(below):
                k = below[0]
                rows[h].append((v_h[k], q["v_up_m_s"][k], out.is_success[i]))
    print(spec, "success", out.is_success.mean())
    for h in HEIGHTS_M:
        a = np.array(rows[h])
        if not len(a):
            continue
        won = a[:, 2] > 0
        print(f"h < {h:5d} m: v_h p50 {np.median(a[:, 0]):6.2f} p90 "
              f"{np.percentile(a[:, 0], 90):6.2f} | v_up p50 {np.median(a[:, 1]):7.2f} | "
              f"v_h p50 landed {np.median(a[won, 0]) if won.any() else np.nan:6.2f} "
              f"failed {np.median(a[~won, 0]) if (~won).any() else np.nan:6.2f}")


if __name__ == "__main__":
    main()
