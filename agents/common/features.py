"""Derived observation features for the landing policies (agents side; the env is unchanged).

Soft landing below; the pinpoint env's features are documented at :func:`_augment_pinpoint`.

Why: ``LunarSoftLanding-v0`` observes altitude / 15 km, radial speed / 169 m/s and horizontal
speed / 1.69 km/s (:mod:`lunar_env.envs.soft_landing`). Those scales suit the start of the
descent, but the last few hundred metres and tens of m/s — where a touchdown speed of 5 m/s is
won or lost — occupy a few thousandths of the input range. A steer-only, constant-thrust lander
must also judge *when* braking has to win over gravity: the key quantity is the ratio of the
distance needed to stop to the altitude left. The features below give the network these
quantities directly. They are computed **from the env's observation alone** (which is an
invertible scaling of the physical state, up to the observation clipping), so the same function
serves training, the terminal observations SB3 bootstraps from, and evaluation, and a policy
trained with features can be replayed exactly: the run's ``config.yml`` records
``obs_features`` and :class:`agents.common.sb3_law.SB3Law` re-applies them.

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
from gymnasium import spaces
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from stable_baselines3.common.vec_env.base_vec_env import VecEnvWrapper

__all__ = ["FEATURE_WIDTHS", "augment_observation", "feature_constants", "validate_features",
           "ObsFeatureWrapper", "StandardizedInputs", "standardized_inputs_kwargs",
           "reference_profile"]

#: columns added by each feature name, in the order they are appended
FEATURE_WIDTHS = {"log_altitude": 1, "fine_velocity": 2, "stopping_ratio": 1,
                  "time_to_go": 2, "fuel_margin": 1}
#: the same for ``LunarPinpointLanding-v*`` (9 observations; see :func:`_augment_pinpoint`)
PINPOINT_FEATURE_WIDTHS = {"log_altitude": 1, "fine_range": 3, "fine_velocity": 3,
                           "stopping_ratio": 1, "time_to_go": 2, "fuel_margin": 1,
                           "reference_profile": 7, "stop_point": 4}


def validate_features(names: Sequence[str] | None) -> list[str]:
    """The feature names as a list; raises ``ValueError`` on unknown or repeated names."""
    if names is None:
        return []
    if isinstance(names, str):
        raise TypeError(f"obs_features={names!r} must be a list of names, not a string")
    out = [str(n) for n in names]
    allowed = set(FEATURE_WIDTHS) | set(PINPOINT_FEATURE_WIDTHS)
    bad = [n for n in out if n not in allowed]
    if bad:
        raise ValueError(f"unknown obs_features {bad}; allowed: {sorted(allowed)}")
    if len(set(out)) != len(out):
        raise ValueError(f"obs_features {out} repeats a name")
    return out


def feature_constants(env) -> dict:
    """What the features need from a soft-landing env, through its public API.

    ``env``: a ``LunarSoftLanding-v0`` env (single or native vector, or its task): its
    ``physical_constants()`` (thrust, exhaust velocity, dry mass, surface gravity, nominal
    propellant) and, under ``"decode"``, its ``observation_quantities`` — the env's own inverse of
    its observation, so a change to the observation cannot silently break trained features.

    Raises ``TypeError`` for an env that is not the planar soft-landing task.
    """
    if not hasattr(env, "observation_quantities") or not hasattr(env, "physical_constants"):
        raise TypeError("observation features are defined for the lunar_env landing envs only")
    try:
        consts: dict = dict(env.physical_constants())
    except TypeError:
        raise TypeError("observation features are defined for the lunar_env landing envs "
                        "only") from None
    consts["decode"] = env.observation_quantities
    consts["pinpoint"] = bool(getattr(env, "has_target", False))
    if consts["pinpoint"]:
        consts["scenario"] = env.scenario
        consts["observation_from_state"] = getattr(env, "observation_from_state", None)
    return consts


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


def augment_observation(obs: np.ndarray, consts: dict[str, float],
                        names: Sequence[str]) -> np.ndarray:
    """Append the features ``names`` to env observations.

    Parameters
    ----------
    obs : ndarray, shape (B, 5)
        ``LunarSoftLanding-v0`` observations (altitude/h₀, v_r/(0.1 v₀), v_t/v₀, propellant
        fraction, time fraction).
    consts : dict
        :func:`feature_constants` of the env.
    names : sequence of str
        Feature names (:data:`FEATURE_WIDTHS`).

    Returns
    -------
    ndarray, shape (B, 5 + Σ widths), float32
    """
    obs = np.asarray(obs)
    if not names:
        return obs.astype(np.float32, copy=False)
    if consts.get("pinpoint"):
        return _augment_pinpoint(obs, consts, names)
    if obs.ndim != 2 or obs.shape[1] != 5:
        raise ValueError(f"obs shape {obs.shape}: expected (B, 5) soft-landing observations")
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


def _augment_pinpoint(obs: np.ndarray, consts: dict, names: Sequence[str]) -> np.ndarray:
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

    Why these two (issue 16, measured with behaviour cloning of the Pontryagin feedback): the
    stop point of a constant-thrust lander is the difference of two ~100 km quantities (range
    to go and braking distance), so with the other features an error of 100 m of range is a
    1e-5 change of the inputs, below what a regression resolves; a clone then drifts 1-10 km
    (0 % success). The deviation from the reference profile at the same range gives "too fast
    / too high for the distance left" directly in m/s and m (clone miss 9.7 km -> 0.2 km), and
    the stop point gives the last ~30 s their scale in metres.
    """
    if obs.ndim != 2 or obs.shape[1] != 9:
        raise ValueError(f"obs shape {obs.shape}: expected (B, 9) pinpoint observations")
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
    m = consts["dry_mass_kg"] + prop
    a_thrust = consts["thrust_n"] / m
    cols: list[np.ndarray] = []
    for name in names:
        if name == "log_altitude":
            cols.append(np.log10(1.0 + np.maximum(q["altitude_m"], 0.0)) / 4.2)
        elif name == "fine_range":
            cols += [np.sign(d[:, j]) * np.log1p(np.abs(d[:, j])) / 13.0 for j in range(3)]
        elif name == "fine_velocity":
            cols += [np.sign(vel[:, j]) * np.log1p(np.abs(vel[:, j])) / 7.5 for j in range(3)]
        elif name == "stopping_ratio":
            ratio = speed ** 2 / (2.0 * a_thrust * np.maximum(dist, 1.0))
            cols.append(np.clip(np.log1p(ratio), 0.0, 8.0))
        elif name == "time_to_go":
            cols.append(np.clip(speed / a_thrust / 100.0, 0.0, 10.0))
            cols.append(np.clip(dist / np.maximum(speed, 1.0) / 100.0, 0.0, 10.0))
        elif name == "fuel_margin":
            need = m * -np.expm1(-speed / consts["exhaust_velocity_m_s"])
            cols.append((prop - need) / consts["prop_nominal_kg"])
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


