"""The optimiser baselines of the touchdown family (``LunarPinpointLanding-v3``): each case's
certified optimum replayed open loop, and the closed-loop expert that re-plans the certified
optimum from the navigation solution.

Both fly the law of :class:`optimizers.optimum.touchdown.TouchdownOptimum` averaged over each
env step (:meth:`~optimizers.optimum.touchdown.TouchdownOptimum.mean_controls`: the step's
mean thrust vector, so its propellant is the plan's and the throttle switches land inside the
step). After a plan's touchdown time the lander is where the plan touched down to within the
errors it flew with; it then thrusts straight up at the engine's minimum throttle (below the
Moon's gravity for every mass of this lander: 300 N against at least 486 N of weight at the
300 kg dry mass), so a lander that is still above the surface sinks onto it rather than
climbing away.
"""

from __future__ import annotations

import math
import time

import numpy as np

from guidance.law import FlightComputer, GuidanceLaw, Navigation
from guidance.laws.baselines import BaselineFamily
from guidance.laws.engine_estimate import PlanEstimateFollowsFlight, ThrustScaleEstimator

__all__ = ["TouchdownBaselines", "TouchdownOpenLoopLaw", "TouchdownReplanningLaw",
           "DEFAULT_REPLAN_S", "DEFAULT_MIN_TGO_S"]

#: re-planning period of the expert (s of mission time): a choice. A certified solve costs
#: about 1 s of one core; every 10 s is 56 solves over the 563 s nominal descent (≈0.1 s of
#: computation per 1-s decision), and the plan flown between re-plans drifts from the truth by
#: the navigation and engine errors of those 10 s only
DEFAULT_REPLAN_S = 10.0
#: no re-plan when the plan flown has less than this left to touchdown (s): a choice. Near
#: touchdown the max–min–max structure loses its arcs and the certified solve refuses (an arc
#: at its minimum duration); the last plan is then flown to its end
DEFAULT_MIN_TGO_S = 15.0


def _after_plan_controls(scenario) -> np.ndarray:
    """(α, β, throttle) flown after a plan's end: straight up at the minimum throttle."""
    return np.array([math.pi / 2.0, math.pi, float(scenario.throttle_min)])


def plan_step_controls(plan, t0_s: float, dt_s: float, scenario) -> np.ndarray:
    """(α, β, throttle) of an env step [t0, t0 + dt] (s of the plan's clock) flying ``plan``
    (a certified :class:`~optimizers.optimum.touchdown.TouchdownOptimum`): the plan's mean
    thrust vector over the step (:meth:`~optimizers.optimum.touchdown.TouchdownOptimum.
    mean_controls`); a step across the plan's touchdown time averages the plan up to it and
    the after-plan thrust (straight up at the minimum throttle) after it, so the engine does not
    go on braking past the plan's end; after it, the after-plan thrust alone."""
    after = _after_plan_controls(scenario)
    if t0_s >= plan.tf_s:
        return after
    if t0_s + dt_s <= plan.tf_s:
        return plan.mean_controls(t0_s, dt_s, scenario)
    w = (plan.tf_s - t0_s) / dt_s
    u = plan.mean_controls(t0_s, plan.tf_s - t0_s, scenario)
    vec = w * _thrust_vector(u) + (1.0 - w) * _thrust_vector(after)
    thr = float(np.linalg.norm(vec))
    from optimizers.optimum.touchdown import touchdown_ocp

    ang = touchdown_ocp(scenario).angles_of((vec / thr)[None])[0]
    return np.array([ang[0], ang[1], thr])


def _thrust_vector(u: np.ndarray) -> np.ndarray:
    """The thrust vector (fraction of full thrust) of controls (α, β, throttle), in the
    components :meth:`~optimizers.optimum.touchdown.TouchdownOptimum.mean_controls` averages
    (up, then the two horizontal axes)."""
    ca = math.cos(u[0])
    return u[2] * np.array([math.sin(u[0]), ca * math.cos(u[1]), ca * math.sin(u[1])])


def _failed_plan_controls() -> np.ndarray:
    """(α, β, throttle) of a case without a plan: the braking attitude at full thrust."""
    return np.array([0.0, math.pi, 1.0])


