"""The touchdown family of guidance (``LunarPinpointLanding-v3``): the pinpoint family's
(along-track, cross-track, up) frame, and the encoder of thrust commands into v3's elevation,
azimuth and throttle actions (the throttle mapped onto the engine's [throttle_min, 1])."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import numpy as np

from guidance.families.pinpoint import PinpointGuidance, encode_pinpoint
from lunar_env.envs.pinpoint_touchdown import action_from_throttle

__all__ = ["TouchdownGuidance", "encode_touchdown"]


def encode_touchdown(direction: np.ndarray, throttle: np.ndarray | None,
                     alpha_bounds_rad: tuple[float, float], beta_bounds_rad: tuple[float, float],
                     throttle_min: float) -> np.ndarray:
    """Actions (N, 3) float32 of thrust directions (N, 3) (along-track, cross-track, up) and
    throttles (N,) (fractions of full thrust; None: full thrust): the angles as the pinpoint
    family encodes them (:func:`~guidance.families.pinpoint.encode_pinpoint`), the throttle by
    :func:`lunar_env.envs.pinpoint_touchdown.action_from_throttle` (a command below the
    engine's floor gets the floor)."""
    act = encode_pinpoint(direction, None, False, alpha_bounds_rad, beta_bounds_rad)
    thr = np.ones(len(act)) if throttle is None else np.asarray(throttle, dtype=np.float64)
    return np.concatenate([act, action_from_throttle(thr, throttle_min)[:, None]],
                          axis=1).astype(np.float32)


class TouchdownGuidance(PinpointGuidance):
    """The touchdown family (``scenario.family == "pinpoint_touchdown"``): the pinpoint frame
    (the target on the surface, so the frame's height is the altitude above it); the episode
    ends at touchdown on that site."""

    lands_on_site = True

    def encoder(self, scenario, throttled: bool = True) -> Callable:
        """The v3 encoder; its actions always carry the throttle (v3's engine throttles, so
        ``throttled`` changes nothing)."""
        return partial(encode_touchdown, alpha_bounds_rad=scenario.alpha_bounds_rad,
                       beta_bounds_rad=scenario.beta_bounds_rad,
                       throttle_min=float(scenario.throttle_min))
