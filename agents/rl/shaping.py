"""Potential-based reward shaping for the soft-landing env (agents side; the env is unchanged).

Why: ``LunarSoftLanding-v0`` pays −fuel per step and −log(1 + v_td / 1 m/s) once, at the end of
a ~700 s flight. Whether a steering decision early in the descent was good shows only hundreds
of steps later, and PPO trained on that signal settled on "dive first, brake near the ground".
The shaping term below pays, at every step, for the change of a potential Φ of the
state, F = γ·Φ(s') − Φ(s), with Φ(terminal) = 0. By Ng, Harada & Russell (1999) shaping of this
form leaves the optimal policy of the discounted problem unchanged (the shaped return differs
from the true one by −Φ(s₀), which no action changes), so the fuel-optimal soft landing stays the
best policy; only the credit assignment becomes local.

Potential (YAML ``reward_shaping: {potential: surface_speed, weight: w}``):

``surface_speed``
    Φ(s) = −w·log(1 + v_s / 1 m/s), v_s = √(v² + 2·(μ/R − μ/r)) the speed the lander would have
    at the surface with the engine off (its mechanical energy, the same estimate the env
    charges a truncated episode with). Thrust that opposes the motion lowers v_s; diving raises
    it. With w = 1 the potential has the same form and scale as the env's terminal penalty.

``gate_speed_and_range`` (pinpoint env)
    Φ(s) = −w·(log(1 + v_g / 1 m/s) + log(1 + d / 100 m)), v_g the engine-off speed at the
    2 km gate sphere and d the distance to the target: the same form and scale as the
    pinpoint env's terminal penalty.

``touchdown_speeds_and_range`` (``LunarPinpointLanding-v3``)
    Φ(s) = −w·(log(1 + v_v / 1 m/s) + log(1 + v_h / 1 m/s) + log(1 + d / 100 m)), v_v the
    engine-off vertical speed at the landing surface, v_h the horizontal speed and d the
    distance from the target of the lander's radial projection: the env's terminal term of an
    episode truncated in state s, so Φ has the terminal penalty's form and scale.

``success_bonus`` (optional, ``reward_shaping: {..., success_bonus: auto}``)
    A terminal reward B paid when the env's own verdict calls the episode a success. It is not
    potential-based: it adds B to the return of every successful episode and nothing to the
    others, so among successes the fuel ordering is unchanged and the fuel-optimal landing (a
    success) keeps the best return; only failures lose ground against successes. Why: the
    env's terminal penalty −log(1 + v/1 m/s) − log(1 + miss/100 m) has its steepest
    slope at v = 0, miss = 0, so PPO spends its updates refining the landings that already
    succeed (a 100 m miss: 1/200 per m) more than rescuing those just outside the verdict (a
    1 km miss: 1/1100 per m), while the evaluation counts only the verdict. ``auto``: B equals
    the env's terminal penalty at the verdict's boundary, log(1 + v_max/1 m/s) + log(1 +
    miss_max/100 m) (3.58 for the pinpoint env's 5 m/s and 500 m; for v3, whose verdict bounds
    each speed component, log(1 + 3) + log(1 + 1.2) + log(1 + 100/100) = 2.87): the worst
    success then ends
    with what a perfect landing ends with without the bonus (0); a number sets B directly.

``margin_bonus`` (optional, ``reward_shaping: {..., margin_bonus: auto}``)
    A terminal reward P·min_k(1 − x_k/limit_k) paid with a success, over the quantities the
    env's verdict bounds (v3: the miss distance, the vertical and the horizontal touchdown
    speed; the pinpoint env: the miss and the speed): P for a landing on the target at rest,
    nothing for one at any limit. Not potential-based either: among successes it ranks
    higher the landings with more room left before the nearest limit, which the env's own
    terms also prefer (each is smallest at zero), but with a slope that stays the same up to
    the limit. Why: a v3 policy trained with the success bonus alone touched down in every
    nominal case at one spot 90 m from the target (along −49 m, cross +77 m, 4 m scatter), still
    braking along-track (1.2 m/s across at the median under ``standard``): successes, with no
    room for the navigation and engine errors, which pushed 104 of its 120 failures over the
    horizontal-speed limit and 60 outside the radius (200 ``standard`` cases). ``auto``:
    P = the success bonus B; a number sets P. Needs each bounded quantity in the env's final
    info (``miss_distance_m``, ``touchdown_speed_m_s`` and the task's ``extra_info_keys``).

``low_gate`` (optional, ``LunarPinpointLanding-v3``)
    ``reward_shaping: {..., low_gate: {height_m: 15, time_s: 1, weight_per_m: 0.03}}``. A
    cost w·log(1 + e / 1 m/s)·Δh at every decision, the last included (at its final
    observation), Δh ≥ 0 the height lost over the decision (m) and e = max(0, v_h −
    max(0, h − h_gate)/τ) the horizontal speed above an envelope that closes linearly to
    zero at the low gate h_gate above the site: the phased laws' terminal descent, straight
    down with the horizontal speed nulled. Charged per metre lost rather than per decision,
    so a lander cannot lower it by falling faster through the envelope (a per-decision cost
    did: its landers dropped at 8 m/s; so did a per-metre cost that spared an episode's last
    decision). Not potential-based: it moves the best policy off the fuel optimum, which
    brakes along-track into the ground (a 24e6-step robust policy still crossed 50 m at
    110 m/s across and 5 m at 16 m/s, median of 100 ``standard`` cases), so the errors'
    timing decides whether the horizontal speed is nulled before contact (87 of its 91
    failures in 200 cases touched down faster than 1.2 m/s across); handing the same policy
    to phased ZEM/ZEV below 50 m landed 92 % of those cases against 59 %. Defaults: h_gate =
    15 m, the phased laws' low gate; τ = 1 s, so that the phased ZEM/ZEV approach (25 m/s
    across at 50 m, 14 m/s at 30 m, median of 100 ``standard`` cases) stays inside the
    envelope and costs nothing; w = 0.03 per metre (a choice: 20 m/s over the envelope from
    50 m down to the gate costs about one success bonus).

The potential is computed from the observation (altitude, radial and horizontal speed), so the
wrapper sits outside the start-state curriculum and needs no access to the env's state.
Evaluation is not affected (it measures touchdown speed and fuel, not rewards). Decision: a
truncated episode also gets Φ(s') = 0 at its end (rare: only policies that never land); SB3
bootstraps the value there, so the shaping's telescoping is exact only for terminated episodes.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnvWrapper

from agents.features import feature_constants
from lunar_env.validation import require_number

__all__ = ["LOW_GATE_DEFAULTS", "MARGIN_INFO_KEYS", "PotentialShaping", "resolve_low_gate",
           "resolve_margin_bonus", "resolve_success_bonus",
           "surface_speed_m_s", "touchdown_speeds_and_range", "verdict_limits"]

#: the final-info key of each quantity a verdict bounds (``success_thresholds`` key -> info key)
MARGIN_INFO_KEYS = {"miss_m": "miss_distance_m", "speed_m_s": "touchdown_speed_m_s",
                    "vertical_speed_m_s": "touchdown_vertical_speed_m_s",
                    "horizontal_speed_m_s": "touchdown_horizontal_speed_m_s"}
#: the low-gate cost's defaults (module docstring): gate height (m), envelope time (s), weight
#: per metre of height lost (1/m)
LOW_GATE_DEFAULTS = {"height_m": 15.0, "time_s": 1.0, "weight_per_m": 0.03}
#: the decoded quantities the low-gate cost reads
_LOW_GATE_QUANTITIES = ("altitude_m", "v_along_m_s", "v_cross_m_s")
#: every potential; which of them fit an env, :data:`FAMILY_POTENTIALS` says
POTENTIALS = ("surface_speed", "gate_speed_and_range", "touchdown_speeds_and_range")
#: the potentials that fit each env family (``scenario.family``): the soft landing's surface
#: speed, the pinpoint landing's gate speed and range, the landing to touchdown's vertical and
#: horizontal speeds and range
FAMILY_POTENTIALS: dict[str, tuple[str, ...]] = {"planar": ("surface_speed",),
                                                 "pinpoint": ("gate_speed_and_range",),
                                                 "pinpoint_touchdown":
                                                     ("touchdown_speeds_and_range",)}


def gate_speed_and_range(obs: np.ndarray, consts: dict) -> tuple[np.ndarray, np.ndarray]:
    """Engine-off speed at the 2 km gate sphere (m/s) and distance to the target (m), shape
    (B,) each, from pinpoint observations (B, ≥9)."""
    q = consts["decode"](np.asarray(obs, dtype=np.float64)[:, :9])
    h = np.maximum(q["altitude_m"], 0.0)
    rg = consts["gate_radius_m"]
    drop = 2.0 * consts["mu_m3_s2"] * (1.0 / rg - 1.0 / (rg + h))
    v_gate = np.sqrt(q["u_m_s"] ** 2 + q["v_m_s"] ** 2 + q["w_m_s"] ** 2 + drop)
    dist = np.sqrt(q["target_radial_m"] ** 2 + q["target_along_m"] ** 2
                   + q["target_cross_m"] ** 2)
    return v_gate, dist


def touchdown_speeds_and_range(obs: np.ndarray | dict[str, np.ndarray], consts: dict
                               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Engine-off vertical speed at the landing surface (m/s), horizontal speed (m/s) and
    distance from the target of the lander's radial projection on the surface (m), shape (B,)
    each, from ``LunarPinpointLanding-v3`` observations (B, n_obs), or their decoded
    quantities: what the env's terminal term measures of an episode truncated now."""
    q = obs if isinstance(obs, dict) else consts["decode"](np.asarray(obs, dtype=np.float64))
    h = np.maximum(q["altitude_m"], 0.0)
    rs = consts["surface_radius_m"]
    drop = 2.0 * consts["mu_m3_s2"] * (1.0 / rs - 1.0 / (rs + h))
    v_vertical = np.sqrt(q["v_up_m_s"] ** 2 + drop)
    v_horizontal = np.hypot(q["v_along_m_s"], q["v_cross_m_s"])
    miss = np.hypot(q["along_m"], q["cross_m"]) * rs / (rs + h)
    return v_vertical, v_horizontal, miss


