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

Phases to touchdown on a site ([K74]; the Apollo 11 press kit, NASA release 69-83K, 1969)
-----------------------------------------------------------------------------------------
Where the episode ends at touchdown on the site (``LunarPinpointLanding-v3``,
:attr:`guidance.families.GuidanceFamily.lands_on_site`), the law flies Apollo's phases
(:class:`DescentPhases`) instead of aiming at the site itself, where t_go → 0 would amplify
every navigation error: the braking phase (P63) to a *high gate* above and uprange of the site,
the approach (P64) to a *low gate* straight above it, then terminal descent (P66) at a constant
rate of descent with the horizontal velocity nulled, throttled from the IMU-measured thrust.
Each gate's t_go is planned once and counted down (the throttled engine's rule above): the
braking phase's by the law's t_go rule, or at the least-effort time where the engine's full
thrust would only be met by a hurried profile (a throttled engine need not hurry), planned at
the first decision the IMU has measured the engine; the approach's as the straight line from
the high gate to the low gate at a constant deceleration. A gate counts as reached when its
t_go falls to :attr:`DescentPhases.switch_s` (the low gate also when the navigated height is
at or below it). A command the engine cannot give keeps its vertical component first.

Lead time ([K74]; Luminary carries ≈2.2 s): with ``lead`` = τ > 0 the navigated state is first
extrapolated τ seconds with the known acceleration plus the previous thrust command, and the
command is computed for that state (it is the state at which the command will act).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from guidance import explicit as gd
from guidance.frames import LocalFrame
from guidance.law import FlightComputer, GuidanceLaw, Navigation, ThrustCommand
from guidance.laws.engine_estimate import ThrustScaleEstimator

__all__ = ["AugmentedApolloLaw", "GravityTurnLaw", "DescentPhases", "TGO_RULES", "TGO_MAX_S",
           "PHASE_HIGH_GATE", "PHASE_LOW_GATE", "PHASE_TERMINAL"]

#: the t_go rules: ``matched`` (the long, braking root; constant thrust), ``matched-short``
#: (the short root), ``rocket`` (burn time from the rocket equation), all re-solved every
#: decision; ``countdown`` (throttled: a planned descent time that shrinks)
TGO_RULES = ("matched", "matched-short", "rocket", "countdown")
#: upper end of the t_go search (s): longer than any descent of the scenarios (≤ 800 s)
TGO_MAX_S = 3000.0
#: lower end of the t_go search and floor of the countdown (s)
TGO_MIN_S = 0.05


#: phase numbers of :attr:`AugmentedApolloLaw.phase`: braking to the high gate (P63), approach
#: to the low gate (P64), terminal descent (P66)
PHASE_HIGH_GATE, PHASE_LOW_GATE, PHASE_TERMINAL = 0, 1, 2


