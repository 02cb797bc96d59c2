"""Minimum-time Pontryagin feedback to touchdown (``LunarPinpointLanding-v3``), and the handover
of thrust-limited landers from an explicit law to it.

Why a second braking law on the touchdown task
----------------------------------------------
Where the engine is weak enough, the fuel optimum of a landing on the site is a single
full-thrust arc (measured: each of ZEM/ZEV's 18 failures among 1000 development cases under
``standard`` has a certified optimum that is one full-thrust arc of 575–623 s, six of them
after 1.0–1.3 s at the minimum throttle), so the minimum-fuel and the minimum-time landings
coincide and no thrust is left to spare: the
lander must fly close to the minimum-time steering, which lofts (climbs to 20–30 km before
the final dive). The explicit laws' linear- or quadratic-in-time profiles through Apollo's
gates are not that path, and with the engine already at full thrust they cannot make up
the difference. Such landers are recognised before they are lost: the minimum-time extremal
of the lander's *measured* engine with the stop point free along the track (the natural stop)
lies only a few kilometres short of the site, or beyond it (nominal engines: 20–35 km short).

:class:`MinimumTimeTouchdownLaw`
    At every decision the minimum-time extremal from the navigated state to rest
    ``stop_above_m`` above the site
    (:class:`~guidance.laws.pontryagin_pinpoint.PinpointPontryaginExpert`: compiled
    Pontryagin shooting, warm-started), planned for the
    engine the IMU measures times ``1 − reserve`` and flown at throttle ``1 − reserve``. An
    extremal that stops more than ``switch_m`` beyond the site (or none) hands the decision to
    the measured engine's full-thrust extremal at full throttle; one that stops more than
    ``switch_m`` short, to the extremal of ``1 − 2·reserve`` at that throttle (the logic of
    :class:`~guidance.laws.pontryagin_pinpoint.PinpointReserveExpert`, with the reserve
    relative to the measured engine rather than the nominal one: a reserve of the nominal
    thrust is more than a 5 % weak engine has). Within ``switch_tgo_s`` of the stop, or below
    ``stop_above_m``, Apollo's terminal descent
    (P66, :meth:`~guidance.laws.apollo.DescentPhases.terminal_thrust`) takes over to
    touchdown.

:class:`MinimumTimeHandover`
    An explicit law (``zem-zev:min_time_slack=M``) whose landers are handed to
    :class:`MinimumTimeTouchdownLaw` for the rest of their descent when, at the first decision
    their engine has been measured, the natural stop lies less than ``M`` metres short of the
    site. The other landers never see the difference.

Defaults, measured on development cases (seeds 10 000–10 999 under ``standard``, never a
campaign's): ``reserve`` = 0.01 (0.03 of the measured engine lengthens the lofted extremal
past the propellant: 2 of 15 thrust-limited landers landed against 12 of 15 at 0.01);
``stop_above_m`` = 20 m (above the explicit laws' 15 m low gate, a choice: the terminal
descent starts where theirs does); ``switch_tgo_s`` = 4 s (two 2-s decisions, a choice: the
extremal's stop is controllable only at second order in its last seconds); ``switch_m`` =
50 m (:class:`~guidance.laws.pontryagin_pinpoint.PinpointReserveExpert`'s);
``min_time_slack`` = 5000 m (ZEM/ZEV with it: 99.6 % of the development cases, against 98.2 %
without, 99.5 % at 3000 m).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from guidance.law import FlightComputer, GuidanceLaw, Navigation, ThrustCommand, actions_of
from guidance.laws.apollo import DescentPhases, _check_range
from guidance.laws.engine_estimate import ThrustScaleEstimator

__all__ = ["MinimumTimeTouchdownLaw", "MinimumTimeHandover", "DEFAULT_RESERVE",
           "DEFAULT_STOP_ABOVE_M", "DEFAULT_SWITCH_TGO_S", "DEFAULT_SWITCH_M",
           "DEFAULT_MIN_TIME_SLACK_M", "check_slack", "spec_slack", "with_handover",
           "min_time_from_spec"]

#: fraction of the measured engine kept in reserve (module docstring)
DEFAULT_RESERVE = 0.01
#: height above the site (m) at which the extremals stop (module docstring)
DEFAULT_STOP_ABOVE_M = 20.0
#: the extremal's time to go (s) below which terminal descent takes over (module docstring)
DEFAULT_SWITCH_TGO_S = 4.0
#: miss along the track (m) beyond which the engine level is switched (module docstring)
DEFAULT_SWITCH_M = 50.0
#: the natural stop's distance short of the site (m) below which a lander is handed over
DEFAULT_MIN_TIME_SLACK_M = 5000.0


def check_slack(slack_m) -> float:
    """The handover's ``min_time_slack`` (m) as a float in (0, 50000]; ``ValueError`` naming
    it otherwise."""
    v = _check_range("min_time_slack", slack_m, 0.0, 50000.0)
    if v == 0.0:
        raise ValueError(f"min_time_slack = {slack_m!r} is not allowed; it must be in "
                         "(0, 50000] m")
    return v


class MinimumTimeTouchdownLaw(GuidanceLaw):
    """The minimum-time Pontryagin feedback to touchdown on the site, with a thrust reserve
    relative to the measured engine, then Apollo's terminal descent (module docstring).

    Alone it is a specialist for landers without thrust to spare. With thrust to spare, the
    minimum-time extremal to the fixed site has no path constraint and can dive through the
    surface (measured: 100 % of 50 development cases in the nominal world, 64 % of 100 under
    ``standard``, 26 of the 36 failures with an engine at 0.999 of the nominal or more); a
    thrust-limited
    lander's extremal lofts instead. :class:`MinimumTimeHandover` flies it only there.

    Parameters
    ----------
    scenario : TouchdownScenario
        The nominal scenario (``LunarPinpointLanding-v3``'s).
    reserve : float
        Fraction of the measured engine kept in reserve, in (0, 0.1]; default
        :data:`DEFAULT_RESERVE`.
    stop_above_m : float
        Height above the site (m) at which the extremals stop, in [5, 200]; default
        :data:`DEFAULT_STOP_ABOVE_M`.
    switch_tgo_s : float
        The extremal's time to go (s) below which terminal descent takes over, in [0, 30];
        default :data:`DEFAULT_SWITCH_TGO_S`.
    switch_m : float
        Miss along the track (m) beyond which the engine level is switched, in [0, 5000];
        default :data:`DEFAULT_SWITCH_M`.

    Attributes
    ----------
    terminal : ndarray of bool, shape (N,)
        The landers in terminal descent.
    decisions : dict[str, int]
        Active decisions flown on the ``"reserve"``, ``"full"`` and ``"low"`` engines and in
        ``"terminal"`` descent, since :meth:`reset`.
    """

    name = "minimum-time feedback"

    def __init__(self, scenario, reserve: float = DEFAULT_RESERVE,
                 stop_above_m: float = DEFAULT_STOP_ABOVE_M,
                 switch_tgo_s: float = DEFAULT_SWITCH_TGO_S,
                 switch_m: float = DEFAULT_SWITCH_M) -> None:
        from guidance.families import guidance_family

        if not getattr(guidance_family(scenario), "lands_on_site", False):
            raise ValueError(f"the minimum-time touchdown law flies a landing on a site; "
                             f"scenario {scenario.name!r} does not end at touchdown on its "
                             "target (use LunarPinpointLanding-v3)")
        self.reserve = _check_range("reserve", reserve, 0.0, 0.1)
        self.stop_above_m = _check_range("stop_above_m", stop_above_m, 5.0, 200.0)
        self.switch_tgo_s = _check_range("switch_tgo_s", switch_tgo_s, 0.0, 30.0)
        self.switch_m = _check_range("switch_m", switch_m, 0.0, 5000.0)
        from guidance.laws.pontryagin_pinpoint import PinpointReserveExpert
        from optimizers.indirect.pinpoint_feedback import PinpointFeedback

        self.scenario = scenario
        # the natural stop is the site's (not the raised stop's)
        self._site = PinpointFeedback(scenario)
        # its three extremals (reserve, full, 1 − 2R engines, stopping above the site) and
        # the choice between them; the engine scale is this law's (planned on the measured
        # engine), so the expert keeps no estimate of its own
        self.expert = PinpointReserveExpert(scenario, self.reserve, switch_m=self.switch_m,
                                               stop_above_m=self.stop_above_m)
        self.descent = DescentPhases()

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self.expert.reset(computer, case_ids)
        n = len(case_ids)
        self.estimator = (ThrustScaleEstimator(computer.thrust_n)
                          if "imu" in computer.sensors else None)
        if self.estimator is not None:
            self.estimator.reset(n)
        self.terminal = np.zeros(n, dtype=bool)
        self._mass_ref_kg = float(computer.scenario.scaling().mass_kg)
        self.decisions = {"reserve": 0, "full": 0, "low": 0, "terminal": 0}

    def engine_scale(self, nav: Navigation) -> np.ndarray:
        """(N,) the engine's thrust-acceleration scale measured by the IMU (1 without one, or
        before the first measured decision), after this decision's reading."""
        if self.estimator is None or "imu" not in nav.sensors:
            return np.ones(nav.n)
        self.estimator.reset_rows(np.flatnonzero(nav.episode_start))
        self.estimator.observe(nav.sensors["imu"], nav.state_nd[:, -1] * self._mass_ref_kg,
                               nav.active)
        return np.asarray(self.estimator.scale, dtype=np.float64).copy()

    def act(self, nav: Navigation) -> np.ndarray:
        """Actions (N, 3): each active lander's extremal over this step, or terminal
        descent."""
        start = np.flatnonzero(nav.episode_start)
        self.expert.start_episodes(start)
        self.terminal[start] = False
        scale = self.engine_scale(nav)
        alive = np.asarray(nav.active, dtype=bool)
        braking = alive & ~self.terminal
        angles, _, throttle, tgo, _, long, short = self.expert.extremals(
            nav.state_nd, nav.t_s, braking, plan_scale=scale, full_scale=scale)
        f = nav.frame
        self.terminal |= braking & ((f.height_m <= self.stop_above_m)
                                    | (np.nan_to_num(tgo, nan=np.inf) <= self.switch_tgo_s))
        out = self.computer.actions_from_controls(np.c_[angles, throttle]).astype(np.float64)
        term = alive & self.terminal
        if term.any():
            a = self.descent.terminal_thrust(f)
            full = self.computer.thrust_n * scale / f.mass_kg
            thr = np.clip(np.linalg.norm(a, axis=1) / full, 0.0, 1.0)
            out[term] = actions_of(self.computer, ThrustCommand(a, thr))[term]
            throttle = np.where(term, thr, throttle)
        flying = braking & ~term
        self.decisions["reserve"] += int((flying & ~long & ~short).sum())
        self.decisions["full"] += int((flying & long).sum())
        self.decisions["low"] += int((flying & short).sum())
        self.decisions["terminal"] += int(term.sum())
        if self.estimator is not None:
            self.estimator.record(throttle, nav.state_nd[:, -1] * self._mass_ref_kg, alive)
        return out.astype(np.float32)

    def flown(self, nav: Navigation, actions: np.ndarray) -> None:
        """Another policy (or the law handing over to this one) flew ``actions`` at this
        decision: the engine estimate records the throttles they gave."""
        if self.estimator is not None:
            self.estimator.record_flown(self.computer, actions,
                                        nav.state_nd[:, -1] * self._mass_ref_kg, nav.active)

    def natural_stop_m(self, state_nd: np.ndarray, thrust_scale: float) -> float:
        """Where the full-thrust minimum-time extremal from ``state_nd`` (7,) stops at rest
        with the stop point free along the track, for an engine ``thrust_scale`` times the
        nominal: metres along the track beyond the site (< 0: short of it); +inf where no
        such extremal converges (a lander that cannot stop on the track)."""
        sol = self._site.natural_stop(state_nd, float(thrust_scale))
        return math.inf if sol is None else float(sol.beyond_m)


