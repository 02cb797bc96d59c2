"""Explicit guidance laws flying the landers: augmented Apollo (Apollo, ZEM/ZEV) and gravity turn.

Each law implements :class:`guidance.law.GuidanceLaw`: it reads the navigated state in the
guidance frame (``nav.frame``, :mod:`guidance.frames`) and the flight computer's *nominal*
vehicle, evaluates the pure functions of :mod:`guidance.explicit` and commands thrust along the
resulting thrust acceleration (:class:`~guidance.law.ThrustCommand`; with a throttle, throttle =
|a| m / T clipped to [0, 1]). The env's encoder turns the command into its action; the same law
flies every env family.

How an acceleration law flies a constant-thrust engine
------------------------------------------------------
The envs' default engine burns at full thrust T and can only be steered, as the papers'
vehicles. The law thrusts along its commanded thrust acceleration and chooses t_go at every
decision so that the command's magnitude *equals* T/m (``tgo=matched``, the default:
:func:`~guidance.explicit.thrust_matched_tgo` on its long, braking branch;
``matched-short`` takes the short, hurried root): the command is then flown exactly.
``tgo=rocket`` takes instead the burn time in which the rocket equation gains |ZEV|
(:func:`~guidance.explicit.rocket_tgo`); the command's direction is flown at
full thrust. The option ``tgo_margin`` = μ scales the rule's t_go, t_go = (1 + μ)·t_rule.
The laws re-plan every decision; the surplus or shortfall of a command flown at T/m is
corrected at the next one.

With the throttle channel (``gym.make(id, throttle_channel=True)``) the law is the textbook one:
t_go counts down from a planned descent time t_f = (1 + μ)·t_matched fixed at the first
decision (``tgo=countdown``, the default there), and the throttle is |a_thrust| m / T.

On an axis without a position target (``nav.frame.free_axes``: the planar env's downrange, as its
task ends at any downrange) the law uses the free-terminal-position optimum
(:func:`~guidance.explicit.free_position_thrust`), and (A) on the others.

Lead time ([K74]; Luminary carries ≈2.2 s): with ``lead`` = τ > 0 the navigated state is first
extrapolated τ seconds with the known acceleration plus the previous thrust command, and the
command is computed for that state (it is the state at which the command will act).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from guidance import explicit as gd
from guidance.frames import LocalFrame
from guidance.law import FlightComputer, GuidanceLaw, Navigation, ThrustCommand
from guidance.laws.engine_estimate import ThrustScaleEstimator

__all__ = ["AugmentedApolloLaw", "GravityTurnLaw", "TGO_RULES", "TGO_MAX_S"]

#: the t_go rules: ``matched`` (the long, braking root; constant thrust), ``matched-short``
#: (the short root), ``rocket`` (burn time from the rocket equation), all re-solved every
#: decision; ``countdown`` (throttled: a planned descent time that shrinks)
TGO_RULES = ("matched", "matched-short", "rocket", "countdown")
#: upper end of the t_go search (s): longer than any descent of the scenarios (≤ 800 s)
TGO_MAX_S = 3000.0
#: lower end of the t_go search and floor of the countdown (s)
TGO_MIN_S = 0.05


class _ExplicitLaw(GuidanceLaw):
    """What the explicit laws share: the nominal vehicle they plan with, and the engine's
    present thrust measured by the IMU (Apollo's throttle routine: the mass estimate times the
    measured acceleration over the last guidance cycle, divided by the throttle flown)."""

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self.thrust_n = computer.thrust_n
        self.exhaust_velocity = computer.exhaust_velocity_m_s
        self.dry_mass_kg = computer.dry_mass_kg
        self.throttled = computer.throttled
        self.estimator = ThrustScaleEstimator(self.thrust_n) if "imu" in computer.sensors \
            else None
        if self.estimator is not None:
            self.estimator.reset(len(case_ids))

    def full_thrust_accel(self, nav: Navigation, mass_kg: np.ndarray) -> np.ndarray:
        """The thrust acceleration (N,) (m/s²) the engine gives at full throttle now: T/m̂
        times the IMU's measured scale (:class:`~guidance.laws.engine_estimate.
        ThrustScaleEstimator`; 1 before a measured decision, or without an IMU)."""
        accel = self.thrust_n / mass_kg
        if self.estimator is None or "imu" not in nav.sensors:
            return accel
        self.estimator.reset_rows(np.flatnonzero(nav.episode_start))
        self.estimator.observe(nav.sensors["imu"], mass_kg, nav.active)
        return accel * self.estimator.scale

    def command(self, nav: Navigation, a_thrust: np.ndarray, accel: np.ndarray,
                mass_kg: np.ndarray) -> ThrustCommand:
        """Thrust along ``a_thrust`` (N, d) (m/s², guidance frame), with throttle
        |a| / ``accel`` (the full-throttle acceleration) on a throttled engine (the engine
        gives its full thrust otherwise); the throttle flown is recorded for the next
        measurement."""
        thr = np.ones(len(accel)) if not self.throttled else np.clip(
            np.linalg.norm(a_thrust, axis=1) / accel, 0.0, 1.0)
        if self.estimator is not None:
            self.estimator.record(thr, mass_kg, nav.active)
        return ThrustCommand(a_thrust, thr if self.throttled else None)


class AugmentedApolloLaw(_ExplicitLaw):
    """Augmented Apollo explicit guidance ([L18]; k_r = 12 Apollo [K74], 6 ZEM/ZEV [GHW]).

    Parameters
    ----------
    k_r : float
        Gain in [6, 24] (:func:`guidance.explicit.check_gain`).
    tgo_margin : float
        μ in t_go = (1 + μ)·t_matched, in [−0.5, 1] (module docstring). Default 0.
    lead_s : float
        Lead time τ (s) in [0, 10]; Luminary's is about 2.2 s. Default 0.
    tgo_rule : str or None
        ``"rocket"``, ``"matched"`` or ``"countdown"`` (None: rocket on a constant-thrust
        engine, countdown on a throttled one).
    terminal_accel_m_s2 : sequence of d floats or None
        Target *total* acceleration a_T (m/s², local frame, up last) for k_r ≠ 6 (None:
        :meth:`default_terminal_accel`).
    include_rotation : bool
        3D: the Moon's Coriolis and centrifugal terms in the known acceleration.
    terminal_s : float
        Constant-thrust engine: once t_go ≤ this (s), thrust opposite the surface-relative
        velocity (a gravity-turn finish, which brings the speed to its minimum, where the env
        cuts the engine off). In [0, 60]; default 0 (off).
    aim_above_m : float
        Aim this many metres above the terminal surface, in [0, 100]; default 0. (The env
        ends the episode at the surface crossing and cuts the engine off at the speed minimum:
        a constant-thrust lander that nulls its speed a few metres up falls the rest softly,
        one that arrives late crosses the surface still braking.)
    name : str
    """

    def __init__(self, k_r: float = gd.K_R_APOLLO, tgo_margin: float = 0.0,
                 lead_s: float = 0.0, tgo_rule: str | None = None,
                 terminal_accel_m_s2=None, include_rotation: bool = True,
                 terminal_s: float = 0.0, aim_above_m: float = 0.0,
                 name: str | None = None) -> None:
        self.include_rotation = bool(include_rotation)
        self.terminal_s = _check_range("terminal_s", terminal_s, 0.0, 60.0)
        self.aim_above_m = _check_range("aim_above_m", aim_above_m, 0.0, 100.0)
        self.k_r = gd.check_gain(k_r)
        self.tgo_margin = _check_range("tgo_margin", tgo_margin, -0.5, 1.0)
        self.lead_s = _check_range("lead_s", lead_s, 0.0, 10.0)
        if tgo_rule is not None and tgo_rule not in TGO_RULES:
            raise ValueError(f"tgo_rule = {tgo_rule!r} is not allowed; use one of {TGO_RULES}")
        self.tgo_rule = tgo_rule
        self.terminal_accel = None if terminal_accel_m_s2 is None else \
            gd.check_state("terminal_accel_m_s2", np.atleast_1d(terminal_accel_m_s2))
        self.name = name or f"augmented Apollo (k_r={self.k_r:g})"

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        d = computer.n_axes
        n = len(case_ids)
        if self.terminal_accel is not None and self.terminal_accel.shape != (d,):
            raise ValueError(f"terminal_accel_m_s2 = {self.terminal_accel.tolist()} must have "
                             f"{d} components (horizontal..., up) for {computer.env_id}")
        self.a_t = self.default_terminal_accel() if self.terminal_accel is None \
            else self.terminal_accel
        self.rule = self.tgo_rule or ("countdown" if self.throttled else "matched")
        self.prev_thrust = np.full((n, d), np.nan)
        self.t_final = np.full(n, np.nan)
        #: t_go (s) of the last decision, per lander (for analysis)
        self.last_tgo = np.full(n, np.nan)

    def default_terminal_accel(self) -> np.ndarray:
        """[K74]'s target acceleration a_T (total, local frame, up last) when none is given.

        A vehicle that can point its thrust anywhere in the guidance plane (the planar env)
        takes a_T = 0: the vertical axis ends like a soft touchdown. Where the thrust's
        elevation is bounded (α ≤ 40° for ``peng2012``), a_T must be reachable inside the
        bound: Apollo's a_T = 0 means hovering at the target, α = 90°, which the env clips to
        40° and the landing fails (measured: 0 % on the throttled engine). The target is then
        the thrust braking along the first horizontal axis at α_T = α_max − 5°, with magnitude
        3/4 of T at the dry mass, plus gravity at the target radius: the lander arrives from
        above and behind along −a_T, with its thrust inside the bounds.
        """
        c = self.computer
        a_t = np.zeros(c.n_axes)
        bounds = c.thrust_elevation_bounds_rad
        if bounds is None:
            return a_t
        alpha = bounds[1] - math.radians(5.0)
        thrust = 0.75 * self.thrust_n / self.dry_mass_kg
        r_gate = c.target_radius_m
        g_gate = c.mu_m3_s2 / (r_gate * r_gate)
        a_t[0] = -thrust * math.cos(alpha)
        a_t[-1] = thrust * math.sin(alpha) - g_gate
        return a_t

    def command_fn(self, f: LocalFrame):
        """``command(t_go, rows) -> (n, d)`` thrust acceleration of this law in frame ``f``
        (the callable :func:`~guidance.explicit.thrust_matched_tgo` solves)."""
        # validated once here, not at each of the ~80 evaluations of the t_go root find
        gd.check_gain(self.k_r)

        def command(t_go, rows):
            v, g = f.v[rows], f.g[rows]
            a = gd.augmented_apollo_thrust(0.0, v, f.r_to_target[rows], 0.0, self.a_t, g,
                                           t_go, self.k_r, check=False)
            for ax in f.free_axes:  # no position target on this axis: the free-end optimum
                a[:, ax] = gd.free_position_thrust(v[:, ax:ax + 1], 0.0, g[:, ax:ax + 1], t_go,
                                                   check=False)[:, 0]
            return a

        return command

    def act(self, nav: Navigation) -> ThrustCommand:
        start = nav.episode_start
        self.t_final[start] = np.nan
        self.prev_thrust[start] = np.nan
        f = nav.frame
        if not self.include_rotation:
            f = dataclasses.replace(f, g=f.g_without_spin)
        accel = self.full_thrust_accel(nav, f.mass_kg)
        if self.aim_above_m > 0.0:
            rel = f.r_to_target.copy()
            rel[:, -1] += self.aim_above_m
            f = dataclasses.replace(f, r_to_target=rel)
        if self.lead_s > 0.0:
            f = self._lead(f, accel)
        command = self.command_fn(f)
        t_go = (1.0 + self.tgo_margin) * self.solve_tgo(f, command, accel)
        if self.rule == "countdown":
            # the frame was extrapolated by the lead: its clock reads t + τ
            t_frame = nav.t_s + self.lead_s
            new = ~np.isfinite(self.t_final)
            self.t_final[new] = t_frame[new] + t_go[new]
            t_go = np.maximum(self.t_final - t_frame, TGO_MIN_S)
        a = command(t_go, slice(None))
        if not self.throttled:  # the engine gives T/m: fly the command's direction
            a *= (accel / np.maximum(np.linalg.norm(a, axis=1), 1e-300))[:, None]
            if self.terminal_s > 0.0:
                # the last seconds: null the velocity (the env cuts the engine off at the
                # speed minimum), instead of timing a 1-s-held command to the arrival
                fin = t_go <= self.terminal_s
                a[fin] = accel[fin, None] * gd.gravity_turn_direction(f.v[fin])
        self.prev_thrust = a
        self.last_tgo = t_go
        return self.command(nav, a, accel, f.mass_kg)

    def solve_tgo(self, f: LocalFrame, command, accel: np.ndarray) -> np.ndarray:
        """t_go (s) of the frame's landers by the rule (the countdown plans with ``rocket``)."""
        if self.rule in ("matched", "matched-short", "countdown"):
            branch = "short" if self.rule == "matched-short" else "long"
            return gd.thrust_matched_tgo(command, accel, TGO_MIN_S, TGO_MAX_S, branch)[0]
        v_t = np.zeros_like(f.v)

        def zev_of(t, rows):
            return gd.zem_zev(np.zeros_like(f.v[rows]), f.v[rows], np.zeros_like(f.v[rows]),
                              v_t[rows], f.g[rows], t)[1]

        burnout = np.maximum(f.mass_kg - self.dry_mass_kg, 0.0) * self.exhaust_velocity \
            / self.thrust_n
        return gd.rocket_tgo(zev_of, accel, self.exhaust_velocity, burnout, TGO_MIN_S,
                             TGO_MAX_S)[0]

    def _lead(self, f: LocalFrame, accel: np.ndarray) -> LocalFrame:
        """The frame extrapolated by the lead time with the previous thrust (full thrust
        against the velocity before the first decision)."""
        prev = self.prev_thrust
        fresh = ~np.isfinite(prev).all(axis=1)
        if fresh.any():  # a row's first decision: full thrust against its velocity
            prev = prev.copy()
            prev[fresh] = accel[fresh, None] * gd.gravity_turn_direction(f.v[fresh])
        tau = self.lead_s
        acc = f.g + prev
        return dataclasses.replace(f, r_to_target=f.r_to_target - f.v * tau - 0.5 * acc * tau * tau,
                                   v=f.v + acc * tau, height_m=f.height_m + f.v[:, -1] * tau)


class GravityTurnLaw(_ExplicitLaw):
    """Gravity turn: thrust opposite the surface-relative velocity.

    Constant-thrust engine: full thrust along −v̂ from the first decision (no free parameter:
    the landing succeeds only if the velocity happens to vanish at the surface). Throttled:
    full thrust until the *terminal* gravity turn can take over, then the magnitude that removes
    the kinetic and potential energy over the straight-line path to the surface,
    a = sin γ (v²/(2h) + g_v), with γ the flight-path angle below the horizontal, h the height
    above the terminal surface and g_v the known vertical acceleration (vertical descent: the
    constant deceleration that stops at the surface). The switch is latched per lander when
    that demand first reaches ``terminal_fraction`` of T/m (from orbit, γ ≈ 0 and the demand is
    nil: without the braking phase the lander would never leave its orbit).

    Parameters
    ----------
    terminal_fraction : float
        In (0, 1]; default 0.8 (a 20 % thrust reserve for the terminal phase).
    include_rotation : bool
    name : str
    """

    def __init__(self, terminal_fraction: float = 0.8, include_rotation: bool = True,
                 name: str = "gravity turn") -> None:
        self.include_rotation = bool(include_rotation)
        self.terminal_fraction = _check_range("terminal_fraction", terminal_fraction, 1e-3,
                                              1.0)
        self.name = name

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self.terminal = np.zeros(len(case_ids), dtype=bool)

    def act(self, nav: Navigation) -> ThrustCommand:
        self.terminal[nav.episode_start] = False
        f = nav.frame
        if not self.include_rotation:
            f = dataclasses.replace(f, g=f.g_without_spin)
        direction = gd.gravity_turn_direction(f.v)
        full = accel = self.full_thrust_accel(nav, f.mass_kg)
        if self.throttled:
            speed = np.linalg.norm(f.v, axis=1)
            sin_gamma = np.clip(-f.v[:, -1] / np.maximum(speed, 1e-9), 0.0, 1.0)
            g_v = np.maximum(-f.g[:, -1], 0.0)
            need = sin_gamma * (speed * speed / (2.0 * np.maximum(f.height_m, 1.0)) + g_v)
            self.terminal |= need >= self.terminal_fraction * accel
            accel = np.where(self.terminal, np.minimum(need, accel), accel)
        return self.command(nav, direction * accel[:, None], full, f.mass_kg)


def _check_range(name: str, value, lo: float, hi: float) -> float:
    """``value`` as a float in [lo, hi]; ``ValueError`` naming it otherwise (NaN included)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r} is not a number; it must be in [{lo:g}, {hi:g}]"
                         ) from None
    if isinstance(value, bool) or not (math.isfinite(v) and lo <= v <= hi):
        raise ValueError(f"{name} = {value!r} is not allowed; it must be in [{lo:g}, {hi:g}]")
    return v
