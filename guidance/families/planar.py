"""The planar soft-landing family of guidance (``LunarSoftLanding-v0``): its (downrange, up)
frame and the encoder of thrust commands into the thrust-angle action."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import numpy as np

from guidance.families import GuidanceFamily
from guidance.frames import LocalFrame, planar_frame
from lunar_env.envs.soft_landing import action_from_thrust_angle

__all__ = ["PlanarGuidance", "encode_planar"]


def encode_planar(direction: np.ndarray, throttle: np.ndarray | None, throttled: bool
                  ) -> np.ndarray:
    """Actions (N, n_act) float32 of thrust directions (N, 2) (downrange, up): the thrust angle
    φ from the local horizontal (cos φ > 0 brakes, thrusting against +downrange motion), and
    with a throttle channel 2·throttle − 1 (throttle clipped to [0, 1]; None: full thrust)."""
    d = np.asarray(direction, dtype=np.float64)
    act = action_from_thrust_angle(np.arctan2(d[:, 1], -d[:, 0]))[:, None]
    if throttled:
        thr = np.ones(len(d)) if throttle is None else np.clip(throttle, 0.0, 1.0)
        act = np.concatenate([act, (2.0 * thr - 1.0)[:, None]], axis=1)
    return act.astype(np.float32)


class PlanarGuidance(GuidanceFamily):
    """The planar family (``scenario.family == "planar"``)."""

    n_axes = 2

    def frame_function(self, scenario) -> Callable[[np.ndarray], LocalFrame]:
        return partial(planar_frame, scaling=scenario.scaling(),
                       surface_radius_m=float(scenario.surface_radius_m))

    def encoder(self, scenario, throttled: bool) -> Callable:
        return partial(encode_planar, throttled=bool(throttled))

    def target_radius_m(self, scenario) -> float:
        """The landing surface's radius (m)."""
        return float(scenario.surface_radius_m)
