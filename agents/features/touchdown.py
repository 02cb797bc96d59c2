"""Derived observation features of the pinpoint landing to touchdown (``LunarPinpointLanding-v3``).

The v3 observation already resolves the last metre and the first 500 km (its position and
velocity channels are log-scaled), so the pinpoint family's ``log_altitude``, ``fine_range``
and ``fine_velocity`` would repeat it and are not defined here. What the observation does not
give directly are the braking quantities (each a difference or ratio of channels a network must
otherwise learn to form from logarithms):

- ``stopping_ratio`` (1): log(1 + v²/(2·(F/m)·|d|)), clipped to [0, 8] (≈ log 2 when a
  full-thrust stop along the motion just reaches the target distance);
- ``time_to_go`` (2): full-thrust braking time v/(F/m) and |d|/max(v, 1 m/s), both /100 s,
  clipped to [0, 10];
- ``fuel_margin`` (1): (propellant − m(1 − exp(−v/v_e)))/nominal propellant;
- ``reference_profile`` (7): the lander's deviation from the nominal certified optimum
  (:mod:`optimizers.optimum.touchdown`) at the same along-track offset from the target:
  altitude and cross-track offset / 300 m, the three velocities / 10 m/s, propellant / 10 kg,
  time / 20 s, clipped to ±20 (the pinpoint family's scales);
- ``stop_point`` (4): where a straight-line stop at full thrust (thrust plus gravity against
  the velocity) would end, as the offset target − stop point (up, along, cross) in
  sign·log(1 + |x|/10 m)/8, and that braking time / 100 s.

``d`` is the target − lander offset (up, along, cross; m), ``v`` the speed, ``F`` the full
thrust, ``m`` the mass estimate. Every column is clipped to its bounds (the feature wrapper's
observation space; only unphysical corners of the observation box reach them). The features
are functions of the observation alone (:mod:`agents.features`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from agents.features import FeatureFamily
from agents.features.pinpoint import STOPPING_FEATURES, stopping_columns

__all__ = ["TOUCHDOWN_FEATURE_WIDTHS", "augment_touchdown", "touchdown_feature_bounds",
           "touchdown_reference_profile", "TouchdownFeatures", "REFERENCE_DT_S"]

#: columns added by each feature name for ``LunarPinpointLanding-v3``, in the order appended
TOUCHDOWN_FEATURE_WIDTHS = {"stopping_ratio": 1, "time_to_go": 2, "fuel_margin": 1,
                            "reference_profile": 7, "stop_point": 4}
_BOUNDS = {"stopping_ratio": (0.0, 8.0), "time_to_go": (0.0, 10.0), "fuel_margin": (-2.0, 2.0),
           "reference_profile": (-20.0, 20.0), "stop_point": (-2.0, 10.0)}
#: decision interval (s) of the env replay of the nominal optimum the reference profile is read
#: from: the replay holds each step's mean control, and at 0.25 s its touchdown is within 0.04 m
#: and 0.5 m/s of the optimum's (the largest over 39 dispersed cases), at 1 s 0.7 m and 2.4 m/s
REFERENCE_DT_S = 0.25
#: the reference profile's quantities and the scale of each deviation (the pinpoint family's)
_PROFILE_SCALES = (("altitude_m", 300.0), ("cross_m", 300.0), ("v_along_m_s", 10.0),
                   ("v_cross_m_s", 10.0), ("v_up_m_s", 10.0), ("propellant_kg", 10.0),
                   ("time_s", 20.0))
_PROFILES: dict = {}
#: the env of the touchdown family (the reference profile's replay)
TOUCHDOWN_ENV_ID = "LunarPinpointLanding-v3"


def touchdown_reference_profile(consts: dict) -> dict[str, np.ndarray]:
    """The nominal certified optimum of a touchdown scenario as a function of the along-track
    offset from the target: the optimum from the scenario's nominal start
    (:func:`optimizers.optimum.touchdown.touchdown_optima`, cached on disk) flown open loop in
    the env at :data:`REFERENCE_DT_S` decisions, each state decoded like an observation.

    Returns arrays sorted by ``along_m`` (increasing): the keys of the profile's quantities.
    Cached per scenario.

    Raises
    ------
    RuntimeError
        The nominal optimum is not certified.
    """
    sc = consts["scenario"]
    key = repr(sc)
    if key not in _PROFILES:
        from guidance.flight import fly
        from guidance.laws.touchdown_baselines import TouchdownOpenLoopLaw
        from optimizers.optimum.touchdown import touchdown_ocp, touchdown_optima

        x0 = touchdown_ocp(sc).x0_nd[None]
        opt = touchdown_optima(sc, x0, progress=False)[0]
        if not opt.success:  # pragma: no cover  (measured: certified, 277.58 kg)
            raise RuntimeError(f"no certified nominal optimum for the reference profile: "
                               f"{opt.message}")
        out = fly(TOUCHDOWN_ENV_ID, TouchdownOpenLoopLaw([opt]), 1, seed=0,
                  env_kwargs={"scenario": sc, "dt_s": REFERENCE_DT_S},
                  reset_options={"state_nd": x0}, record=[0])
        rec = out.records[0]
        q = consts["decode"](consts["observation_from_state"](rec["state_nd"], rec["t_s"]))
        order = np.argsort(q["along_m"], kind="stable")
        prof = {k: np.asarray(q[k], dtype=np.float64)[order] for k, _ in _PROFILE_SCALES}
        prof["along_m"] = np.asarray(q["along_m"], dtype=np.float64)[order]
        _PROFILES[key] = prof
    return _PROFILES[key]


def _offsets(q: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Target − lander offset (up, along, cross; m) and velocity (up, along, cross; m/s)."""
    d = -np.stack([q["altitude_m"], q["along_m"], q["cross_m"]], axis=1)
    vel = np.stack([q["v_up_m_s"], q["v_along_m_s"], q["v_cross_m_s"]], axis=1)
    return d, vel