def _feature_bounds(names: Sequence[str], pinpoint: bool = False
                    ) -> tuple[list[float], list[float]]:
    if pinpoint:
        lo, hi = [], []
        for name in names:
            w = PINPOINT_FEATURE_WIDTHS[name]
            b = {"log_altitude": (0.0, 2.0), "fine_range": (-2.0, 2.0),
                 "fine_velocity": (-2.0, 2.0), "stopping_ratio": (0.0, 8.0),
                 "time_to_go": (0.0, 10.0), "fuel_margin": (-2.0, 2.0),
                 "reference_profile": (-20.0, 20.0), "stop_point": (-2.0, 10.0)}[name]
            lo += [b[0]] * w
            hi += [b[1]] * w
        return lo, hi
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


class ObsFeatureWrapper(VecEnvWrapper):
    """Append :func:`augment_observation` features to every observation of a soft-landing VecEnv.

    :param venv: a VecEnv whose innermost env is :class:`agents.common.vec_env.LanderSB3VecEnv` of
        ``LunarSoftLanding-v0`` (curriculum wrappers in between are fine: the features are a
        function of the observation alone).
    :param names: feature names (:data:`FEATURE_WIDTHS`).

    ``info["terminal_observation"]`` is augmented too, so value bootstrapping on truncation sees
    the same inputs as the policy.
    """

    def __init__(self, venv, names: Sequence[str]) -> None:
        self.names = validate_features(names)
        if not self.names:
            raise ValueError("ObsFeatureWrapper needs at least one feature name")
        node = venv
        while not hasattr(node, "native") and hasattr(node, "venv"):
            node = node.venv
        native = getattr(node, "native", None)
        if native is None:
            raise TypeError("ObsFeatureWrapper needs a LanderSB3VecEnv of LunarSoftLanding-v0 "
                            "inside the wrapper chain")
        self.consts = feature_constants(native)
        base = venv.observation_space
        lo, hi = _feature_bounds(self.names, bool(self.consts.get("pinpoint")))
        space = spaces.Box(np.concatenate([base.low, lo]).astype(np.float32),
                           np.concatenate([base.high, hi]).astype(np.float32), dtype=np.float32)
        super().__init__(venv, observation_space=space)

    def _aug(self, obs: np.ndarray) -> np.ndarray:
        return augment_observation(obs, self.consts, self.names)

    def reset(self) -> np.ndarray:
        return self._aug(self.venv.reset())

    def step_wait(self):
        obs, rew, done, infos = self.venv.step_wait()
        for info in infos:
            t = info.get("terminal_observation")
            if t is not None:
                info["terminal_observation"] = self._aug(np.asarray(t)[None])[0]
        return self._aug(obs), rew, done, infos


