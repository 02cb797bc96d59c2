"""The 3D pinpoint expert (``LunarPinpointLanding-v*``): :class:`PinpointPontryaginExpert`, the
optimal feedback of :mod:`optimizers.indirect.pinpoint_feedback` as a guidance law, and the
labeller of the pinpoint datasets and of DAgger."""

from __future__ import annotations

import dataclasses

import numpy as np

from guidance.law import FlightComputer, GuidanceLaw, Navigation
from guidance.laws.engine_estimate import ThrustScaleEstimator
from guidance.laws.terminal_window import TerminalWindow
from lunar_env.envs.pinpoint_landing import action_from_angles
from optimizers.indirect.pinpoint_feedback import PinpointFeedback
from optimizers.optimum import plant_scenario

__all__ = ["PinpointPontryaginExpert", "PinpointReserveExpert", "PINPOINT_LABEL_STATUSES"]

#: a re-plan inside the terminal window replaces the plan flown if its margin is at most this
#: much smaller (m): the gate's navigated height moves by its noise (0.33 m at 1σ under
#: ``standard``) between decisions
_REPLAN_TOLERANCE_M = 0.5

#: statuses of :class:`PinpointPontryaginExpert` decisions that are the extremal's law, hence
#: labels; "stale" and "fallback" (no converged solve) are guesses and are not
PINPOINT_LABEL_STATUSES = ("optimal", "nearest", "hold")