def augment_touchdown(obs: np.ndarray, consts: dict, names: Sequence[str]) -> np.ndarray:
    """The v3 observations (B, n_obs) with the features ``names`` appended (module docstring),
    float32.

    Raises
    ------
    ValueError
        ``obs`` not two-dimensional, or a name that is not a touchdown feature.
    """
    if obs.ndim != 2:
        raise ValueError(f"obs shape {obs.shape}: expected (B, n_obs) touchdown observations")
    for n in names:
        if n not in TOUCHDOWN_FEATURE_WIDTHS:
            raise ValueError(f"obs_features {n!r} is not defined for LunarPinpointLanding-v3 "
                             f"(its observation is log-scaled already); allowed: "
                             f"{sorted(TOUCHDOWN_FEATURE_WIDTHS)}")
    o = obs.astype(np.float64)
    q = consts["decode"](o)
    d, vel = _offsets(q)
    dist = np.sqrt(np.sum(d * d, axis=1))
    speed = np.sqrt(np.sum(vel * vel, axis=1))
    prop = np.maximum(q["propellant_kg"], 0.0)
    m = consts["dry_mass_kg"] + prop
    a_thrust = consts["thrust_n"] / m
    cols: list[np.ndarray] = []
    for name in names:
        if name in STOPPING_FEATURES:
            cols += stopping_columns(name, dist, speed, prop, consts)
        elif name == "reference_profile":
            prof = touchdown_reference_profile(consts)
            for key, scale in _PROFILE_SCALES:
                ref = np.interp(q["along_m"], prof["along_m"], prof[key])
                cols.append(np.clip((q[key] - ref) / scale, -20.0, 20.0))
        elif name == "stop_point":
            r = consts["gate_radius_m"] + q["altitude_m"]
            g = consts["mu_m3_s2"] / (r * r)
            vhat_up = vel[:, 0] / np.maximum(speed, 1e-9)
            k = g * vhat_up + np.sqrt(np.maximum(a_thrust ** 2 - g * g * (1.0 - vhat_up ** 2),
                                                 1e-9))
            tau = speed / np.maximum(k, 1e-9)
            off = d - vel * (0.5 * tau)[:, None]
            cols += [np.sign(off[:, j]) * np.log1p(np.abs(off[:, j]) / 10.0) / 8.0
                     for j in range(3)]
            cols.append(np.clip(tau / 100.0, 0.0, 10.0))
    lo, hi = touchdown_feature_bounds(names)
    feats = np.clip(np.stack(cols, axis=1), lo, hi)  # the wrapper's observation space
    return np.concatenate([o, feats], axis=1).astype(np.float32)


def touchdown_feature_bounds(names: Sequence[str]) -> tuple[list[float], list[float]]:
    """Lower and upper bounds of the columns the features ``names`` add."""
    lo, hi = [], []
    for name in names:
        b = _BOUNDS[name]
        lo += [b[0]] * TOUCHDOWN_FEATURE_WIDTHS[name]
        hi += [b[1]] * TOUCHDOWN_FEATURE_WIDTHS[name]
    return lo, hi


class TouchdownFeatures(FeatureFamily):
    """The touchdown family's observation features (:data:`TOUCHDOWN_FEATURE_WIDTHS`)."""

    widths = dict(TOUCHDOWN_FEATURE_WIDTHS)

    def constants(self, env) -> dict:
        """The scenario and the observation map (the ``reference_profile`` feature)."""
        return {"scenario": env.scenario,
                "observation_from_state": getattr(env, "observation_from_state", None)}

    def augment(self, obs, consts, names) -> np.ndarray:
        return augment_touchdown(obs, consts, names)

    def bounds(self, names) -> tuple[list[float], list[float]]:
        return touchdown_feature_bounds(names)
