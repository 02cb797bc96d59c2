"""Derived observation features of the 3D pinpoint landing (``LunarPinpointLanding-v*``),
answered for :mod:`agents.features` by
:class:`guidance.families.pinpoint.PinpointFamily` (the feature names and their reasons:
:func:`augment_pinpoint`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from agents.features import FeatureFamily

__all__ = ["PINPOINT_FEATURE_WIDTHS", "augment_pinpoint", "pinpoint_feature_bounds",
           "pinpoint_feature_constants", "reference_profile", "straight_line_stop"]

#: columns added by each feature name for ``LunarPinpointLanding-v*`` (9 observations), in the
#: order they are appended
PINPOINT_FEATURE_WIDTHS = {"log_altitude": 1, "fine_range": 3, "fine_velocity": 3,
                           "stopping_ratio": 1, "time_to_go": 2, "fuel_margin": 1,
                           "reference_profile": 7, "stop_point": 4}

#: bounds of each feature's columns (the observation space of the feature wrapper)
_BOUNDS = {"log_altitude": (0.0, 2.0), "fine_range": (-2.0, 2.0),
           "fine_velocity": (-2.0, 2.0), "stopping_ratio": (0.0, 8.0),
           "time_to_go": (0.0, 10.0), "fuel_margin": (-2.0, 2.0),
           "reference_profile": (-20.0, 20.0), "stop_point": (-2.0, 10.0)}



#: the features of a braking lander's stop, shared by the 3D families (:func:`stopping_columns`)
STOPPING_FEATURES = ("stopping_ratio", "time_to_go", "fuel_margin")


def stopping_columns(name: str, dist_m: np.ndarray, speed_m_s: np.ndarray,
                     propellant_kg: np.ndarray, consts: dict) -> list[np.ndarray]:
    """The columns of the feature ``name`` (one of :data:`STOPPING_FEATURES`) of landers
    ``dist_m`` from the target at ``speed_m_s`` with ``propellant_kg`` (clipped at 0), the
    engine of ``consts`` (``dry_mass_kg``, ``thrust_n``, ``exhaust_velocity_m_s``,
    ``prop_nominal_kg``): the log stopping ratio v²/(2 a d); the time to stop v/a and to reach
    the target d/v (100 s units); the propellant left after the rocket equation's Δv = v, over
    the nominal propellant."""
    m = consts["dry_mass_kg"] + propellant_kg
    a_thrust = consts["thrust_n"] / m
    if name == "stopping_ratio":
        ratio = speed_m_s ** 2 / (2.0 * a_thrust * np.maximum(dist_m, 1.0))
        return [np.clip(np.log1p(ratio), 0.0, 8.0)]
    if name == "time_to_go":
        return [np.clip(speed_m_s / a_thrust / 100.0, 0.0, 10.0),
                np.clip(dist_m / np.maximum(speed_m_s, 1.0) / 100.0, 0.0, 10.0)]
    if name == "fuel_margin":
        need = m * -np.expm1(-speed_m_s / consts["exhaust_velocity_m_s"])
        return [(propellant_kg - need) / consts["prop_nominal_kg"]]
    raise ValueError(f"{name!r} is not one of {STOPPING_FEATURES}")

def pinpoint_feature_constants(env) -> dict:
    """What the pinpoint features need besides the env's physical constants and decoding: the
    scenario and the observation map (for :func:`reference_profile`)."""
    return {"scenario": env.scenario,
            "observation_from_state": getattr(env, "observation_from_state", None)}


#: nominal optimal profiles by scenario (see :func:`reference_profile`)
_PROFILES: dict = {}


def reference_profile(consts: dict) -> dict[str, np.ndarray]:
    """The nominal minimum-fuel descent of a pinpoint scenario as a function of the along-track
    distance to the target: the Pontryagin extremal from the scenario's nominal start
    (:mod:`optimizers.indirect.pinpoint_feedback`, every 0.5 s), decoded like an observation.

    Returns arrays sorted by ``along_m`` (increasing): ``altitude_m``, ``target_cross_m``,
    ``u_m_s``, ``v_m_s``, ``w_m_s``, ``propellant_kg``, ``time_s``. Cached per scenario.
    """
    sc = consts["scenario"]
    key = repr(sc)
    if key not in _PROFILES:
        from optimizers.indirect.pinpoint_feedback import (
            PinpointFeedback,
            extremal_path,
            solve_extremal,
        )

        fb = PinpointFeedback(sc)
        x0 = sc.state_nd(scaling=sc.scaling())
        # solved and integrated on the same 0.5 s grid: the shooting's endpoint is sensitive
        # to the grid (the first ~20 s fly the α bound), so a path integrated on another grid
        # than its solve misses the target by metres
        sol = solve_extremal(fb.k, x0, fb.nominal_costates(), step_s=0.5)
        if not sol.converged:  # pragma: no cover  (measured: converges in 2 iterations)
            raise RuntimeError("no nominal extremal for the reference profile")
        t, path = extremal_path(fb.k, x0, sol.z, step_s=0.5)
        to_obs = consts["observation_from_state"]
        q = consts["decode"](to_obs(path[:, :7], t))
        order = np.argsort(q["target_along_m"])
        prof = {k: np.asarray(q[k], dtype=np.float64)[order]
                for k in ("altitude_m", "target_cross_m", "u_m_s", "v_m_s", "w_m_s",
                          "propellant_kg")}
        prof["time_s"] = t[order]
        prof["along_m"] = np.asarray(q["target_along_m"], dtype=np.float64)[order]
        _PROFILES[key] = prof
    return _PROFILES[key]


def straight_line_stop(q: dict[str, np.ndarray], consts: dict) -> tuple[np.ndarray, np.ndarray]:
    """Where a straight-line stop of a pinpoint lander would end.

    Thrust plus gravity antiparallel to the velocity: net deceleration k from |k v̂ − g| = F/m
    (g radial, down), stop after τ = v/k at r + v τ/2. ``q``: decoded observations
    (``observation_quantities``). Returns the offset target − stop point (radial, along,
    cross; m), shape (B, 3), and τ (s), shape (B,).
    """
    d = np.stack([q["target_radial_m"], q["target_along_m"], q["target_cross_m"]], axis=1)
    vel = np.stack([q["u_m_s"], q["v_m_s"], q["w_m_s"]], axis=1)
    speed = np.sqrt(np.sum(vel * vel, axis=1))
    m = consts["dry_mass_kg"] + np.maximum(q["propellant_kg"], 0.0)
    a_thrust = consts["thrust_n"] / m
    r = consts["gate_radius_m"] + q["altitude_m"]
    g = consts["mu_m3_s2"] / (r * r)
    vhat_r = vel[:, 0] / np.maximum(speed, 1e-9)
    k = g * vhat_r + np.sqrt(np.maximum(a_thrust ** 2 - g * g * (1.0 - vhat_r ** 2), 1e-9))
    tau = speed / np.maximum(k, 1e-9)
    return d - vel * (0.5 * tau)[:, None], tau


def augment_pinpoint(obs: np.ndarray, consts: dict, names: Sequence[str]) -> np.ndarray:
    """Pinpoint features (``LunarPinpointLanding-v*`` observations (B, 9)).

    ``log_altitude`` log10(1 + h/1 m)/4.2 (h above the gate); ``fine_range`` sign·log(1 +
    |d|/1 m)/13 of the target − lander components (radial, along, cross: 1 m and 500 km both
    resolved); ``fine_velocity`` sign·log(1 + |v|/1 m/s)/7.5 of u, v, w; ``stopping_ratio``
    log(1 + v²/(2·(F/m)·|d|)) clipped to [0, 8] (≈ log 2 when a full-thrust stop along the
    motion just reaches the target distance: the braking timing of a constant-thrust lander);
    ``time_to_go`` full-thrust braking time v/(F/m) and |d|/max(v, 1 m/s), both /100 s, clipped
    to [0, 10]; ``fuel_margin`` (propellant − m(1 − exp(−v/v_e)))/nominal propellant.

    ``reference_profile`` (7): the deviation of the lander from the nominal optimal descent
    (:func:`reference_profile`) *at the same along-track distance to the target*: altitude and
    cross-track offset / 300 m, u, v, w / 10 m/s, propellant / 10 kg, time / 20 s, clipped to
    ±20. ``stop_point`` (4): where a straight-line stop (thrust plus gravity against the
    velocity) would end, as the offset target − stop point (radial, along, cross) in
    sign·log(1 + |x|/10 m)/8, and that braking time / 100 s.

    Why these two (measured with behaviour cloning of the Pontryagin feedback): the
    stop point of a constant-thrust lander is the difference of two ~100 km quantities (range
    to go and braking distance), so with the other features an error of 100 m of range is a
    1e-5 change of the inputs, below what a regression resolves; a clone then drifts 1-10 km
    (0 % success). The deviation from the reference profile at the same range gives "too fast
    / too high for the distance left" directly in m/s and m (clone miss 9.7 km -> 0.2 km), and
    the stop point gives the last ~30 s their scale in metres.
    """
    if obs.ndim != 2 or obs.shape[1] < 9:
        raise ValueError(f"obs shape {obs.shape}: expected (B, 9) pinpoint observations, or "
                         "(B, 9 + sensor channels)")
    for n in names:
        if n not in PINPOINT_FEATURE_WIDTHS:
            raise ValueError(f"obs_features {n!r} is not defined for the pinpoint env; allowed: "
                             f"{sorted(PINPOINT_FEATURE_WIDTHS)}")
    o = obs.astype(np.float64)
    q = consts["decode"](o)
    d = np.stack([q["target_radial_m"], q["target_along_m"], q["target_cross_m"]], axis=1)
    vel = np.stack([q["u_m_s"], q["v_m_s"], q["w_m_s"]], axis=1)
    dist = np.sqrt(np.sum(d * d, axis=1))
    speed = np.sqrt(np.sum(vel * vel, axis=1))
    prop = np.maximum(q["propellant_kg"], 0.0)
    cols: list[np.ndarray] = []
    for name in names:
        if name == "log_altitude":
            cols.append(np.log10(1.0 + np.maximum(q["altitude_m"], 0.0)) / 4.2)
        elif name == "fine_range":
            cols += [np.sign(d[:, j]) * np.log1p(np.abs(d[:, j])) / 13.0 for j in range(3)]
        elif name == "fine_velocity":
            cols += [np.sign(vel[:, j]) * np.log1p(np.abs(vel[:, j])) / 7.5 for j in range(3)]
        elif name in STOPPING_FEATURES:
            cols += stopping_columns(name, dist, speed, prop, consts)
        elif name == "reference_profile":
            prof = reference_profile(consts)
            for key, scale in (("altitude_m", 300.0), ("target_cross_m", 300.0),
                               ("u_m_s", 10.0), ("v_m_s", 10.0), ("w_m_s", 10.0),
                               ("propellant_kg", 10.0), ("time_s", 20.0)):
                ref = np.interp(q["target_along_m"], prof["along_m"], prof[key])
                cols.append(np.clip((q[key] - ref) / scale, -20.0, 20.0))
        elif name == "stop_point":
            off, tau = straight_line_stop(q, consts)
            cols += [np.sign(off[:, j]) * np.log1p(np.abs(off[:, j]) / 10.0) / 8.0
                     for j in range(3)]
            cols.append(np.clip(tau / 100.0, 0.0, 10.0))
    out = np.concatenate([o, np.stack(cols, axis=1)], axis=1)
    return out.astype(np.float32)


def pinpoint_feature_bounds(names: Sequence[str]) -> tuple[list[float], list[float]]:
    """Lower and upper bounds of the columns the features ``names`` add."""
    lo, hi = [], []
    for name in names:
        w = PINPOINT_FEATURE_WIDTHS[name]
        b = _BOUNDS[name]
        lo += [b[0]] * w
        hi += [b[1]] * w
    return lo, hi


class PinpointFeatures(FeatureFamily):
    """The pinpoint family's observation features (:data:`PINPOINT_FEATURE_WIDTHS`)."""

    widths = dict(PINPOINT_FEATURE_WIDTHS)

    def constants(self, env) -> dict:
        """The scenario and the observation map (the ``reference_profile`` feature)."""
        return pinpoint_feature_constants(env)

    def augment(self, obs, consts, names) -> np.ndarray:
        return augment_pinpoint(obs, consts, names)

    def bounds(self, names) -> tuple[list[float], list[float]]:
        return pinpoint_feature_bounds(names)