class TouchdownOpenLoopLaw(GuidanceLaw):
    """Replay of each case's certified optimum (one per case id), averaged over every env step,
    then straight up at the minimum throttle after its touchdown time (module docstring). A law
    of the clock alone: it reads nothing of the navigation solution. Cases whose solve failed
    fly the braking attitude at full thrust and are reported like any other case.

    Parameters
    ----------
    optima : list of TouchdownOptimum
        One per case (indexed by case id), solved for the flight computer's nominal scenario
        (whose frame the plan's angles are measured in).
    """

    name = "optimum, open loop"

    def __init__(self, optima: list) -> None:
        self.optima = list(optima)
        self._ids = np.zeros(0, dtype=int)

    def reset(self, computer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self._ids = np.asarray(case_ids)

    def act(self, nav: Navigation) -> np.ndarray:
        dt = self.computer.dt_s
        scenario = self.computer.scenario
        u = np.tile(_failed_plan_controls(), (len(self._ids), 1))
        for k, cid in enumerate(self._ids):
            opt = self.optima[cid]
            if not opt.success:
                continue
            u[k] = plan_step_controls(opt, float(nav.t_s[k]), dt, scenario)
        return self.computer.actions_from_controls(u)


class TouchdownReplanningLaw(PlanEstimateFollowsFlight, GuidanceLaw):
    """The certified optimum re-planned from the navigation solution: every ``every_s`` seconds
    each lander solves :func:`optimizers.optimum.touchdown.solve_touchdown_case` (collocation
    certified by Pontryagin shooting) from its navigated state with the nominal model, the
    engine's thrust scaled by what the IMU measures
    (:class:`~guidance.laws.engine_estimate.ThrustScaleEstimator`), warm-started from its
    previous plan; between re-plans it flies the plan (module docstring). A re-plan that is not
    certified leaves the previous plan in force (counted in :attr:`n_failed`).

    Parameters
    ----------
    scenario : TouchdownScenario
    every_s : float
        Re-planning period (s, > 0); default :data:`DEFAULT_REPLAN_S`.
    min_tgo_s : float
        No re-plan once the plan flown has less than this to touchdown (s, >= 0); default
        :data:`DEFAULT_MIN_TGO_S`.

    Attributes
    ----------
    replan_log : list of tuple
        Per solve: (wall s, process CPU s, certified).
    n_replans, n_failed : int
    """

    name = "certified optimum, re-planned"

    def __init__(self, scenario, every_s: float = DEFAULT_REPLAN_S,
                 min_tgo_s: float = DEFAULT_MIN_TGO_S) -> None:
        for key, v, lo in (("every", every_s, 0.0), ("min_tgo", min_tgo_s, 0.0)):
            ok = isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            if not ok or v < lo or (key == "every" and v <= 0.0):
                raise ValueError(f"{key} = {v!r} s is not allowed; it must be finite and "
                                 + ("> 0" if key == "every" else ">= 0"))
        self.scenario = scenario
        self.every_s = float(every_s)
        self.min_tgo_s = float(min_tgo_s)
        self._nominal = None
        self.replan_log: list[tuple[float, float, bool]] = []
        self.n_replans = 0
        self.n_failed = 0

    def nominal_plan(self):
        """The nominal start's certified optimum (solved once per law)."""
        if self._nominal is None:
            from optimizers.optimum.touchdown import solve_touchdown_case, touchdown_ocp

            self._nominal = solve_touchdown_case(self.scenario,
                                                 touchdown_ocp(self.scenario).x0_nd)
        return self._nominal

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        n = len(case_ids)
        self.plans: list = [None] * n
        self.plan_t_s = np.full(n, np.nan)
        self.estimator = (ThrustScaleEstimator(self.scenario.vehicle.thrust_n)
                          if "imu" in computer.sensors else None)
        if self.estimator is not None:
            self.estimator.reset(n)
        self._mass_ref_kg = float(self.scenario.scaling().mass_kg)

    def _solve(self, x_nd: np.ndarray, warm, scale: float):
        from optimizers.optimum.touchdown import solve_touchdown_case

        t0, c0 = time.perf_counter(), time.process_time()
        sol = solve_touchdown_case(self.scenario, x_nd, warm, thrust_scale=scale)
        self.replan_log.append((time.perf_counter() - t0, time.process_time() - c0,
                                bool(sol.success)))
        self.n_replans += 1
        if not sol.success:
            self.n_failed += 1
            return None
        return sol

    def _due(self, i: int, t_s: float) -> bool:
        plan = self.plans[i]
        if plan is None:
            return True
        elapsed = t_s - self.plan_t_s[i]
        return elapsed >= self.every_s - 1e-9 and plan.tf_s - elapsed > self.min_tgo_s

    def act(self, nav: Navigation) -> np.ndarray:
        """Actions (N, 3): each active lander's plan over this step, after a re-plan when one
        is due."""
        for i in np.flatnonzero(nav.episode_start):
            self.plans[i], self.plan_t_s[i] = None, np.nan
        scale = np.ones(nav.n)
        mass_kg = nav.state_nd[:, -1] * self._mass_ref_kg
        if self.estimator is not None and "imu" in nav.sensors:
            self.estimator.reset_rows(np.flatnonzero(nav.episode_start))
            self.estimator.observe(nav.sensors["imu"], mass_kg, nav.active)
            scale = self.estimator.scale
        dt = self.computer.dt_s
        u = np.tile(_after_plan_controls(self.scenario), (nav.n, 1))
        for i in np.flatnonzero(nav.active):
            t = float(nav.t_s[i])
            if self._due(i, t):
                old = self.plans[i]
                warm = old if old is not None else self.nominal_plan()
                new = self._solve(np.asarray(nav.state_nd[i], dtype=np.float64), warm,
                                  float(scale[i]))
                if new is not None:
                    self.plans[i], self.plan_t_s[i] = new, t
                elif old is None:  # no plan at all: fly the nominal start's
                    self.plans[i], self.plan_t_s[i] = self.nominal_plan(), t
            plan = self.plans[i]
            tau = t - self.plan_t_s[i]
            if not plan.success:
                u[i] = _failed_plan_controls()
            else:
                u[i] = plan_step_controls(plan, tau, dt, self.scenario)
        if self.estimator is not None and "imu" in nav.sensors:
            self.estimator.record(u[:, 2], mass_kg, nav.active)
        return self.computer.actions_from_controls(u)


class TouchdownBaselines(BaselineFamily):
    """The touchdown family's baselines."""

    #: the expert costs one certified solve (~1 s of one core) per re-plan, 56 re-plans per
    #: landing at its default period: 20 cases by default
    default_expert_cases = 20
    #: none in a quick run: one re-planned landing (~1 min of one core) outlasts its training
    quick_expert_cases = 0

    def expert_law(self, scenario) -> GuidanceLaw:
        return TouchdownReplanningLaw(scenario)

    def open_loop_law(self, optimum) -> GuidanceLaw:
        return TouchdownOpenLoopLaw(optimum.solutions)
