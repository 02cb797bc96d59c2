"""The optimiser baselines of the touchdown family (``LunarPinpointLanding-v3``): the replay of
each case's certified optimum (:mod:`optimizers.optimum.touchdown`) at the env's decisions.

Registered in :data:`guidance.laws.baselines.BASELINE_FAMILIES` as ``pinpoint_touchdown``. The
family has no closed-loop expert: its certified optimum costs ~0.6-1.2 s a solve from a
dispersed start with a neighbour's warm start (measured on [001]'s dispersion), and a
mid-flight state, whose throttle structure has lost arcs, needs the cold structure search
(~5 s), so re-solving at every decision of a ~560 s flight is no baseline an evaluation can fly.
"""

from __future__ import annotations

import math

import numpy as np

from guidance.law import GuidanceLaw, Navigation
from guidance.laws.baselines import BaselineFamily

__all__ = ["TouchdownBaselines", "TouchdownOpenLoopLaw", "step_controls", "NO_EXPERT"]

#: why the touchdown family has no closed-loop expert (the message of its refusal)
NO_EXPERT = ("LunarPinpointLanding-v3 has no closed-loop expert baseline: its certified "
             "optimum takes ~1 s a solve (and ~5 s from a mid-flight state), far too slow to "
             "re-solve at every decision; fly the open-loop optimum ('open-loop') or a guidance "
             "law (e.g. 'zem-zev'), and evaluate with --eval-expert-states 0 / --expert-states 0")


def step_controls(optimum, t0_s, dt_s: float, scenario, n_gauss: int = 4) -> np.ndarray:
    """(α, β, throttle) (K, 3) of a certified optimum averaged over the env steps [t0, t0 + dt]
    for every ``t0_s`` (K,): :meth:`optimizers.optimum.touchdown.TouchdownOptimum.mean_controls`
    for all steps in one evaluation of the law (each step split at the arcs' switches, each part
    by ``n_gauss``-point Gauss-Legendre quadrature, the mean thrust vector's direction and
    length), except that the law after the optimum's touchdown time is the minimum throttle
    straight up, not the last control held: the step that holds touchdown flies its part after
    touchdown that way. Why: the replay of 1 s holds is still above the ground at tf, and the
    last control held (full thrust, braking) over the rest of the step reverses the horizontal
    velocity; measured over 39 dispersed cases at 1 s decisions, the replay lands 18 %
    (touchdown up to 3.9 m/s, late by 2.4 s median) with the last control held, 77 % (up to
    2.4 m/s, late by 0.2 s) this way."""
    from optimizers.common.quadrature import legendre_gauss
    from optimizers.optimum.touchdown import touchdown_ocp

    t0 = np.atleast_1d(np.asarray(t0_s, dtype=np.float64))
    x, w = legendre_gauss(int(n_gauss))
    edges = np.concatenate([[0.0], np.cumsum(optimum.durations_s)])
    ts, ws, owner = [], [], []
    for k, a0 in enumerate(t0):
        a1 = a0 + dt_s
        cuts = np.concatenate([[a0], edges[(edges > a0) & (edges < a1)], [a1]])
        lo, hi = cuts[:-1, None], cuts[1:, None]
        ts.append((lo + (x + 1.0) * (hi - lo) / 2.0).ravel())
        ws.append((w * (hi - lo) / 2.0).ravel() / dt_s)
        owner.append(np.full(ts[-1].size, k))
    t_all, w_all, own = np.concatenate(ts), np.concatenate(ws), np.concatenate(owner)
    u = optimum.controls_at(t_all, scenario)
    u[t_all > optimum.tf_s] = (0.5 * math.pi, math.pi, float(scenario.throttle_min))
    ca = np.cos(u[:, 0])
    d = (w_all * u[:, 2])[:, None] * np.stack([np.sin(u[:, 0]), ca * np.cos(u[:, 1]),
                                               ca * np.sin(u[:, 1])], axis=1)
    vec = np.stack([np.bincount(own, d[:, j], minlength=len(t0)) for j in range(3)], axis=1)
    thr = np.linalg.norm(vec, axis=1)
    ang = touchdown_ocp(scenario).angles_of(vec / thr[:, None])
    return np.column_stack([ang, thr])


class TouchdownOpenLoopLaw(GuidanceLaw):
    """Replay of each case's certified optimum (α, β, throttle)(t), averaged over every env step
    (:func:`step_controls`); once the plan has ended (touchdown is due) the engine holds its
    minimum throttle straight up, the gentlest descent it has. A law of the clock alone: it
    reads nothing of the navigation solution.

    Cases without a certified optimum fly full thrust against the motion (α = 0, β = 180°) and
    are reported like any other case.

    Parameters
    ----------
    optima : list of TouchdownOptimum
        One per case (indexed by case id).
    """

    name = "optimum, open loop"

    def __init__(self, optima: list) -> None:
        self.optima = list(optima)
        self._ids = np.zeros(0, dtype=int)
        self._tables: dict[int, np.ndarray] = {}

    def reset(self, computer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self._ids = np.asarray(case_ids)
        dt = float(computer.dt_s)
        self._tables = {}
        for cid in self._ids:
            opt = self.optima[int(cid)]
            if opt.success:
                n = int(math.ceil(opt.tf_s / dt - 1e-9))
                self._tables[int(cid)] = step_controls(opt, dt * np.arange(n), dt,
                                                       computer.scenario)

    def act(self, nav: Navigation) -> np.ndarray:
        dt = float(self.computer.dt_s)
        sc = self.computer.scenario
        u = np.tile([0.0, math.pi, 1.0], (len(self._ids), 1))
        for k, cid in enumerate(self._ids):
            table = self._tables.get(int(cid))
            if table is None:
                continue
            t = float(nav.t_s[k])
            j = int(round(t / dt))
            if t >= self.optima[int(cid)].tf_s:
                u[k] = (0.5 * math.pi, math.pi, float(sc.throttle_min))
            elif abs(t - j * dt) < 1e-9 and j < len(table):
                u[k] = table[j]
            else:  # off the decision grid: this step alone
                u[k] = step_controls(self.optima[int(cid)], [t], dt, sc)[0]
        return self.computer.actions_from_controls(u)


class TouchdownBaselines(BaselineFamily):
    """The touchdown family's baselines: the open-loop optimum only (see the module
    docstring)."""

    #: no closed-loop expert (:data:`NO_EXPERT`)
    default_expert_cases = 0

    def expert_law(self, scenario) -> GuidanceLaw:
        """Refused (:data:`NO_EXPERT`).

        Raises
        ------
        ValueError
            Always.
        """
        raise ValueError(NO_EXPERT)

    def open_loop_law(self, optimum) -> GuidanceLaw:
        return TouchdownOpenLoopLaw(optimum.solutions)
