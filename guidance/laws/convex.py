"""Convex re-planning guidance: the SCvx landing solver flown as a closed-loop law.

:class:`ConvexReplanningLaw` re-solves the minimum-fuel landing
(:class:`optimizers.transcription.convex.SuccessiveConvexification`) every ``every_s`` seconds
of mission time from each lander's *navigated* state (``nav.state_nd``, the env's normalised
units) with the *nominal* model (the flight computer's scenario), warm-started from that
lander's previous plan shifted by the time flown (:meth:`~optimizers.transcription.convex.
ConvexGuess.shifted`), and between re-plans flies the planned thrust direction (and throttle,
on an env with a throttle channel) of the plan's current interval. This is the G-FOLD /
Reynolds et al. (2020) pattern: one SOCP problem built once, parameters updated per re-plan.

Problems: the env family's re-planning problem (:meth:`optimizers.optimum.OptimumFamily.
replan_ocp`): planar envs fly :class:`~optimizers.problems.planar_ocp.PlanarOCP` of the
scenario; pinpoint envs :func:`optimizers.transcription.batch.replan_ocp` (the env's problem: the
path above the 2 km gate sphere with its clearance, tf lower bound relaxed for short times to
go). The plan's controls are the dynamics model's, which the env's encoder
(:attr:`~guidance.law.FlightComputer.actions_from_controls`) turns into actions.

Decisions
---------
- The first plan of every lander is warm-started from the nominal start's solution (solved
  once per law and scenario, cold); its own first solve may take up to ``first_iter``
  iterations, every later re-plan at most ``iters`` (2–3 are typical when warm).
- A re-plan is adopted when SCvx converged, or when its last convex solve was optimal and its
  interval defects are below 1e-6 (normalised); otherwise the lander keeps flying its previous
  plan (the failure is counted in :attr:`ConvexReplanningLaw.n_failed`).
- The re-planning period is ``every_s`` but at most a third of the last plan's time to go, so
  the plan is refreshed at least three times over any remaining horizon (the touchdown speed
  is set by the last seconds: the engine cuts off at the speed minimum and the lander falls
  the height that is left); no re-plan closer than ``min_tgo_s`` to the planned touchdown.
- The action is held for the env's decision interval ``dt_s``: the law flies the plan's
  control at the middle of that interval.
- Where the flight computer has an IMU, every re-plan plans with the engine it measures
  (:class:`~guidance.laws.engine_estimate.ThrustScaleEstimator`, to the nearest
  :data:`SCALE_STEP`), not the nominal one.
- After the plan's end the last control is held (the env ends the burn at zero speed).
"""

from __future__ import annotations

import math
import time

import numpy as np

from guidance.law import FlightComputer, GuidanceLaw, Navigation
from guidance.laws.engine_estimate import PlanEstimateFollowsFlight, ThrustScaleEstimator
from guidance.registry import require_no_argument
from optimizers.optimum import optimum_family, plant_scenario

#: resolution of the engine's measured thrust scale the re-plans use (a new problem is built
#: per step: 0.5 % is a tenth of ``standard``'s 2 % thrust error)
SCALE_STEP = 0.005

__all__ = ["ConvexReplanningLaw", "convex_from_spec"]


