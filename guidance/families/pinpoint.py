"""The 3D pinpoint family of guidance (``LunarPinpointLanding-v*``): its (along-track,
cross-track, up) frame and the encoder of thrust commands into the elevation and azimuth
actions."""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial

import numpy as np

from guidance.families import GuidanceFamily
from guidance.frames import LocalFrame, pinpoint_frame
from lunar_env.envs.pinpoint_landing import action_from_angles

__all__ = ["PinpointGuidance", "encode_pinpoint"]


def encode_pinpoint(direction: np.ndarray, throttle: np.ndarray | None, throttled: bool,
                    alpha_bounds_rad: tuple[float, float],
                    beta_bounds_rad: tuple[float, float]) -> np.ndarray:
    """Actions (N, n_act) float32 of thrust directions (N, 3) (along-track, cross-track, up):
    the elevation α above the local horizontal and the azimuth β from +along-track, centred on
    π (braking) so that the bounds' wrap is harmless, clipped to the bounds
    (:func:`lunar_env.envs.pinpoint_landing.action_from_angles`); with a throttle channel
    2·throttle − 1 (throttle clipped to [0, 1]; None: full thrust)."""
    d = np.asarray(direction, dtype=np.float64)
    mag = np.linalg.norm(d, axis=1)
    alpha = np.arcsin(np.clip(d[:, 2] / np.maximum(mag, 1e-300), -1.0, 1.0))
    beta = math.pi + np.arctan2(-d[:, 1], -d[:, 0])
    act = action_from_angles(alpha, beta, alpha_bounds_rad, beta_bounds_rad)
    if throttled:
        thr = np.ones(len(d)) if throttle is None else np.clip(throttle, 0.0, 1.0)
        act = np.concatenate([act, (2.0 * thr - 1.0)[:, None]], axis=1)
    return act.astype(np.float32)


class PinpointGuidance(GuidanceFamily):
    """The pinpoint family (``scenario.family == "pinpoint"``)."""

    n_axes = 3

    def frame_function(self, scenario) -> Callable[[np.ndarray], LocalFrame]:
        return partial(pinpoint_frame, scaling=scenario.scaling(),
                       plane_normal=np.asarray(scenario.plane_normal()),
                       target_m=np.asarray(scenario.target_position_m()),
                       spin_rate_rad_s=float(scenario.body.spin_rate_rad_s))

    def encoder(self, scenario, throttled: bool) -> Callable:
        return partial(encode_pinpoint, throttled=bool(throttled),
                       alpha_bounds_rad=scenario.alpha_bounds_rad,
                       beta_bounds_rad=scenario.beta_bounds_rad)

    def target_radius_m(self, scenario) -> float:
        """The radius of the gate sphere through the target (m)."""
        return float(np.linalg.norm(np.asarray(scenario.target_position_m())))

    def thrust_elevation_bounds_rad(self, scenario) -> tuple[float, float]:
        return tuple(scenario.alpha_bounds_rad)