class MinimumTimeHandover(GuidanceLaw):
    """A law whose thrust-limited landers fly :class:`MinimumTimeTouchdownLaw` (module
    docstring): at the first decision a lander's engine has been measured (the first
    decision without an IMU), it is handed over for the rest of its descent if its natural
    stop (:meth:`MinimumTimeTouchdownLaw.natural_stop_m`, the measured engine, the navigated
    state) lies less than ``slack_m`` short of the site.

    Parameters
    ----------
    law : GuidanceLaw
        The law flown otherwise: an explicit law (``zem-zev:min_time_slack=M``), whose own
        engine estimate (its ``estimator``) measures the engine, or one without an estimate
        (a learned law: ``dagger:RUN:min_time_slack=M``), whose engine the minimum-time law's
        estimate measures.
    min_time : MinimumTimeTouchdownLaw
    slack_m : float
        In (0, 50000] m; default :data:`DEFAULT_MIN_TIME_SLACK_M`.

    Attributes
    ----------
    handed_over : ndarray of bool, shape (N,)
        The landers flying the minimum-time law.
    natural_stop_m : ndarray, shape (N,)
        Each lander's natural stop when it was classified (m beyond the site; NaN before).
    """

    def __init__(self, law: GuidanceLaw, min_time: MinimumTimeTouchdownLaw,
                 slack_m: float = DEFAULT_MIN_TIME_SLACK_M, name: str | None = None) -> None:
        self.law = law
        self.min_time = min_time
        self.slack_m = check_slack(slack_m)
        self.name = name or f"{law.name} + minimum time"

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self.law.reset(computer, case_ids)
        self.min_time.reset(computer, case_ids)
        n = len(case_ids)
        self.handed_over = np.zeros(n, dtype=bool)
        self.natural_stop_m = np.full(n, np.nan)

    def act(self, nav: Navigation) -> np.ndarray:
        start = nav.episode_start
        self.handed_over[start] = False
        self.natural_stop_m[start] = np.nan
        out = actions_of(self.computer, self.law.act(nav)).astype(np.float64)
        # the minimum-time law's engine estimate reads every lander at every decision, so a
        # lander handed over is flown on its measured engine from its first decision (the
        # reading is repeated for the landers it flies, with the same result)
        self.min_time.engine_scale(nav)
        # the law's own estimate classifies where it keeps one (the explicit laws' landers
        # are classified on the engine they fly), the minimum-time law's otherwise
        est = getattr(self.law, "estimator", None)
        if est is None:
            est = self.min_time.estimator
        measured = np.ones(nav.n, dtype=bool) if est is None else est.measured
        scale = np.ones(nav.n) if est is None else est.scale
        new = np.asarray(nav.active, dtype=bool) & np.isnan(self.natural_stop_m) & measured
        for i in np.flatnonzero(new):
            self.natural_stop_m[i] = self.min_time.natural_stop_m(nav.state_nd[i], scale[i])
            self.handed_over[i] = self.natural_stop_m[i] > -self.slack_m
        rows = np.asarray(nav.active, dtype=bool) & self.handed_over
        if rows.any():
            out[rows] = self.min_time.act(dataclasses.replace(nav, active=rows))[rows]
        self.flown(nav, out)
        return out.astype(np.float32)

    def flown(self, nav: Navigation, actions: np.ndarray) -> None:
        """Both laws' engine estimates record the throttles ``actions`` gave."""
        for law in (self.law, self.min_time):
            law.flown(nav, actions)