class ConvexReplanningLaw(PlanEstimateFollowsFlight, GuidanceLaw):
    """SCvx re-planning from the navigated state (see the module docstring).

    Parameters
    ----------
    scenario : PlanarScenario or PinpointScenario
        The nominal scenario the flight computer plans with.
    every_s : float
        Re-planning period (s of mission time, > 0). Default 10 (the measured setting).
    n_nodes : int
        Nodes K of every plan (≥ 2). Default 30.
    iters : int
        SCvx iterations per re-plan (≥ 1). Default 2.
    first_iter : int
        SCvx iterations of each lander's first plan (≥ 1). Default 30.
    engine : {"constant", "throttled"}
        The papers' full-thrust engine, or the throttled one (needs the env's throttle channel).
    throttle_max : float
        Largest throttle the throttled engine plans with, in (0, 1] (default 1): below 1, a
        thrust margin that re-planning spends when the engine is weaker than the model.
    min_tgo_s : float
        No re-plan when the planned time to go is below this (s, ≥ 0). Default 3.

    Attributes
    ----------
    replan_s : list of float
        Wall time of every re-plan (s), the first plans included.
    replan_log : list of tuple
        Per re-plan: (wall s, process CPU time s — the one-core cost on a shared machine —,
        the convex solver's own time s, cvxpy ``solve`` calls s, SCvx iterations, whether it
        was a lander's first plan).
    n_replans, n_failed : int

    Raises
    ------
    ValueError
        A setting out of range (named), or ``engine="throttled"`` on an env without a throttle
        channel (at :meth:`reset`).
    """

    name = "convex re-planning"

    def __init__(self, scenario, *, every_s: float = 10.0, n_nodes: int = 30, iters: int = 2,
                 first_iter: int = 30, engine: str = "constant", throttle_max: float = 1.0,
                 min_tgo_s: float = 3.0) -> None:
        from optimizers.transcription.convex import SuccessiveConvexification

        try:
            family = optimum_family(scenario)
        except (KeyError, TypeError) as exc:
            raise ValueError(f"convex re-planning needs a landing scenario with a re-planning "
                             f"problem: {exc}") from None
        if not (isinstance(every_s, int | float) and math.isfinite(every_s) and every_s > 0):
            raise ValueError(f"every = {every_s!r} s is not allowed; it must be finite and > 0")
        if not (isinstance(min_tgo_s, int | float) and math.isfinite(min_tgo_s)
                and min_tgo_s >= 0):
            raise ValueError(f"min_tgo = {min_tgo_s!r} s is not allowed; it must be >= 0")
        for key, v in (("iters", iters), ("first_iter", first_iter)):
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{key} = {v!r} is not allowed; it must be an integer >= 1")
        self.scenario = scenario
        self.every_s = float(every_s)
        self.iters = int(iters)
        self.first_iter = int(first_iter)
        self.min_tgo_s = float(min_tgo_s)
        self.engine = engine
        self.solver = SuccessiveConvexification(n_nodes, engine=engine, max_iter=first_iter,
                                                throttle_max=throttle_max)
        self._family = family
        self.ocp = family.replan_ocp(scenario)
        from optimizers.problems.pinpoint import PinpointOCP
        from optimizers.problems.planar_ocp import PlanarOCP

        if not isinstance(self.ocp, PlanarOCP | PinpointOCP):
            raise ValueError(f"convex re-planning has no convex transcription of "
                             f"{type(self.ocp).__name__} (scenario {scenario.name!r}); the SCvx "
                             "model covers the planar landing and the pinpoint landing to its "
                             "gate (PlanarOCP, PinpointOCP)")
        self._ocps = {1.0: self.ocp}
        self._nominal = None
        self.replan_s: list[float] = []
        self.replan_log: list[tuple[float, float, float, float, int, bool]] = []
        self.n_replans = 0
        self.n_failed = 0

    # ---- planning ----------------------------------------------------------------------------
    def nominal_plan(self):
        """The nominal start's solution (cold SCvx solve, once per law)."""
        if self._nominal is None:
            self._nominal = self.solver.solve(self.ocp)
        return self._nominal

    def _plan(self, x_nd: np.ndarray, guess, max_iter: int, first: bool, ocp=None):
        t0, c0 = time.perf_counter(), time.process_time()
        sol = self.solver.solve(self.ocp if ocp is None else ocp, guess, initial_state=x_nd,
                                max_iter=max_iter)
        cpu = time.process_time() - c0
        self.replan_s.append(time.perf_counter() - t0)
        self.replan_log.append((self.replan_s[-1], cpu, float(sol.extra["solver_s"]),
                                float(sol.extra["solve_s"]), int(sol.n_iter),
                                bool(first)))
        self.n_replans += 1
        ok = sol.extra["converged"] or (
            sol.extra["statuses"] and sol.extra["statuses"][-1] == "optimal"
            and sol.extra["max_defect_nd"] < 1e-6)
        if not ok:
            self.n_failed += 1
            return None
        return sol

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        if self.engine == "throttled" and not computer.throttled:
            raise ValueError(f"engine='throttled' needs the env's throttle channel; "
                             f"{computer.env_id} has none (make it with "
                             "throttle_channel=True, or use engine='constant')")
        n = len(case_ids)
        self.plans: list = [None] * n
        self.plan_t_s = np.full(n, np.nan)
        self.estimator = (ThrustScaleEstimator(self.scenario.vehicle.thrust_n)
                          if "imu" in computer.sensors else None)
        if self.estimator is not None:
            self.estimator.reset(n)
            self._mass_ref_kg = float(self.scenario.scaling().mass_kg)

    def ocp_for(self, thrust_scale: float):
        """The re-planning problem of an engine ``thrust_scale`` times the nominal one (to the
        nearest :data:`SCALE_STEP`, so a flight builds a few problems, not one per re-plan)."""
        q = round(float(thrust_scale) / SCALE_STEP) * SCALE_STEP
        if q not in self._ocps:
            self._ocps[q] = self._family.replan_ocp(plant_scenario(self.scenario, q, 1.0))
        return self._ocps[q]

    def _replan_due(self, i: int, t_s: float) -> bool:
        plan = self.plans[i]
        if plan is None:
            return True
        elapsed = t_s - self.plan_t_s[i]
        tgo = plan.tf_s - elapsed
        period = min(self.every_s, plan.tf_s / 3.0)
        return elapsed >= period - 1e-9 and tgo > self.min_tgo_s

    def act(self, nav: Navigation) -> np.ndarray:
        """Actions (N, n_act) float32: each active lander's planned control now, after a
        re-plan when one is due."""
        time_s = self.ocp.scaling.time_s
        for i in np.flatnonzero(nav.episode_start):  # a new episode: no plan to warm-start
            self.plans[i], self.plan_t_s[i] = None, np.nan
        scale = np.ones(nav.n)
        if self.estimator is not None and "imu" in nav.sensors:
            self.estimator.reset_rows(np.flatnonzero(nav.episode_start))
            mass_kg = nav.state_nd[:, -1] * self._mass_ref_kg
            self.estimator.observe(nav.sensors["imu"], mass_kg, nav.active)
            scale = self.estimator.scale
        controls = None
        for i in np.flatnonzero(nav.active):
            t = float(nav.t_s[i])
            if self._replan_due(i, t):
                old = self.plans[i]
                if old is None:
                    guess, iters = self.nominal_plan().guess(), self.first_iter
                else:
                    elapsed = (t - self.plan_t_s[i]) / time_s
                    guess = old.guess().shifted(min(elapsed, 0.999 * old.tf_nd))
                    iters = self.iters
                new = self._plan(np.asarray(nav.state_nd[i], dtype=np.float64), guess, iters,
                                 old is None, self.ocp_for(scale[i]))
                if new is not None:
                    self.plans[i], self.plan_t_s[i] = new, t
                elif old is None:  # no plan at all: fly the nominal one
                    self.plans[i], self.plan_t_s[i] = self.nominal_plan(), t
            plan = self.plans[i]
            # the action is held for one decision interval: fly the plan at its middle
            tau = (t + 0.5 * self.computer.dt_s - self.plan_t_s[i]) / time_s
            k = int(np.clip(np.searchsorted(plan.t_nd, tau, side="right") - 1, 0,
                            len(plan.model_controls) - 1))
            if controls is None:
                controls = np.zeros((nav.n, len(plan.model_controls[k])))
            controls[i] = plan.model_controls[k]
        if controls is None:  # nobody flying: any valid action
            return np.zeros((nav.n, *self.computer.action_space.shape), dtype=np.float32)
        if self.estimator is not None and "imu" in nav.sensors:
            throttle = controls[:, -1] if self.computer.throttled else np.ones(nav.n)
            self.estimator.record(throttle, mass_kg, nav.active)
        return self.computer.actions_from_controls(controls)


def convex_from_spec(spec, context) -> GuidanceLaw:
    """``convex[:every=S,nodes=K,iters=I,first_iter=J,engine=constant|throttled,tmax=G,
    min_tgo=S]``: :class:`ConvexReplanningLaw` on the context's nominal scenario (defaults 10 s,
    30 nodes, 2 iterations per re-plan, 30 for the first plan, constant engine, throttle_max 1,
    3 s)."""
    spec.require_known_options(("every", "nodes", "iters", "first_iter", "engine", "tmax",
                                "min_tgo"))
    require_no_argument(spec)
    law = ConvexReplanningLaw(
        context.scenario,
        every_s=spec.option("every", float, 10.0),
        n_nodes=spec.option("nodes", int, 30),
        iters=spec.option("iters", int, 2),
        first_iter=spec.option("first_iter", int, 30),
        engine=spec.option("engine", str, "constant"),
        throttle_max=spec.option("tmax", float, 1.0),
        min_tgo_s=spec.option("min_tgo", float, 3.0))
    law.name = spec.label() if spec.options else "convex"
    return law