@dataclass(frozen=True)
class DescentPhases:
    """Apollo's phases of a landing on a site: braking to a high gate, approach to a low gate,
    terminal descent at a constant rate (module docstring). Heights are above the site's
    surface; the gates lie in the plane of the lander's along-track axis through the site.

    Every default is for the 600 kg lander of ``peng2012_touchdown`` (300 kg of propellant,
    of which the certified optimum leaves 22 kg); the gate speed, the low gate and the rate
    were chosen by measurement on development cases (``benchmarks/bench_phases.py``: seeds
    10 000 and up under ``standard``, not the campaigns' seed-0 cases).

    Attributes
    ----------
    low_gate_m : float
        Height of the low gate, straight above the site (m), in [5, 500]
        (:data:`LOW_GATE_RANGE_M`). Apollo's low gate was at 500 ft (152 m) and its vertical
        descent began at about 150 ft (46 m) with the forward velocity nulled (Apollo 11 press
        kit). Here terminal descent costs the hover's propellant, 0.18 kg/s at this lander's
        landing mass (≈520 N at Isp 300 s), and the lander has ~22 kg over the optimum for
        everything (Apollo kept two minutes of hover): default 15 m, 15 s at 1 m/s (measured:
        the same success as 30 m with 2.6 kg less propellant).
    rate_m_s : float
        Rate of descent held in terminal descent (m/s), in [0.2, 2.9]
        (:data:`RATE_RANGE_M_S`); also the low gate's velocity (straight down). Apollo 11
        planned 3 ft/s (0.9 m/s) (press kit). Default 1 m/s: Apollo's, a third of the landing
        gear's 3 m/s limit (NASA TN D-6850); 1.5 m/s measured the same success for 0.9 kg
        less.
    high_gate_m : float
        Height of the high gate (m): 0 for none (braking straight to the low gate), else in
        (low gate, :data:`HIGH_GATE_MAX_M`]. Apollo's braking phase ended at about 7,000 ft
        (2.1 km) (press kit). Default 2000 m (measured: ZEM/ZEV without the high gate lands
        one development case fewer in a hundred).
    high_gate_angle_deg : float
        Elevation of the high gate seen from the low gate (degrees), in [2, 45]: the
        approach's line of sight. Default 10°: where this lander's certified optimum crosses
        2 km (line of sight 10.2° from the site, flight-path angle 9°), so the gate lies on the
        fuel-optimal path (Apollo's approach was steeper for the crew's view of the site,
        which this uncrewed lander does not need).
    high_gate_speed_m_s : float
        Speed at the high gate along the line of sight toward the low gate (m/s), in
        (0, 1000]. Default 250 m/s, measured: the certified optimum crosses 2 km at 289 m/s
        at full thrust, and a gate at that speed leaves the approach no thrust margin (91 %
        success with ZEM/ZEV, none with Apollo's gain, against 95 % and 94 % at 250 m/s);
        250 m/s is the fastest measured speed (the least propellant) at which Apollo's gain
        still lands (at 270 m/s it lands none, ZEM/ZEV still 95 %).
    switch_s : float
        t_go (s) at which a gate counts as reached, in [0.5, 20]. Default 2 s: two decisions
        of 1 s; the explicit law's position gain grows as 1/t_go² and below 2 s it turns the
        navigation noise into thrust swings (a choice).
    rate_tau_s : float
        Time constant of the rate-of-descent loop (s), in [0.5, 20]. Default 2 s (a choice:
        two decisions, so the loop does not ring with the 1-s hold).
    horizontal_tau_s : float
        Time constant of the horizontal-velocity nulling (s), in [0.5, 30]. Default 3 s (a
        choice: slower than the rate loop, which keeps the thrust near the vertical).
    max_tilt_deg : float
        Largest tilt of the thrust from the vertical in terminal descent (degrees), in
        [0, 60]. Default 45° (a choice: the horizontal correction may reach the vertical
        thrust, about 1.6 m/s² near hover, so the few m/s a gate law leaves at the low gate
        are nulled within seconds; the rate loop keeps its vertical thrust whatever the tilt).
    """

    low_gate_m: float = 15.0
    rate_m_s: float = 1.0
    high_gate_m: float = 2000.0
    high_gate_angle_deg: float = 10.0
    high_gate_speed_m_s: float = 250.0
    switch_s: float = 2.0
    rate_tau_s: float = 2.0
    horizontal_tau_s: float = 3.0
    max_tilt_deg: float = 45.0

    def __post_init__(self) -> None:
        for name, (lo, hi) in _PHASE_RANGES.items():
            object.__setattr__(self, name, _check_range(name, getattr(self, name), lo, hi))
        hg = self.high_gate_m
        if hg != 0.0 and not (self.low_gate_m < hg <= HIGH_GATE_MAX_M):
            raise ValueError(f"high_gate_m = {hg!r} is not allowed; it must be 0 (no high "
                             f"gate) or in ({self.low_gate_m:g}, {HIGH_GATE_MAX_M:g}] m "
                             "(above the low gate)")

    def targets(self, r_to_site: np.ndarray, phase: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Target position relative to each lander, velocity and total acceleration (N, 3)
        (guidance frame: along-track, cross-track, up) of each row's gate: the high gate for
        rows in :data:`PHASE_HIGH_GATE`, the low gate otherwise."""
        n = len(phase)
        r_t = r_to_site.copy()
        r_t[:, 2] += self.low_gate_m
        v_t = np.zeros((n, 3))
        v_t[:, 2] = -self.rate_m_s
        a_t = np.zeros((n, 3))  # the low gate: constant velocity into terminal descent
        hi = phase == PHASE_HIGH_GATE
        if hi.any():
            gam = math.radians(self.high_gate_angle_deg)
            rise = self.high_gate_m - self.low_gate_m
            back = rise / math.tan(gam)
            r_t[hi, 0] -= back
            r_t[hi, 2] += rise
            v_hg = self.high_gate_speed_m_s * np.array([math.cos(gam), 0.0, -math.sin(gam)])
            v_lg = np.array([0.0, 0.0, -self.rate_m_s])
            # [K74]'s target acceleration: the constant one of the approach flown as a straight
            # line from the high gate to the low gate (duration 2·length/(sum of the speeds))
            length = math.hypot(back, rise)
            t_app = 2.0 * length / (self.high_gate_speed_m_s + self.rate_m_s)
            v_t[hi] = v_hg
            a_t[hi] = (v_lg - v_hg) / t_app
        return r_t, v_t, a_t

    def terminal_thrust(self, f: LocalFrame) -> np.ndarray:
        """Terminal descent's thrust acceleration (N, 3) (m/s²): the rate of descent brought to
        :attr:`rate_m_s` and the horizontal velocity to zero with their time constants,
        against the known acceleration, the tilt from the vertical at most
        :attr:`max_tilt_deg`."""
        up = (-self.rate_m_s - f.v[:, -1]) / self.rate_tau_s - f.g[:, -1]
        up = np.maximum(up, 0.0)
        horiz = -f.v[:, :-1] / self.horizontal_tau_s - f.g[:, :-1]
        mag = np.linalg.norm(horiz, axis=1)
        cap = math.tan(math.radians(self.max_tilt_deg)) * up
        horiz *= (np.minimum(mag, cap) / np.maximum(mag, 1e-300))[:, None]
        return np.concatenate([horiz, up[:, None]], axis=1)


#: allowed range of the low gate's height (m): above the last decision's fall at the rate
#: (a few metres), below the highest gate a hover of this lander's propellant could descend
LOW_GATE_RANGE_M = (5.0, 500.0)
#: allowed range of the terminal rate of descent (m/s): positive, below the landing gear's
#: 3 m/s limit
RATE_RANGE_M_S = (0.2, 2.9)
#: the highest high gate (m): below the env's start (15 km)
HIGH_GATE_MAX_M = 10000.0
_PHASE_RANGES = {"low_gate_m": LOW_GATE_RANGE_M, "rate_m_s": RATE_RANGE_M_S,
                 "high_gate_m": (0.0, HIGH_GATE_MAX_M), "high_gate_angle_deg": (2.0, 45.0),
                 "high_gate_speed_m_s": (1e-3, 1000.0), "switch_s": (0.5, 20.0),
                 "rate_tau_s": (0.5, 20.0), "horizontal_tau_s": (0.5, 30.0),
                 "max_tilt_deg": (0.0, 60.0)}


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

    def flown(self, nav: Navigation, actions: np.ndarray) -> None:
        """Another policy flew ``actions`` (N, n_act) at the decision of ``nav`` (this law
        is a DAgger teacher flying along): the thrust estimate records the throttle those
        actions gave the engine, not this law's own, so the next IMU reading is divided by the
        throttle that produced it. (Measured on ``LunarPinpointLanding-v3`` with the IMU: fed
        its own throttles while a student flew, ZEM/ZEV's engine estimate was off by the ratio
        of the two throttles, and its labels planned with that engine.)"""
        if self.estimator is not None:
            self.estimator.record_flown(self.computer, actions, nav.frame.mass_kg, nav.active)


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
    phases : DescentPhases, bool or None
        Apollo's phases to touchdown on the site (module docstring): None (default) flies
        :class:`DescentPhases`' defaults where the env lands on its site
        (:attr:`guidance.families.GuidanceFamily.lands_on_site`) and aims at the target
        directly elsewhere; False never flies phases; a :class:`DescentPhases` flies those
        (only where the env lands on its site).
    name : str

    Attributes
    ----------
    phase : ndarray of int, shape (N,)
        With phases: each lander's phase (:data:`PHASE_HIGH_GATE`, :data:`PHASE_LOW_GATE`,
        :data:`PHASE_TERMINAL`) after the last decision.
    """

    def __init__(self, k_r: float = gd.K_R_APOLLO, tgo_margin: float = 0.0,
                 lead_s: float = 0.0, tgo_rule: str | None = None,
                 terminal_accel_m_s2=None, include_rotation: bool = True,
                 terminal_s: float = 0.0, aim_above_m: float = 0.0,
                 phases: DescentPhases | bool | None = None,
                 name: str | None = None) -> None:
        if not (phases is None or isinstance(phases, bool | DescentPhases)):
            raise ValueError(f"phases = {phases!r} is not allowed; use None (the env "
                             "family's default), False or a DescentPhases")
        self.phases = phases
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
        self.descent = self._descent_phases(computer)
        if self.descent is not None:
            self.phase = np.full(n, self._first_phase(), dtype=np.int64)
        self.prev_thrust = np.full((n, d), np.nan)
        self.t_final = np.full(n, np.nan)
        #: t_go (s) of the last decision, per lander (for analysis)
        self.last_tgo = np.full(n, np.nan)

    def _descent_phases(self, computer: FlightComputer) -> DescentPhases | None:
        """The phases flown on ``computer``'s env (None: aim at the target directly)."""
        from guidance.families import guidance_family

        lands = bool(getattr(guidance_family(computer.scenario), "lands_on_site", False))
        if self.phases is None:
            chosen = DescentPhases() if lands else None
        elif self.phases is False:
            chosen = None
        elif not lands:
            raise ValueError(f"descent phases fly a landing on a site to touchdown; "
                             f"{computer.env_id} does not end at touchdown on its target")
        else:
            chosen = DescentPhases() if self.phases is True else self.phases
        if chosen is not None and (self.aim_above_m > 0.0 or self.terminal_s > 0.0):
            raise ValueError(f"aim_above_m = {self.aim_above_m:g} and terminal_s = "
                             f"{self.terminal_s:g} are options of the law without phases; "
                             "with phases the law aims at its gates (give phases=False to "
                             "use them)")
        return chosen

    def _first_phase(self) -> int:
        return PHASE_HIGH_GATE if self.descent.high_gate_m > 0.0 else PHASE_LOW_GATE

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
        if self.descent is not None:
            return self._act_phased(nav, f, accel)
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

    def _act_phased(self, nav: Navigation, f: LocalFrame, accel: np.ndarray) -> ThrustCommand:
        """One decision of the phased descent (module docstring): each row's gate law, its
        switch to the next phase when the gate is reached, or terminal descent."""
        ph = self.descent
        phase = self.phase
        phase[nav.episode_start] = self._first_phase()
        t_frame = nav.t_s + self.lead_s
        t_go = np.full(f.n, np.nan)
        for _ in range(3):  # a row may pass a gate and the next one's switch in one decision
            gate = phase < PHASE_TERMINAL
            if not gate.any():
                break
            r_t, v_t, a_t = ph.targets(f.r_to_target, phase)
            command = self._gate_command_fn(f, r_t, v_t, a_t)
            # the braking root where there is one; where the engine's full thrust is only met
            # by a hurried profile (a slow lander near its gate), the least-effort time: the
            # engine throttles, it need not hurry
            t_go = (1.0 + self.tgo_margin) * np.maximum(
                self.solve_tgo(f, command, accel, v_t), _least_effort_tgo(command, f.n))
            braking = gate & (phase == self._first_phase())
            t_go = self._countdown(braking, t_go, t_frame)
            # the approach from the high gate: a countdown from the straight line's duration
            # at a constant deceleration to the low gate
            app = gate & ~braking
            if app.any():
                dist = np.linalg.norm(r_t, axis=1)
                speed = np.linalg.norm(f.v, axis=1)
                line = (1.0 + self.tgo_margin) * 2.0 * dist / (speed + ph.rate_m_s)
                t_go = np.where(app, self._countdown(app, line, t_frame), t_go)
            reached = gate & (t_go <= ph.switch_s)
            reached |= (phase == PHASE_LOW_GATE) & (f.height_m <= ph.low_gate_m)
            if not reached.any():
                break
            phase[reached] += 1
            self.t_final[reached] = np.nan
        a = ph.terminal_thrust(f)
        gate = phase < PHASE_TERMINAL
        if gate.any():
            a[gate] = _keep_vertical(command(t_go[gate], np.flatnonzero(gate)), accel[gate])
        self.prev_thrust = a
        self.last_tgo = np.where(gate, t_go, np.nan)
        return self.command(nav, a, accel, f.mass_kg)

    def _countdown(self, rows: np.ndarray, plan: np.ndarray, t_frame: np.ndarray
                   ) -> np.ndarray:
        """t_go (N,) of a countdown on ``rows`` (elsewhere ``plan``): a row without a planned
        end time takes ``plan`` from now, fixed at the first decision its engine has been
        measured (where the law has an IMU; until then ``plan`` is flown one decision at a
        time)."""
        new = rows & ~np.isfinite(self.t_final)
        fix = new & self.estimator.measured if self.estimator is not None else new
        self.t_final[fix] = t_frame[fix] + plan[fix]
        counted = rows & np.isfinite(self.t_final)
        return np.where(counted, np.maximum(self.t_final - t_frame, TGO_MIN_S), plan)

    def _gate_command_fn(self, f: LocalFrame, r_t: np.ndarray, v_t: np.ndarray,
                         a_t: np.ndarray):
        """``command(t_go, rows) -> (n, d)``: this law's thrust acceleration toward the gates
        (per-row target position relative to the lander ``r_t``, velocity ``v_t`` and total
        acceleration ``a_t``, each (N, d))."""
        gd.check_gain(self.k_r)

        def command(t_go, rows):
            return gd.augmented_apollo_thrust(0.0, f.v[rows], r_t[rows], v_t[rows], a_t[rows],
                                              f.g[rows], t_go, self.k_r, check=False)

        return command

    def solve_tgo(self, f: LocalFrame, command, accel: np.ndarray,
                  v_t: np.ndarray | None = None) -> np.ndarray:
        """t_go (s) of the frame's landers by the rule (the countdown plans with ``rocket``)."""
        if self.rule in ("matched", "matched-short", "countdown"):
            branch = "short" if self.rule == "matched-short" else "long"
            return gd.thrust_matched_tgo(command, accel, TGO_MIN_S, TGO_MAX_S, branch)[0]
        if v_t is None:
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


def _least_effort_tgo(command, n: int, n_grid: int = 96) -> np.ndarray:
    """t_go (n,) of the first minimum of the command's magnitude ``|command(t_go, rows)|``
    (the law's natural time), on a geometric grid of ``n_grid`` points over
    [TGO_MIN_S, TGO_MAX_S] (12 % apart: a plan's time, not a root). The first one: for very
    long t_go the magnitude tends to that of the known acceleration, a hover that never
    arrives."""
    grid = np.geomspace(TGO_MIN_S, TGO_MAX_S, n_grid)
    mags = np.linalg.norm(command(np.repeat(grid, n), np.tile(np.arange(n), n_grid)),
                          axis=1).reshape(n_grid, n)
    rising = mags[:-1] <= mags[1:]
    first = np.where(rising.any(axis=0), np.argmax(rising, axis=0), n_grid - 1)
    return grid[first]


def _keep_vertical(a: np.ndarray, accel: np.ndarray) -> np.ndarray:
    """Thrust accelerations ``a`` (n, d) limited to the engine's ``accel`` (n,) (m/s²) with
    the vertical component kept first: a command the engine cannot give loses its horizontal
    part, not its support against gravity (scaling the whole vector down instead lets a weak
    engine sink into the ground short of the gate)."""
    mag = np.linalg.norm(a, axis=1)
    over = mag > accel
    if not over.any():
        return a
    out = a.copy()
    up = np.clip(a[over, -1], -accel[over], accel[over])
    room = np.sqrt(np.maximum(accel[over] ** 2 - up * up, 0.0))
    h = a[over, :-1]
    hmag = np.linalg.norm(h, axis=1)
    out[over, :-1] = h * (np.minimum(hmag, room) / np.maximum(hmag, 1e-300))[:, None]
    out[over, -1] = up
    return out


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