class StandardizedInputs(BaseFeaturesExtractor):
    """Flatten and standardise the policy input with fixed statistics: (x − mean)/std.

    A features extractor for SB3 policies trained by regression (behaviour cloning, DAgger):
    the statistics are those of the training inputs, stored as buffers in the policy's state
    dict and as ``features_extractor_kwargs`` in the saved model, so ``PPO.load`` and
    ``train.py --init-from`` rebuild the same input map (PPO's own ``VecNormalize`` plays this
    role in RL runs). Why: the pinpoint inputs span very different scales (stop offsets of
    metres in a log column, times of hundreds of seconds), and the clone's angle error reaches
    the ~0.1° it needs only on standardised inputs (issue 16).
    """

    def __init__(self, observation_space, mean=None, std=None) -> None:
        import torch as th

        n = int(np.prod(observation_space.shape))
        super().__init__(observation_space, features_dim=n)
        m = np.zeros(n) if mean is None else np.asarray(mean, dtype=np.float64)
        s = np.ones(n) if std is None else np.asarray(std, dtype=np.float64)
        if m.shape != (n,) or s.shape != (n,) or not (np.isfinite(m).all() and np.all(s > 0)):
            raise ValueError(f"mean/std must be {n} finite numbers (std > 0)")
        self.register_buffer("mean", th.as_tensor(m, dtype=th.float32))
        self.register_buffer("std", th.as_tensor(s, dtype=th.float32))

    def forward(self, observations):
        import torch as th

        return (th.flatten(observations, start_dim=1) - self.mean) / self.std


def standardized_inputs_kwargs(inputs: np.ndarray) -> dict:
    """``policy_kwargs`` entries that standardise a policy's inputs with the statistics of
    ``inputs`` (N, n_in) (std floored at 1e-6 of the largest, for constant columns)."""
    x = np.asarray(inputs, dtype=np.float64)
    std = x.std(axis=0)
    std = np.maximum(std, 1e-6 * max(float(std.max()), 1e-12))
    return {"features_extractor_class": StandardizedInputs,
            "features_extractor_kwargs": {"mean": x.mean(axis=0).tolist(),
                                          "std": std.tolist()}}
