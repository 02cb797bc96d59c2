"""Explicit guidance laws flying the landers: augmented Apollo (Apollo, ZEM/ZEV) and gravity turn.

Each law implements :class:`agents.common.law.GuidanceLaw`: it reads only the navigation
solution ``nav.state_nd`` and the flight computer's *nominal* scenario, builds the local
frame of :mod:`agents.experts.explicit.frames`, evaluates the pure functions of
:mod:`agents.experts.explicit.guidance` and converts the thrust acceleration into the env's
action (planar: thrust angle φ; 3D: elevation α and azimuth β, clipped to the scenario's
bounds; with the throttle channel also throttle = |a| m / T clipped to [0, 1]).

How an acceleration law flies a constant-thrust engine (decision, issue 30)
---------------------------------------------------------------------------
The envs' default engine burns at full thrust T and can only be steered, as the papers'
vehicles. The law thrusts along its commanded thrust acceleration and chooses t_go at every
decision so that the command's magnitude *equals* T/m (``tgo=matched``, the default:
:func:`~agents.experts.explicit.guidance.thrust_matched_tgo` on its long, braking branch;
``matched-short`` takes the short, hurried root): the command is then flown exactly.
``tgo=rocket`` takes instead the burn time in which the rocket equation gains |ZEV|
(:func:`~agents.experts.explicit.guidance.rocket_tgo`); the command's direction is flown at
full thrust. The option ``tgo_margin`` = μ scales the rule's t_go, t_go = (1 + μ)·t_rule.
The laws re-plan every decision; the surplus or shortfall of a command flown at T/m is
corrected at the next one.

With the throttle channel (``gym.make(id, throttle_channel=True)``) the law is the textbook one:
t_go counts down from a planned descent time t_f = (1 + μ)·t_matched fixed at the first
decision (``tgo=countdown``, the default there), and the throttle is |a_thrust| m / T.

The planar env has no landing site (its task ends at any downrange), so on the downrange axis
the law uses the free-terminal-position optimum (:func:`~agents.experts.explicit.guidance.
free_position_thrust`) and (A) only on the vertical axis.

Lead time ([K74]; Luminary carries ≈2.2 s): with ``lead`` = τ > 0 the navigated state is first
extrapolated τ seconds with the known acceleration plus the previous thrust command, and the
command is computed for that state (it is the state at which the command will act).
"""

from __future__ import annotations

import math

import numpy as np

from agents.common.law import FlightComputer, GuidanceLaw, Navigation
from agents.experts.explicit import guidance as gd
from agents.experts.explicit.frames import LocalFrame, pinpoint_frame, planar_frame
from lunar_env.envs.pinpoint_landing import action_from_angles
from lunar_env.envs.soft_landing import action_from_thrust_angle
from lunar_env.scenarios import PinpointScenario, PlanarScenario

__all__ = ["AugmentedApolloLaw", "GravityTurnLaw", "TGO_RULES", "TGO_MAX_S"]

#: the t_go rules: ``matched`` (the long, braking root; constant thrust), ``matched-short``
#: (the short root), ``rocket`` (burn time from the rocket equation), all re-solved every
#: decision; ``countdown`` (throttled: a planned descent time that shrinks)
TGO_RULES = ("matched", "matched-short", "rocket", "countdown")
#: upper end of the t_go search (s): longer than any descent of the scenarios (≤ 800 s)
TGO_MAX_S = 3000.0
#: lower end of the t_go search and floor of the countdown (s)
TGO_MIN_S = 0.05


class _ExplicitBase(GuidanceLaw):
    """Shared plumbing: the scenario's geometry, the frame, and the action mapping."""

    def __init__(self, include_rotation: bool = True) -> None:
        self.include_rotation = bool(include_rotation)

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        sc = computer.scenario
        self.scaling = sc.scaling()
        self.thrust_n = float(sc.vehicle.thrust_n)
        self.exhaust_velocity = float(sc.vehicle.exhaust_velocity_m_s)
        n_act = int(computer.action_space.shape[0])
        if isinstance(sc, PlanarScenario):
            self.planar = True
            self.dry_mass_kg = float(sc.vehicle.dry_mass_kg)
            self.throttled = n_act == 2
            self.surface_radius_m = float(sc.surface_radius_m)
        elif isinstance(sc, PinpointScenario):
            self.planar = False
            self.dry_mass_kg = float(sc.vehicle.dry_mass_kg)
            self.throttled = n_act == 3
            self.plane_normal = np.asarray(sc.plane_normal())
            self.target_m = np.asarray(sc.target_position_m())
            self.spin_rate = float(sc.body.spin_rate_rad_s)
            self.alpha_bounds = sc.alpha_bounds_rad
            self.beta_bounds = sc.beta_bounds_rad
        else:
            raise ValueError(f"scenario {getattr(sc, 'name', sc)!r} is neither planar nor "
                             "pinpoint; the explicit laws fly LunarSoftLanding and "
                             "LunarPinpointLanding")

    def frame(self, state_nd: np.ndarray) -> LocalFrame:
        """The local frame of the navigated states (``ValueError`` on a non-finite state)."""
        s = gd.check_state("navigated state (nav.state_nd)", state_nd)
        if self.planar:
            return planar_frame(s, self.scaling, self.surface_radius_m)
        return pinpoint_frame(s, self.scaling, self.plane_normal, self.target_m,
                              self.spin_rate, self.include_rotation)

    def to_action(self, a_thrust: np.ndarray, mass_kg: np.ndarray) -> np.ndarray:
        """Actions (N, n_act) float32 steering along ``a_thrust`` (N, d) (m/s², local frame),
        with throttle |a| m / T on a throttled engine."""
        mag = np.linalg.norm(a_thrust, axis=1)
        if self.planar:
            # φ from the local horizontal, cos φ > 0 brakes (thrust against +downrange motion)
            act = action_from_thrust_angle(np.arctan2(a_thrust[:, 1], -a_thrust[:, 0]))[:, None]
        else:
            alpha = np.arcsin(np.clip(a_thrust[:, 2] / np.maximum(mag, 1e-300), -1.0, 1.0))
            # β from +along-track, centred on π (braking) so that the bounds' wrap is harmless
            beta = math.pi + np.arctan2(-a_thrust[:, 1], -a_thrust[:, 0])
            act = action_from_angles(alpha, beta, self.alpha_bounds, self.beta_bounds)
        if self.throttled:
            thr = np.clip(mag * mass_kg / self.thrust_n, 0.0, 1.0)
            act = np.concatenate([act, (2.0 * thr - 1.0)[:, None]], axis=1)
        return act.astype(np.float32)


