"""Derived observation features of the planar soft landing (``LunarSoftLanding-v0``), answered
for :mod:`agents.features` by :class:`guidance.families.planar.PlanarFamily`.

Why: ``LunarSoftLanding-v0`` observes altitude / 15 km, radial speed / 169 m/s and horizontal
speed / 1.69 km/s (:mod:`lunar_env.envs.soft_landing`). Those scales suit the start of the
descent, but the last few hundred metres and tens of m/s — where a touchdown speed of 5 m/s is
won or lost — occupy a few thousandths of the input range. A steer-only, constant-thrust lander
must also judge *when* braking has to win over gravity: the key quantity is the ratio of the
distance needed to stop to the altitude left. The features below give the network these
quantities directly.

Feature names (YAML key ``obs_features``; each adds the columns listed, in this order):

``log_altitude``
    log10(1 + h / 1 m) / 4.2 (h: altitude above the surface; 15 km → ~1).
``fine_velocity``
    sign(v)·log(1 + |v| / 1 m/s) / 7 for the radial and then the horizontal velocity (2 columns):
    1 m/s and 1 km/s are both resolved.
``stopping_ratio``
    log(1 + v² / (2·a_net·h)), clipped to [0, 8], with v the speed, a_net = max(F/m − g, 0.05
    m/s²) the net braking acceleration if all thrust opposed gravity and the motion, and h
    clipped below at 1 m: ~log 2 when a full-thrust stop just reaches the ground. Decision: the
    ratio uses the total speed (horizontal braking is also paid against the altitude budget,
    since the thrust that brakes horizontally does not hold the lander up).
``time_to_go``
    Two columns: the full-thrust braking time v / (F/m) and the time to reach the ground at the
    current sink rate h / max(−v_r, 1 m/s), both / 100 s and clipped to [0, 10].
``fuel_margin``
    (propellant left − propellant to cancel the speed at full thrust, m·(1 − exp(−v / v_e)))
    / nominal propellant: the margin the remaining descent can spend on gravity losses.

Mass m = dry mass + propellant fraction × nominal propellant; g = μ / R_surface² (the scenario's
scaling: 1.62 m/s² for the Moon). All features are finite for every observation in the env's
observation box (tested).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from agents.features import FeatureFamily

__all__ = ["PLANAR_FEATURE_WIDTHS", "augment_planar", "planar_feature_bounds"]

#: columns added by each feature name, in the order they are appended
PLANAR_FEATURE_WIDTHS = {"log_altitude": 1, "fine_velocity": 2, "stopping_ratio": 1,
                         "time_to_go": 2, "fuel_margin": 1}


def augment_planar(obs: np.ndarray, consts: dict, names: Sequence[str]) -> np.ndarray:
    """Append the features ``names`` to soft-landing observations.

    Parameters
    ----------
    obs : ndarray, shape (B, 5) or (B, 5 + sensor channels)
        ``LunarSoftLanding-v0`` observations (altitude/h₀, v_r/(0.1 v₀), v_t/v₀, propellant
        fraction, time fraction).
    consts : dict
        :func:`agents.features.feature_constants` of the env.
    names : sequence of str
        Feature names (:data:`PLANAR_FEATURE_WIDTHS`), at least one.

    Returns
    -------
    ndarray, shape (B, 5 + Σ widths), float32
    """
    if obs.ndim != 2 or obs.shape[1] < 5:
        raise ValueError(f"obs shape {obs.shape}: expected (B, 5) soft-landing observations, or "
                         "(B, 5 + sensor channels)")
    o = obs.astype(np.float64)
    q = consts["decode"](o)  # the env's own inverse of its observation
    h = q["altitude_m"]
    vr = q["radial_velocity_m_s"]
    vt = q["tangential_velocity_m_s"]
    prop = np.maximum(q["propellant_kg"], 0.0)
    m = consts["dry_mass_kg"] + prop
    speed = np.hypot(vr, vt)
    a_thrust = consts["thrust_n"] / m
    cols: list[np.ndarray] = []
    for name in names:
        if name == "log_altitude":
            cols.append(np.log10(1.0 + np.maximum(h, 0.0)) / 4.2)
        elif name == "fine_velocity":
            cols.append(np.sign(vr) * np.log1p(np.abs(vr)) / 7.0)
            cols.append(np.sign(vt) * np.log1p(np.abs(vt)) / 7.0)
        elif name == "stopping_ratio":
            a_net = np.maximum(a_thrust - consts["gravity_m_s2"], 0.05)
            ratio = speed ** 2 / (2.0 * a_net * np.maximum(h, 1.0))
            cols.append(np.clip(np.log1p(ratio), 0.0, 8.0))
        elif name == "time_to_go":
            cols.append(np.clip(speed / a_thrust / 100.0, 0.0, 10.0))
            cols.append(np.clip(np.maximum(h, 0.0) / np.maximum(-vr, 1.0) / 100.0, 0.0, 10.0))
        elif name == "fuel_margin":
            need = m * -np.expm1(-speed / consts["exhaust_velocity_m_s"])
            cols.append((prop - need) / consts["prop_nominal_kg"])
        else:  # validate_features guards this
            raise ValueError(f"unknown feature {name!r}")
    out = np.concatenate([o, np.stack(cols, axis=1)], axis=1)
    return out.astype(np.float32)


def planar_feature_bounds(names: Sequence[str]) -> tuple[list[float], list[float]]:
    """Lower and upper bounds of the columns the features ``names`` add (the observation space
    of :class:`agents.features.ObsFeatureWrapper`)."""
    lo, hi = [], []
    for name in names:
        if name == "log_altitude":
            lo += [0.0]
            hi += [2.0]
        elif name == "fine_velocity":
            lo += [-2.0, -2.0]
            hi += [2.0, 2.0]
        elif name == "stopping_ratio":
            lo += [0.0]
            hi += [8.0]
        elif name == "time_to_go":
            lo += [0.0, 0.0]
            hi += [10.0, 10.0]
        elif name == "fuel_margin":
            lo += [-2.0]
            hi += [2.0]
    return lo, hi


class PlanarFeatures(FeatureFamily):
    """The planar family's observation features (:data:`PLANAR_FEATURE_WIDTHS`)."""

    widths = dict(PLANAR_FEATURE_WIDTHS)

    def augment(self, obs, consts, names) -> np.ndarray:
        return augment_planar(obs, consts, names)

    def bounds(self, names) -> tuple[list[float], list[float]]:
        return planar_feature_bounds(names)
