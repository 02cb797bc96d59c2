"""The 3D pinpoint expert (``LunarPinpointLanding-v*``): :class:`PinpointPontryaginExpert`, the
optimal feedback of :mod:`optimizers.indirect.pinpoint_feedback` as a guidance law, and the
labeller of the pinpoint datasets and of DAgger."""

from __future__ import annotations

import dataclasses

import numpy as np

from agents.common.law import FlightComputer, GuidanceLaw, Navigation
from agents.experts.family import plant_scenario
from agents.experts.pinpoint.engine_estimate import ThrustScaleEstimator
from lunar_env.envs.pinpoint_landing import action_from_angles
from optimizers.indirect.pinpoint_feedback import (
    PinpointFeedback,
)

__all__ = ["PinpointPontryaginExpert", "PinpointReserveExpert", "PINPOINT_LABEL_STATUSES"]

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
               active: np.ndarray | None = None) -> np.ndarray:
        """(α, β) (rad), (B, 2), of the extremals from states (B, 7) at episode times (B,)."""
        ang = self.feedback(states_nd, t_s, dt_s, active)
        act = np.ones(len(ang), dtype=bool) if active is None else np.asarray(active, bool)
        for st, a in zip(self.feedback.last_status, act, strict=True):
            if a:
                self.status_counts[st] = self.status_counts.get(st, 0) + 1
        return ang

    def labels(self, state_nd: np.ndarray, t_s: np.ndarray, active: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The expert's decision at normalised states (B, 7) and episode times (B,) (s).

        Returns ``(angles, actions, is_label)``: (α, β) (rad) and the env actions (float32),
        both (B, 2), and (B,) bool: the row is active (``active``; None: all) and its status is
        one of :data:`PINPOINT_LABEL_STATUSES`. Call :meth:`reset` first.
        """
        ang = self.angles(state_nd, t_s, self.computer.dt_s, active)
        sc = self.scenario
        actions = action_from_angles(ang[:, 0], ang[:, 1], sc.alpha_bounds_rad,
                                     sc.beta_bounds_rad).astype(np.float32)
        is_label = np.isin(np.asarray(self.last_status), PINPOINT_LABEL_STATUSES)
        if active is not None:
            is_label &= np.asarray(active, dtype=bool)
        return ang, actions, is_label

    def act(self, nav: Navigation) -> np.ndarray:
        return self.computer.at_full_thrust(self.labels(nav.state_nd, nav.t_s, nav.active)[1])

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
    guidance keeps by design (issue 31: a fuel-optimal constant-thrust plan brakes at full
    thrust, so an engine weaker than planned cannot stop in time).

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
        Estimate the engine's thrust-acceleration scale from the navigated velocity changes
        (:class:`agents.experts.pinpoint.engine_estimate.ThrustScaleEstimator`) and divide
        the commanded throttle by it, so that the engine gives the thrust the plan assumed
        (up to full throttle): the reserve then absorbs a weak engine instead of the plan
        drifting long until the switch.
    feedback_kwargs : forwarded to the three experts' :class:`PinpointFeedback`.

    Attributes
    ----------
    decisions : dict[str, int]
        Active decisions flown on the ``"reserve"`` (1 − R), ``"full"`` and ``"low"``
        (1 − 2R) engine since construction.
    """

    name = "Pontryagin feedback expert with a thrust reserve"

    def __init__(self, scenario, thrust_reserve: float, switch_m: float = 50.0,
                 stop_above_m: float = 0.0, estimate_thrust: bool = False,
                 **feedback_kwargs) -> None:
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
        self.decisions = {"reserve": 0, "full": 0, "low": 0}
        self.estimator = None
        if estimate_thrust:
            sc, k = self.full.scenario, self.full.feedback.k
            self.estimator = ThrustScaleEstimator(sc.params(sc.scaling()), k.time_s,
                                                  k.velocity_m_s)

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        """New flights; ``ValueError`` unless the env has a throttle channel."""
        n_act = int(computer.action_space.shape[-1])
        if n_act != 3:
            raise ValueError(f"a thrust reserve needs the throttle channel (throttle_channel="
                             f"True: 3 action channels); this env has {n_act}")
        super().reset(computer, case_ids)
        for expert in (self.planned, self.full, self.low):
            expert.reset(computer, case_ids)
        if self.estimator is not None:
            self.estimator.reset(len(case_ids))

    def act(self, nav: Navigation) -> np.ndarray:
        active = np.asarray(nav.active, dtype=bool)
        if self.estimator is not None:
            self.estimator.observe(nav.state_nd, nav.t_s, active)
        angles, actions, _ = self.planned.labels(nav.state_nd, nav.t_s, active)
        # states are normalised by length, mu and the initial mass: the derated engines'
        # plans read the same normalised states as the nominal one's
        beyond = self.planned.feedback.last_beyond_m
        short = active & (beyond < -self.switch_m)
        long = active & ~short & ~(beyond <= self.switch_m)  # NaN (no extremal): long
        off = short | long
        throttle = np.full(len(active), 1.0 - self.thrust_reserve)
        for rows, expert, level, key in ((long, self.full, 1.0, "full"),
                                         (short, self.low, 1.0 - 2.0 * self.thrust_reserve,
                                          "low")):
            if rows.any():
                ang, act, _ = expert.labels(nav.state_nd, nav.t_s, rows)
                angles[rows], actions[rows] = ang[rows], act[rows]
                throttle[rows] = level
            self.decisions[key] += int(rows.sum())
        self.decisions["reserve"] += int((active & ~off).sum())
        if self.estimator is not None:
            throttle = np.clip(throttle / self.estimator.scale, 0.0, 1.0)
            self.estimator.record(nav.state_nd, np.c_[angles, throttle], nav.t_s, active)
        return np.concatenate([actions, (2.0 * throttle - 1.0)[:, None]],
                              axis=1).astype(np.float32)