class PinpointPontryaginExpert(GuidanceLaw):
    """Closed-loop optimal feedback for ``LunarPinpointLanding-v*``: at every decision the
    minimum-time extremal from the lander's current state (:class:`optimizers.indirect.
    pinpoint_feedback.PinpointFeedback`, compiled Pontryagin shooting warm-started from the
    previous decision's extremal, ~1-15 ms), flown over the env step as its mean angle.

    A guidance law on the navigation solution (:meth:`act`), and the labeller of the pinpoint
    datasets and of DAgger (:meth:`labels`, which the privileged teachers call with the truth).
    Where the target is out of reach (a lander too
    fast to stop at it), the extremal to the nearest reachable stop on the track is flown;
    the per-decision statuses are counted in :attr:`status_counts`.

    Parameters
    ----------
    scenario : PinpointScenario
    feedback_kwargs : forwarded to :class:`PinpointFeedback` (``step_s``, ``hold_s``, ...).
    """

    name = "Pontryagin feedback expert"

    def __init__(self, scenario, **feedback_kwargs) -> None:
        self.scenario = scenario
        self.feedback = PinpointFeedback(scenario, **feedback_kwargs)
        self.status_counts: dict[str, int] = {}

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        """New flights: forget the previous extremals, and keep them above the gate where the
        env counts it (its ``gate_range_m``: near the target in v2, everywhere in v0/v1)."""
        super().reset(computer, case_ids)
        self.feedback.reset()
        self.feedback.gate_floor_range_m = computer.gate_range_m

    def angles(self, states_nd: np.ndarray, t_s: np.ndarray, dt_s: float,
               active: np.ndarray | None = None, thrust_scale=None) -> np.ndarray:
        """(α, β) (rad), (B, 2), of the extremals from states (B, 7) at episode times (B,)
        (``thrust_scale``: each row's engine / the scenario's, see :class:`PinpointFeedback`)."""
        ang = self.feedback(states_nd, t_s, dt_s, active, thrust_scale)
        act = np.ones(len(ang), dtype=bool) if active is None else np.asarray(active, bool)
        for st, a in zip(self.feedback.last_status, act, strict=True):
            if a:
                self.status_counts[st] = self.status_counts.get(st, 0) + 1
        return ang

    def labels(self, state_nd: np.ndarray, t_s: np.ndarray, active: np.ndarray | None = None,
               thrust_scale=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The expert's decision at normalised states (B, 7) and episode times (B,) (s).

        Returns ``(angles, actions, is_label)``: (α, β) (rad) and the env actions (float32),
        both (B, 2), and (B,) bool: the row is active (``active``; None: all) and its status is
        one of :data:`PINPOINT_LABEL_STATUSES`. Call :meth:`reset` first.
        """
        ang = self.angles(state_nd, t_s, self.computer.dt_s, active, thrust_scale)
        sc = self.scenario
        actions = action_from_angles(ang[:, 0], ang[:, 1], sc.alpha_bounds_rad,
                                     sc.beta_bounds_rad).astype(np.float32)
        is_label = np.isin(np.asarray(self.last_status), PINPOINT_LABEL_STATUSES)
        if active is not None:
            is_label &= np.asarray(active, dtype=bool)
        return ang, actions, is_label

    def act(self, nav: Navigation) -> np.ndarray:
        self.feedback.reset(np.flatnonzero(nav.episode_start))
        ang = self.labels(nav.state_nd, nav.t_s, nav.active)[0]
        return self.computer.actions_from_controls(np.c_[ang, np.ones(len(ang))])

    @property
    def last_status(self) -> list[str]:
        return self.feedback.last_status


class PinpointReserveExpert(GuidanceLaw):
    """The Pontryagin feedback expert with thrust held in reserve both ways, for a throttled
    engine (``throttle_channel=True``): ``feedback:thrust_reserve=R``.

    At every decision it re-plans, from the navigation solution, the extremal of an engine
    ``1 − R`` times the nominal one (same Isp: a throttle setting) and flies it at throttle
    ``1 − R``. Where that engine's extremal stops more than ``switch_m`` from the target
    along the track, the side it misses on picks the engine: *long* (beyond the target: e.g. a
    weaker engine than nominal), or no extremal at all, the full-thrust extremal at throttle 1,
    as :class:`PinpointPontryaginExpert` flies throughout; *short* (a stronger engine), the
    extremal of ``1 − 2R`` at that throttle. Within ``switch_m`` the reserve engine's own
    extremal is flown to its stop: near the end the stop of a constant-thrust extremal moves
    only at second order with the steering, so its sign flips with every navigation error
    (measured: the engines alternated every decision over the last 60 s and the lander crossed
    the gate at 8.3 m/s), while a stop within tens of metres lands. A constant-thrust
    extremal can only stretch its range so far by steering (the family of extremals folds),
    so a short lander needs less thrust, not more. The reserve is what Apollo's throttled
    guidance keeps by design (a fuel-optimal constant-thrust plan brakes at full thrust, so an
    engine weaker than planned cannot stop in time).

    Parameters
    ----------
    scenario : PinpointScenario
        The nominal scenario.
    thrust_reserve : float
        R in (0, 0.25): the fraction of the nominal thrust kept in hand either way.
    switch_m : float
        The miss along the track (m) beyond which the engine is switched; default 50, a tenth
        of ``LunarPinpointLanding-v2``'s success miss (500 m).
    stop_above_m : float
        Height (m, >= 0) above the target at which the extremals stop. The engine cuts off at
        the stop and the lander falls the rest (from 4 m: 3.6 m/s); an extremal stopped
        exactly at the gate skims it nearly level, so that a navigation altitude error of a
        few metres (3 m at 1σ at the v2 gate under ``standard``) crosses the gate still
        braking at tens of m/s.
    estimate_thrust : bool
        Measure the engine's thrust-acceleration scale with the IMU
        (:class:`guidance.laws.engine_estimate.ThrustScaleEstimator`) and divide
        the commanded throttle by it, so that the engine gives the thrust the plan assumed
        (up to full throttle): the reserve then absorbs a weak engine instead of the plan
        drifting long until the switch. The full engine is then planned with the thrust
        full throttle gives, ``min(1, scale)`` times the nominal.
    terminal_window : bool
        Fly the last seconds as a window (:class:`guidance.laws.terminal_window.
        TerminalWindow`, re-planned every decision) instead of stopping and falling: from the
        first decision at which the extremal flown has at most two decisions to go, as soon
        as the window keeps the navigated gate deeper inside it than the fall from the stop
        would (``min(H, 7.7 m − H)`` for a stop H m up), and then to the end. Fly it with
        ``stop_above_m=12``: the widest windows start 8-16 m up at 10-18 m/s, where the
        extremal is two decisions before a 12 m stop, and an approach that high stays above
        the true gate for altitude errors to 3σ (10 m under ``standard``).
    feedback_kwargs : forwarded to the three experts' :class:`PinpointFeedback`.

    Attributes
    ----------
    decisions : dict[str, int]
        Active decisions flown on the ``"reserve"`` (1 − R), ``"full"`` and ``"low"``
        (1 − 2R) engine, and in the terminal ``"window"``, since construction.
    """

    name = "Pontryagin feedback expert with a thrust reserve"

    def __init__(self, scenario, thrust_reserve: float, switch_m: float = 50.0,
                 stop_above_m: float = 0.0, estimate_thrust: bool = False,
                 terminal_window: bool = False, **feedback_kwargs) -> None:
        r = float(thrust_reserve)
        if not 0.0 < r < 0.25:
            raise ValueError(f"thrust_reserve = {thrust_reserve!r} must be in (0, 0.25)")
        if not float(switch_m) >= 0.0:  # NaN fails too
            raise ValueError(f"switch_m = {switch_m!r} must be a number >= 0 (m)")
        if not float(stop_above_m) >= 0.0:
            raise ValueError(f"stop_above_m = {stop_above_m!r} must be a number >= 0 (m)")
        self.thrust_reserve = r
        self.switch_m = float(switch_m)
        self.stop_above_m = float(stop_above_m)
        if self.stop_above_m > 0.0:
            t = scenario.target
            scenario = dataclasses.replace(
                scenario, name=f"{scenario.name}[stop {self.stop_above_m:g} m above]",
                target=dataclasses.replace(t, altitude_m=t.altitude_m + self.stop_above_m))
        self.full = PinpointPontryaginExpert(scenario, **feedback_kwargs)
        # from R ~ 0.07 a derated engine cannot reach the target from the nominal start
        # (measured: 95 % lands there in 575 s, 93 % stops 1.5 km beyond), so its cold starts
        # get the nominal engine's extremal, a neighbour, in place of its own
        guess = self.full.feedback.nominal_costates()
        self.planned, self.low = (
            PinpointPontryaginExpert(plant_scenario(scenario, scale, 1.0), nominal_guess=guess,
                                     **feedback_kwargs) for scale in (1.0 - r, 1.0 - 2.0 * r))
        self.decisions = {"reserve": 0, "full": 0, "low": 0, "window": 0}
        self.last_status: list[str] = []
        self.terminal_window = bool(terminal_window)
        self.window: TerminalWindow | None = None
        self.estimator = None
        if estimate_thrust:
            self.estimator = ThrustScaleEstimator(self.full.scenario.vehicle.thrust_n)

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        """New flights; ``ValueError`` unless the env has a throttle channel (and an IMU, to
        estimate the thrust)."""
        if not computer.throttled:
            raise ValueError(f"a thrust reserve needs the throttle channel (throttle_channel="
                             f"True); {computer.env_id} has none")
        if self.estimator is not None and "imu" not in computer.sensors:
            raise ValueError(f"estimate_thrust needs the IMU; {computer.env_id}'s flight "
                             "computer has none")
        self._mass_ref_kg = float(computer.scenario.scaling().mass_kg)
        super().reset(computer, case_ids)
        for expert in (self.planned, self.full, self.low):
            expert.reset(computer, case_ids)
        if self.estimator is not None:
            self.estimator.reset(len(case_ids))
        if self.terminal_window:
            sc = computer.scenario
            if self.window is None or self.window.dt_s != float(computer.dt_s):
                v = sc.vehicle
                self.window = TerminalWindow(v.thrust_n, v.exhaust_velocity_m_s,
                                             sc.alpha_bounds_rad, sc.beta_bounds_rad,
                                             float(computer.dt_s))
            n = len(case_ids)
            self.in_window = np.zeros(n, dtype=bool)
            self._top_m = np.full(n, np.nan)
            self._plans: list[np.ndarray | None] = [None] * n
            self._margin_m = np.full(n, -np.inf)

    def start_episodes(self, rows: np.ndarray) -> None:
        """Rows ``rows`` start new episodes: forget their extremals, estimates and windows."""
        for expert in (self.planned, self.full, self.low):
            expert.feedback.reset(rows)
        if self.estimator is not None:
            self.estimator.reset_rows(rows)
        if self.window is not None:
            for i in rows:
                self.in_window[i], self._top_m[i], self._plans[i] = False, np.nan, None
                self._margin_m[i] = -np.inf

    def act(self, nav: Navigation) -> np.ndarray:
        self.start_episodes(np.flatnonzero(nav.episode_start))
        active = np.asarray(nav.active, dtype=bool)
        mass_kg = nav.state_nd[:, 6] * self._mass_ref_kg
        if self.estimator is not None:
            self.estimator.observe(nav.sensors["imu"], mass_kg, active)
        everyone = active
        if self.window is not None:
            active = active & ~self.in_window  # landers in their window fly it
        # the full engine is what full throttle gives: a weak engine's estimate (below 1) is
        # all it has, so its extremal is planned with that thrust (a stronger one is throttled
        # back to the nominal); planned at the nominal thrust, a lander 2.4 % weak believed
        # itself short by 960 m, stretched its range and landed 1.5 km long (measured)
        full_scale = (None if self.estimator is None
                      else np.minimum(np.asarray(self.estimator.scale, dtype=float), 1.0))
        angles, actions, throttle, tgo, status, long, short = self.extremals(
            nav.state_nd, nav.t_s, active, full_scale=full_scale)
        off = short | long
        if self.estimator is not None:
            throttle = np.clip(throttle / self.estimator.scale, 0.0, 1.0)
        windowed = np.zeros(len(active), dtype=bool)
        if self.window is not None:
            windowed = self._fly_windows(nav, everyone, tgo, angles, actions, throttle)
        status[windowed] = "window"
        #: per row, the status of the decision flown: the flying extremal's (see
        #: :data:`PINPOINT_LABEL_STATUSES`; "stale" / "fallback": no converged solve, a guess)
        #: or "window"
        self.last_status = [str(x) for x in status]
        self.decisions["full"] += int((long & ~windowed).sum())
        self.decisions["low"] += int((short & ~windowed).sum())
        self.decisions["reserve"] += int((active & ~off & ~windowed).sum())
        self.decisions["window"] += int(windowed.sum())
        if self.estimator is not None:
            self.estimator.record(throttle, mass_kg, everyone)
        self._commanded = np.concatenate([actions, (2.0 * throttle - 1.0)[:, None]],
                                         axis=1).astype(np.float32)
        return self._commanded.copy()

    def extremals(self, state_nd: np.ndarray, t_s: np.ndarray, active: np.ndarray,
                  plan_scale=None, full_scale=None):
        """The engine chosen for each lander and its extremal (class docstring): the reserve
        engine's extremal, or, where it stops more than ``switch_m`` long (or there is none),
        the full engine's, or, more than ``switch_m`` short, the ``1 − 2R`` engine's.
        ``plan_scale`` multiplies the reserve and ``1 − 2R`` engines, ``full_scale`` the full
        one (each (N,) or None: 1; see :meth:`PinpointPontryaginExpert.labels`).

        Returns ``(angles, actions, throttle, tgo_s, status, long, short)``: (N, 2) angles and
        actions, (N,) throttles (fractions of the planned engines: 1 − R, 1 or 1 − 2R), times
        to go (s), statuses (object array) and the two switched masks.
        """
        angles, actions, _ = self.planned.labels(state_nd, t_s, active, plan_scale)
        status = np.array(self.planned.last_status, dtype=object)
        tgo = np.array(self.planned.feedback.last_tgo_s, dtype=float)
        # states are normalised by length, mu and the initial mass: the derated engines'
        # plans read the same normalised states as the nominal one's
        beyond = self.planned.feedback.last_beyond_m
        short = active & (beyond < -self.switch_m)
        long = active & ~short & ~(beyond <= self.switch_m)  # NaN (no extremal): long
        throttle = np.full(len(active), 1.0 - self.thrust_reserve)
        for rows, expert, level, scale in (
                (long, self.full, 1.0, full_scale),
                (short, self.low, 1.0 - 2.0 * self.thrust_reserve, plan_scale)):
            if rows.any():
                ang, act, _ = expert.labels(state_nd, t_s, rows, scale)
                angles[rows], actions[rows] = ang[rows], act[rows]
                status[rows] = np.array(expert.last_status, dtype=object)[rows]
                throttle[rows] = level
                tgo[rows] = np.asarray(expert.feedback.last_tgo_s)[rows]
        return angles, actions, throttle, tgo, status, long, short

    def flown(self, nav: Navigation, actions: np.ndarray) -> None:
        """As a teacher (:class:`agents.imitation.teachers.Teacher`) while another policy flies:
        that policy flew ``actions`` (N, 3) at this decision. The thrust estimate records
        those controls, not this law's (else it credits the engine with the difference), and
        a lander in its window flown off its plan takes the next re-plan from where it is
        (the plan's promised margin no longer holds)."""
        actions = np.asarray(actions, dtype=np.float64)
        active = np.asarray(nav.active, dtype=bool)
        if self.estimator is not None:
            throttle = np.clip(0.5 * (actions[:, 2] + 1.0), 0.0, 1.0)
            self.estimator.record(throttle, nav.state_nd[:, 6] * self._mass_ref_kg, active)
        if self.window is not None:
            off = active & self.in_window & np.any(
                np.abs(actions - self._commanded) > 1e-6, axis=1)
            self._margin_m[off] = -np.inf

    def _fly_windows(self, nav: Navigation, active: np.ndarray, tgo_s: np.ndarray,
                     angles: np.ndarray, actions: np.ndarray, throttle: np.ndarray
                     ) -> np.ndarray:
        """Overwrite, in place, the controls of the landers in (or entering) their terminal
        window: those already in it, and those whose extremal has at most two decisions to go
        (``tgo_s``) and whose window beats the fall from the stop. Returns (N,) bool: the rows
        flown in their window."""
        dt = float(self.computer.dt_s)
        rows = active & (self.in_window | (tgo_s <= 2.0 * dt))
        windowed = np.zeros(len(active), dtype=bool)
        if not rows.any():
            return windowed
        idx = np.flatnonzero(rows)
        # the frame of the env's own gate (the extremals' target may be raised above it)
        f = self.computer.frame_of(nav.state_nd[idx])
        scale = (np.ones(len(nav.state_nd)) if self.estimator is None
                 else np.asarray(self.estimator.scale, dtype=float))
        h_stop = self.stop_above_m
        fall_margin_m = min(h_stop, self.window.success_speed ** 2 / (2.0 * -f.g[0, 2]) - h_stop)
        sc = self.computer.scenario
        for k, i in enumerate(idx):
            speed = float(np.linalg.norm(f.v[k]))
            if self.in_window[i] and np.isnan(self._top_m[i]) and speed <= self.window.speed_limit:
                self._top_m[i] = f.height_m[k]  # inside the window from here down
            top = None if np.isnan(self._top_m[i]) else float(self._top_m[i])
            plan = self.window.plan(f.v[k], f.height_m[k], f.mass_kg[k], f.g[k], scale[i], top,
                                    previous=self._plans[i])
            # in the window, a re-plan replaces the plan flown only if it promises as much:
            # the plan's margins cover the errors, while its constraints are active, so the
            # errors of a step can leave the rest of it just infeasible from the new state
            # and the re-plan worse (measured: a promised 6.7 m fell to 3.3 m, 5.1 m/s)
            better = plan is not None and (
                plan.margin_m >= self._margin_m[i] - _REPLAN_TOLERANCE_M if self.in_window[i]
                else plan.margin_m > fall_margin_m)
            if better:
                self.in_window[i] = True
                self._plans[i], self._margin_m[i] = plan.controls, plan.margin_m
            elif self.in_window[i] and self._plans[i] is not None:
                # the plan flown, a step on
                prev = self._plans[i]
                self._plans[i] = np.vstack([prev[1:], prev[-1:] * [1.0, 1.0, 0.0]])
            else:
                continue
            angles[i], throttle[i] = self._plans[i][0, :2], self._plans[i][0, 2]
            windowed[i] = True
        if windowed.any():
            actions[windowed] = action_from_angles(angles[windowed, 0], angles[windowed, 1],
                                                   sc.alpha_bounds_rad, sc.beta_bounds_rad)
        return windowed