def spec_slack(spec) -> float | None:
    """A law spec's ``min_time_slack`` option (m), checked before anything is built or loaded
    (:func:`check_slack`); None where the spec has none. ``ValueError`` naming the law."""
    slack = spec.option("min_time_slack", float, None)
    if slack is None:
        return None
    try:
        return check_slack(slack)
    except ValueError as exc:
        raise ValueError(f"law {spec.text!r}: {exc}") from None


def with_handover(law: GuidanceLaw, slack_m: float | None, spec, context) -> GuidanceLaw:
    """``law`` itself (``slack_m`` None), or ``law`` inside :class:`MinimumTimeHandover` on
    the context's scenario, named ``law.name``: the one way a spec's ``min_time_slack``
    (:func:`spec_slack`) is flown, explicit and learned laws alike. ``ValueError`` naming the
    law ``spec`` where the scenario does not land on its site."""
    if slack_m is None:
        return law
    try:
        min_time = MinimumTimeTouchdownLaw(context.scenario)
    except ValueError as exc:
        raise ValueError(f"law {spec.text!r}: {exc}") from None
    return MinimumTimeHandover(law, min_time, slack_m, name=law.name)


def min_time_from_spec(spec, context) -> GuidanceLaw:
    """``min-time[:reserve=R,stop_above=H,switch_tgo=S,switch_m=M]``:
    :class:`MinimumTimeTouchdownLaw` (``LunarPinpointLanding-v3``)."""
    from guidance.registry import require_no_argument

    spec.require_known_options(("reserve", "stop_above", "switch_tgo", "switch_m"))
    require_no_argument(spec)
    try:
        law = MinimumTimeTouchdownLaw(
            context.scenario, reserve=spec.option("reserve", float, DEFAULT_RESERVE),
            stop_above_m=spec.option("stop_above", float, DEFAULT_STOP_ABOVE_M),
            switch_tgo_s=spec.option("switch_tgo", float, DEFAULT_SWITCH_TGO_S),
            switch_m=spec.option("switch_m", float, DEFAULT_SWITCH_M))
    except ValueError as exc:
        raise ValueError(f"law {spec.text!r}: {exc}") from None
    law.name = spec.text
    return law
