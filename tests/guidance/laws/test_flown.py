"""A law with an engine estimate, flying along while another policy flies (a DAgger teacher),
records the throttle the env's engine flew, not its own command (``flown``)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import lunar_env  # noqa: F401  (registers the env ids)
from guidance.flight import fly
from guidance.law import GuidanceLaw
from guidance.registry import LawContext, build_law


class _Stop(Exception):
    pass


@pytest.mark.parametrize("env_id, env_kwargs, spec", [
    ("LunarPinpointLanding-v3", {"dt_s": 2.0, "sensors": ["imu"]}, "zem-zev"),
    ("LunarPinpointLanding-v3", {"dt_s": 2.0, "sensors": ["imu"]}, "apollo"),
    ("LunarPinpointLanding-v3", {"dt_s": 2.0, "sensors": ["imu"]}, "feedback"),
    ("LunarPinpointLanding-v2", {"throttle_channel": True}, "convex"),
])
def test_an_estimating_law_records_the_throttle_flown(env_id, env_kwargs, spec):
    env = gym.make(env_id, **env_kwargs)
    scenario = env.unwrapped.scenario
    env.close()
    law = build_law(spec, LawContext(env_id=env_id, env_kwargs=env_kwargs, scenario=scenario))
    seen = {}

    class Probe(GuidanceLaw):
        """Asks the law, then tells it another policy flew a low throttle (action −0.5)."""

        def reset(self, computer, case_ids):
            super().reset(computer, case_ids)
            law.reset(computer, case_ids)

        def act(self, nav):
            own = law.act(nav)
            other = np.zeros((nav.n, self.computer.action_space.shape[0]), np.float32)
            other[:, -1] = -0.5
            law.flown(nav, other)
            seen.update(own=own, recorded=law.estimator._throttle.copy(),
                        flown=self.computer.controls_from_actions(other.astype(float))[:, -1])
            raise _Stop

    with pytest.raises(_Stop):
        fly(env_id, Probe(), 2, seed=1, env_kwargs=env_kwargs)
    np.testing.assert_allclose(seen["recorded"], seen["flown"])
    assert 0.0 < seen["flown"].max() < 0.6  # a throttle well below the laws' opening command
