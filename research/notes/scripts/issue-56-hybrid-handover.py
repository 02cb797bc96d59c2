"""The PPO above H m of navigated height, phased ZEM/ZEV below (both asked every decision),
200 `standard` cases of seed 0 at 2 s decisions with the IMU channels:

    python research/notes/scripts/issue-56-hybrid-handover.py ppo:RUN H [H ...]
"""

import sys

import gymnasium as gym
import numpy as np

from guidance.flight import fly
from guidance.law import GuidanceLaw, actions_of
from guidance.registry import LawContext, build_law

ENV_ID = "LunarPinpointLanding-v3"
ENV_KWARGS = {"dt_s": 2.0, "sensors": ["imu"], "uncertainty": "standard"}


class Handover(GuidanceLaw):
    """``upper`` until a lander's navigated height first falls below ``height_m``, then
    ``lower``; both laws see every decision, so the lower one's memory (phase, engine
    estimate) is that of the whole flight."""

    name = "handover"

    def __init__(self, upper, lower, height_m: float) -> None:
        self.upper, self.lower, self.height_m = upper, lower, height_m

    def reset(self, computer, case_ids):
        super().reset(computer, case_ids)
        self.upper.reset(computer, case_ids)
        self.lower.reset(computer, case_ids)
        self.switched = np.zeros(len(case_ids), dtype=bool)

    def act(self, nav):
        a_up = actions_of(self.computer, self.upper.act(nav))
        a_low = actions_of(self.computer, self.lower.act(nav))
        self.switched[nav.episode_start] = False
        self.switched |= nav.frame.height_m < self.height_m
        return np.where(self.switched[:, None], a_low, a_up)


def main() -> None:
    scenario = gym.make(ENV_ID, **ENV_KWARGS).unwrapped.scenario
    ctx = LawContext(env_id=ENV_ID, env_kwargs=ENV_KWARGS, scenario=scenario)
    for h in (float(x) for x in sys.argv[2:]):
        law = Handover(build_law(sys.argv[1], ctx), build_law("zem-zev", ctx), h)
        out = fly(ENV_ID, law, 200, seed=0, env_kwargs=ENV_KWARGS)
        print(f"below {h:6.0f} m: success {100 * out.is_success.mean():5.1f} %, "
              f"fuel p50 {np.median(out.fuel_used_kg):.1f} kg", flush=True)


if __name__ == "__main__":
    main()