def surface_speed_m_s(obs: np.ndarray, consts: dict[str, float], surface_radius_m: float
                      ) -> np.ndarray:
    """Engine-off surface speed (m/s), shape (B,), from soft-landing observations (B, ≥5)."""
    q = consts["decode"](np.asarray(obs, dtype=np.float64)[:, :5])
    h = np.maximum(q["altitude_m"], 0.0)
    vr = q["radial_velocity_m_s"]
    vt = q["tangential_velocity_m_s"]
    g_r2 = consts["gravity_m_s2"] * surface_radius_m ** 2  # μ (m³/s²)
    drop = 2.0 * g_r2 * (1.0 / surface_radius_m - 1.0 / (surface_radius_m + h))
    return np.sqrt(vr ** 2 + vt ** 2 + drop)


class PotentialShaping(VecEnvWrapper):
    """Add F = γ·Φ(s') − Φ(s) to the rewards of a soft-landing VecEnv (see module docstring).

    :param venv: VecEnv of ``LunarSoftLanding-v0`` observations (a ``LanderSB3VecEnv``, possibly
        wrapped by the curriculum).
    :param gamma: the algorithm's discount factor (the shaping must use the same γ).
    :param potential: ``"surface_speed"``.
    :param weight: w > 0.
    :param success_bonus: None (default), ``"auto"`` or a finite number >= 0: the terminal
        reward added to a successful episode (module docstring).
    :param margin_bonus: None (default), ``"auto"`` or a finite number >= 0: P of the
        reward P·min_k(1 − x_k/limit_k) added to a successful episode (module docstring).
    :param low_gate: None (default) or a mapping with any of ``height_m`` (h_gate > 0, m),
        ``time_s`` (τ > 0, s) and ``weight_per_m`` (w > 0, 1/m): the low-gate cost of
        ``LunarPinpointLanding-v3`` (module docstring; defaults :data:`LOW_GATE_DEFAULTS`).
    """

    def __init__(self, venv, gamma: float, potential: str = "surface_speed",
                 weight: float = 1.0, success_bonus: float | str | None = None,
                 margin_bonus: float | str | None = None,
                 low_gate: dict[str, float] | None = None) -> None:
        super().__init__(venv)
        if potential not in POTENTIALS:
            raise ValueError(f"potential={potential!r}; allowed: {POTENTIALS}")
        if not (np.isfinite(weight) and weight > 0):
            raise ValueError(f"weight={weight!r} must be finite and > 0")
        if not (0.0 < gamma <= 1.0):
            raise ValueError(f"gamma={gamma!r} must be in (0, 1]")
        node = venv
        while not hasattr(node, "native") and hasattr(node, "venv"):
            node = node.venv
        native = getattr(node, "native", None)
        if native is None:
            raise TypeError("PotentialShaping needs a LanderSB3VecEnv of LunarSoftLanding-v0")
        self.consts = feature_constants(native)
        allowed = FAMILY_POTENTIALS.get(self.consts["family"], ())
        if potential not in allowed:
            raise ValueError(f"potential={potential!r} does not fit this env: use one of "
                             f"{allowed}")
        self.surface_radius_m = float(getattr(native.scenario, "surface_radius_m", np.nan))
        self.gamma = float(gamma)
        self.potential = potential
        self.weight = float(weight)
        self._phi: np.ndarray | None = None
        self._height_m: np.ndarray | None = None  # navigated height after the last step (m)
        thresholds = native.success_thresholds
        self.success_bonus = resolve_success_bonus(success_bonus, thresholds)
        self.margin_bonus = resolve_margin_bonus(margin_bonus, thresholds)
        #: the verdict's limits, each with the final-info key of the quantity it bounds
        self.limits = {MARGIN_INFO_KEYS[k]: v for k, v in verdict_limits(thresholds).items()}
        self.low_gate = resolve_low_gate(low_gate, self.consts["family"])

    def phi(self, obs: np.ndarray | dict[str, np.ndarray]) -> np.ndarray:
        """Φ of observations (or, for ``touchdown_speeds_and_range``, their decoded
        quantities), shape (B,)."""
        if self.potential == "gate_speed_and_range":
            v_gate, dist = gate_speed_and_range(obs, self.consts)
            return -self.weight * (np.log1p(v_gate) + np.log1p(dist / 100.0))
        if self.potential == "touchdown_speeds_and_range":
            v_vert, v_hor, miss = touchdown_speeds_and_range(obs, self.consts)
            return -self.weight * (np.log1p(v_vert) + np.log1p(v_hor) + np.log1p(miss / 100.0))
        return -self.weight * np.log1p(surface_speed_m_s(obs, self.consts,
                                                         self.surface_radius_m))

    def reset(self) -> np.ndarray:
        obs = self.venv.reset()
        # with the low gate (touchdown potential only) the observations are decoded once
        q = self._decode(obs) if self.low_gate is not None else obs
        self._phi = self.phi(q)
        if self.low_gate is not None:
            self._height_m = q["altitude_m"]
        return obs

    def step_wait(self):
        obs, rew, done, infos = self.venv.step_wait()
        q_next = self._decode(obs) if self.low_gate is not None else obs
        phi_next = self.phi(q_next)
        target = np.where(done, 0.0, phi_next)  # Φ(terminal) = 0; obs of a done env is a reset
        shaped = rew + (self.gamma * target - self._phi).astype(np.float32)
        if self.low_gate is not None:
            # an episode's last decision is charged at its final observation: a lander
            # must not save the cost by falling through the envelope in one decision
            q_last = {k: q_next[k] for k in _LOW_GATE_QUANTITIES}
            if done.any():
                ended = np.flatnonzero(done)
                q_end = self._decode(np.stack([infos[i]["terminal_observation"]
                                               for i in ended]))
                q_last = {k: v.copy() for k, v in q_last.items()}
                for k in _LOW_GATE_QUANTITIES:
                    q_last[k][ended] = q_end[k]
            shaped -= self.low_gate_cost(q_last, self._height_m).astype(np.float32)
            # the next decision starts where this one ended, or at a reset's first observation
            self._height_m = np.where(done, q_next["altitude_m"], q_last["altitude_m"])
        if (self.success_bonus or self.margin_bonus) and done.any():
            won = [i for i in np.flatnonzero(done) if infos[i].get("is_success")]
            shaped[won] += np.float32(self.success_bonus)
            if self.margin_bonus and won:
                shaped[won] += (self.margin_bonus
                                * self.margins([infos[i] for i in won])).astype(np.float32)
        self._phi = phi_next
        return obs, shaped.astype(np.float32), done, infos

    def _decode(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        """The navigated quantities of observations (B, n_obs)."""
        return self.consts["decode"](np.asarray(obs, dtype=np.float64))

    def low_gate_cost(self, obs: np.ndarray | dict[str, np.ndarray],
                      height_before_m: np.ndarray) -> np.ndarray:
        """The low-gate cost w·log(1 + e / 1 m/s)·Δh of the decisions that ended in
        observations (B, n_obs), or their decoded quantities, from heights
        ``height_before_m`` (B,) (m), shape (B,) (module docstring)."""
        q = obs if isinstance(obs, dict) else self._decode(obs)
        gate = self.low_gate
        allowed = np.maximum(q["altitude_m"] - gate["height_m"], 0.0) / gate["time_s"]
        excess = np.maximum(np.hypot(q["v_along_m_s"], q["v_cross_m_s"]) - allowed, 0.0)
        lost = np.maximum(np.asarray(height_before_m, dtype=np.float64) - q["altitude_m"], 0.0)
        return gate["weight_per_m"] * np.log1p(excess) * lost

    def margins(self, infos: list[dict]) -> np.ndarray:
        """min_k(1 − x_k/limit_k), clipped to [0, 1], of final infos of successes (B,).

        Raises
        ------
        KeyError
            An info lacks a quantity the verdict bounds.
        """
        x = np.array([[info[key] / limit for key, limit in self.limits.items()]
                      for info in infos], dtype=np.float64)
        return np.clip(1.0 - x.max(axis=1), 0.0, 1.0)

    def config(self) -> dict[str, Any]:
        return {"potential": self.potential, "weight": self.weight, "gamma": self.gamma,
                "success_bonus": self.success_bonus, "margin_bonus": self.margin_bonus,
                "low_gate": self.low_gate}


def resolve_low_gate(value: dict[str, float] | None, family: str) -> dict[str, float] | None:
    """The low-gate settings of a ``low_gate`` mapping, completed with
    :data:`LOW_GATE_DEFAULTS` (None for None); ``family``: the env family's name.

    Raises
    ------
    ValueError
        An env other than ``LunarPinpointLanding-v3``, an unknown key, or a value that is not
        a finite number > 0.
    """
    if value is None:
        return None
    if family != "pinpoint_touchdown":
        raise ValueError(f"low_gate needs LunarPinpointLanding-v3 (a landing to touchdown); "
                         f"this env's family is {family!r}")
    if not isinstance(value, dict):
        raise ValueError(f"low_gate={value!r} must be a mapping with keys "
                         f"{sorted(LOW_GATE_DEFAULTS)}")
    unknown = sorted(set(value) - set(LOW_GATE_DEFAULTS))
    if unknown:
        raise ValueError(f"low_gate keys {unknown} unknown; allowed: {sorted(LOW_GATE_DEFAULTS)}")
    out = dict(LOW_GATE_DEFAULTS)
    for key, v in value.items():
        x = require_number(f"low_gate.{key}", v)
        if not (np.isfinite(x) and x > 0):
            raise ValueError(f"low_gate.{key}={v!r} must be a finite number > 0")
        out[key] = float(x)
    return out


def verdict_limits(thresholds: dict[str, float]) -> dict[str, float]:
    """The finite limits an env's verdict bounds, keyed as its ``success_thresholds``: each
    speed component where the verdict bounds them (v3, whose ``speed_m_s`` is only their
    hypotenuse), else the speed; and the miss distance where there is a target."""
    speeds = (("vertical_speed_m_s", "horizontal_speed_m_s") if "vertical_speed_m_s" in thresholds
              else ("speed_m_s",))
    return {k: float(thresholds[k]) for k in (*speeds, "miss_m")
            if k in thresholds and np.isfinite(thresholds[k])}


def resolve_success_bonus(value: float | str | None, thresholds: dict[str, float]) -> float:
    """The success bonus B of a ``success_bonus`` setting (0.0 for None); ``thresholds``: the
    env's ``success_thresholds``."""
    if value is None:
        return 0.0
    if isinstance(value, str):
        if value != "auto":
            raise ValueError(f"success_bonus={value!r}; allowed: 'auto', a number >= 0 or null")
        limits = verdict_limits(thresholds)
        speeds = sum(np.log1p(v) for k, v in limits.items() if k != "miss_m")
        return float(speeds + np.log1p(limits.get("miss_m", 0.0) / 100.0))
    b = require_number("success_bonus", value)
    if not (np.isfinite(b) and b >= 0):
        raise ValueError(f"success_bonus={value!r} must be 'auto', a finite number >= 0 or null")
    return b


def resolve_margin_bonus(value: float | str | None, thresholds: dict[str, float]) -> float:
    """P of a ``margin_bonus`` setting (0.0 for None): ``"auto"`` is the success bonus ``auto``
    resolves to; ``thresholds``: the env's ``success_thresholds``, which must bound at least
    one quantity (:func:`verdict_limits`).

    Raises
    ------
    ValueError
        Not ``"auto"``, a finite number >= 0 or None, or the env's verdict bounds nothing.
    """
    if value is None:
        return 0.0
    if not verdict_limits(thresholds):
        raise ValueError(f"margin_bonus={value!r} needs a verdict with limits; this env's "
                         f"success thresholds are {sorted(thresholds)}")
    if isinstance(value, str):
        if value != "auto":
            raise ValueError(f"margin_bonus={value!r}; allowed: 'auto', a number >= 0 or null")
        return resolve_success_bonus("auto", thresholds)
    p = require_number("margin_bonus", value)
    if not (np.isfinite(p) and p >= 0):
        raise ValueError(f"margin_bonus={value!r} must be 'auto', a finite number >= 0 or "
                         "null")
    return p