class AugmentedApolloLaw(_ExplicitBase):
    """Augmented Apollo explicit guidance ([L18]; k_r = 12 Apollo [K74], 6 ZEM/ZEV [GHW]).

    Parameters
    ----------
    k_r : float
        Gain in [6, 24] (:func:`agents.experts.explicit.guidance.check_gain`).
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
        super().__init__(include_rotation)
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
        d = 2 if self.planar else 3
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

        Planar: zero (the vertical axis ends like a soft touchdown; the downrange axis is free).
        3D: a_T must be reachable with the thrust inside the scenario's elevation bound (α ≤
        40° for ``peng2012``): Apollo's a_T = 0 means hovering at the gate, α = 90°, which
        the env clips to 40° and the landing fails (measured: 0 % on the throttled engine).
        We take the thrust at the gate braking along the track at α_T = α_max − 5°, with
        magnitude 3/4 of T at the dry mass, plus gravity at the gate: the lander then
        arrives from above and behind along −a_T, with its thrust inside the bounds.
        """
        if self.planar:
            return np.zeros(2)
        alpha = self.alpha_bounds[1] - math.radians(5.0)
        thrust = 0.75 * self.thrust_n / self.dry_mass_kg
        r_gate = float(np.linalg.norm(self.target_m))
        g_gate = self.scaling.mu_m3_s2 / (r_gate * r_gate)
        return np.array([-thrust * math.cos(alpha), 0.0, thrust * math.sin(alpha) - g_gate])

    def command_fn(self, f: LocalFrame):
        """``command(t_go, rows) -> (n, d)`` thrust acceleration of this law in frame ``f``
        (the callable :func:`~agents.experts.explicit.guidance.thrust_matched_tgo` solves)."""
        # validated once here, not at each of the ~80 evaluations of the t_go root find
        gd.check_gain(self.k_r)

        def command(t_go, rows):
            v, g = f.v[rows], f.g[rows]
            a = gd.augmented_apollo_thrust(0.0, v, f.r_to_target[rows], 0.0, self.a_t, g,
                                           t_go, self.k_r, check=False)
            if self.planar:  # free landing site: the downrange axis has no position target
                a[:, 0] = gd.free_position_thrust(v[:, 0:1], 0.0, g[:, 0:1], t_go,
                                                  check=False)[:, 0]
            return a

        return command

    def act(self, nav: Navigation) -> np.ndarray:
        f = self.frame(nav.state_nd)
        accel = self.thrust_n / f.mass_kg
        if self.aim_above_m > 0.0:
            rel = f.r_to_target.copy()
            rel[:, -1] += self.aim_above_m
            f = LocalFrame(r_to_target=rel, v=f.v, g=f.g, mass_kg=f.mass_kg,
                           height_m=f.height_m)
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
        return self.to_action(a, f.mass_kg)

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
        if prev.shape[0] != len(accel) or not np.isfinite(prev).all():
            prev = accel[:, None] * gd.gravity_turn_direction(f.v)
        tau = self.lead_s
        acc = f.g + prev
        return LocalFrame(r_to_target=f.r_to_target - f.v * tau - 0.5 * acc * tau * tau,
                          v=f.v + acc * tau, g=f.g, mass_kg=f.mass_kg,
                          height_m=f.height_m + f.v[:, -1] * tau)


class GravityTurnLaw(_ExplicitBase):
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
        super().__init__(include_rotation)
        self.terminal_fraction = _check_range("terminal_fraction", terminal_fraction, 1e-3,
                                              1.0)
        self.name = name

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self.terminal = np.zeros(len(case_ids), dtype=bool)

    def act(self, nav: Navigation) -> np.ndarray:
        f = self.frame(nav.state_nd)
        direction = gd.gravity_turn_direction(f.v)
        accel = self.thrust_n / f.mass_kg
        if self.throttled:
            speed = np.linalg.norm(f.v, axis=1)
            sin_gamma = np.clip(-f.v[:, -1] / np.maximum(speed, 1e-9), 0.0, 1.0)
            g_v = np.maximum(-f.g[:, -1], 0.0)
            need = sin_gamma * (speed * speed / (2.0 * np.maximum(f.height_m, 1.0)) + g_v)
            self.terminal |= need >= self.terminal_fraction * accel
            accel = np.where(self.terminal, np.minimum(need, accel), accel)
        return self.to_action(direction * accel[:, None], f.mass_kg)


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
