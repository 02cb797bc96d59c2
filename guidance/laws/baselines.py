"""The optimiser baselines of each env family: the replay of each case's optimum (open loop)
and the closed-loop expert (the optimum re-solved from the navigation solution).

A :class:`BaselineFamily` per env family, registered in :data:`BASELINE_FAMILIES` by
``scenario.family``: ``planar`` (Pontryagin: the optimal thrust-angle history replayed,
:class:`~guidance.laws.pontryagin_planar.PlanarReplanningLaw`), ``pinpoint`` ([001]'s GPM
optimum replayed, :class:`~guidance.laws.pontryagin_pinpoint.PinpointPontryaginExpert`) and
``pinpoint_touchdown`` (the certified touchdown optimum replayed, and re-planned from the
navigation solution: :mod:`guidance.laws.touchdown_baselines`). The
``open-loop`` and ``feedback`` law specs (:mod:`guidance.laws.feedback`) and the evaluation
(:func:`guidance.evaluation.compare.baseline_laws`) fly them.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from guidance.law import GuidanceLaw, Navigation
from lunar_env.families import FamilyRegistry

__all__ = ["BaselineFamily", "BASELINE_FAMILIES", "PlanarBaselines", "PinpointBaselines",
           "PlanarOpenLoopLaw", "PinpointOpenLoopLaw"]


class BaselineFamily(ABC):
    """The optimiser baselines of an env family."""

    #: cases the family's closed-loop expert flies in an evaluation by default (None: all)
    default_expert_cases: int | None = None
    #: cases it flies in a quick run's evaluation (``train.py --quick``)
    quick_expert_cases: int = 2

    @abstractmethod
    def expert_law(self, scenario) -> GuidanceLaw:
        """The closed-loop expert: the optimum re-solved from the navigation solution."""

    @abstractmethod
    def open_loop_law(self, optimum) -> GuidanceLaw:
        """The replay of each case's optimal control history
        (:class:`optimizers.optimum.PerCaseOptimum`; case id = row)."""


class PlanarBaselines(BaselineFamily):
    """The planar family's baselines."""

    #: the re-planning expert costs a Pontryagin solve per decision (~5 ms): 20 cases by default
    default_expert_cases = 20

    def expert_law(self, scenario) -> GuidanceLaw:
        from guidance.laws.pontryagin_planar import PlanarReplanningLaw

        return PlanarReplanningLaw(scenario)

    def open_loop_law(self, optimum) -> GuidanceLaw:
        return PlanarOpenLoopLaw(optimum.solutions)


class PinpointBaselines(BaselineFamily):
    """The pinpoint family's baselines."""

    #: the feedback expert costs ~1 ms a decision and lands every case at the optimum's fuel:
    #: 200 cases are enough for its row
    default_expert_cases = 200

    def expert_law(self, scenario) -> GuidanceLaw:
        from guidance.laws.pontryagin_pinpoint import PinpointPontryaginExpert

        return PinpointPontryaginExpert(scenario)

    def open_loop_law(self, optimum) -> GuidanceLaw:
        return PinpointOpenLoopLaw(optimum.solutions)


#: the optimiser baselines of each env family, by ``scenario.family``
BASELINE_FAMILIES: FamilyRegistry[BaselineFamily] = FamilyRegistry(
    "baseline", entry_point_group="lunar_env.baseline_families")
BASELINE_FAMILIES.register("planar", PlanarBaselines)
BASELINE_FAMILIES.register("pinpoint", PinpointBaselines)
BASELINE_FAMILIES.register("pinpoint_touchdown",
                           "guidance.laws.touchdown_baselines:TouchdownBaselines")


class PlanarOpenLoopLaw(GuidanceLaw):
    """Replay of per-case optimal thrust-angle histories φ(t).

    The env holds each action for ``dt_s``; the replay samples φ at the middle of the step
    (a second-order accurate hold of a smooth control). After the optimal final time the last
    value is held. A law of the clock alone: it reads nothing of the navigation solution.

    Parameters
    ----------
    solutions : sequence of PontryaginSolution
        One per case (indexed by case id), with ``thrust_angle_at(t_s)``. Cases whose solve
        failed fly φ = 0 (a braking burn) and are reported like any other case.
    """

    name = "Pontryagin open loop"

    def __init__(self, solutions) -> None:
        self.solutions = list(solutions)
        self._ids = np.zeros(0, dtype=int)

    def reset(self, computer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self._ids = np.asarray(case_ids)

    def act(self, nav: Navigation) -> np.ndarray:
        t_mid = nav.t_s + 0.5 * self.computer.dt_s
        phi = np.zeros(len(self._ids))
        for k, cid in enumerate(self._ids):
            sol = self.solutions[cid]
            if sol.success:
                phi[k] = sol.thrust_angle_at(float(t_mid[k]))
        return self.computer.actions_from_controls(np.stack([phi, np.ones(len(phi))], axis=1))


class PinpointOpenLoopLaw(GuidanceLaw):
    """Replay of each case's optimal (α, β)(t), averaged over every env step (held after tf).
    A law of the clock alone: it reads nothing of the navigation solution.

    Cases whose solve failed fly the nominal braking attitude (α = 0, β = 180°) and are
    reported like any other case.

    Parameters
    ----------
    optima : list of PinpointOptimum
        One per case (indexed by case id; :class:`optimizers.transcription.batch.
        PinpointOptimum`).
    t_offset_s : array_like, optional
        Per-case episode time at which each plan starts (mid-flight plans; default 0).
    """

    name = "optimum, open loop"

    def __init__(self, optima: list, t_offset_s=None) -> None:
        self.optima = list(optima)
        self.t_offset_s = (np.zeros(len(self.optima)) if t_offset_s is None
                           else np.asarray(t_offset_s, dtype=np.float64).reshape(-1))
        self._ids = np.zeros(0, dtype=int)

    def reset(self, computer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self._ids = np.asarray(case_ids)

    def act(self, nav: Navigation) -> np.ndarray:
        dt = self.computer.dt_s
        ang = np.tile([0.0, np.pi], (len(self._ids), 1))
        for k, cid in enumerate(self._ids):
            opt = self.optima[cid]
            if opt.success:
                ang[k] = opt.mean_angles(float(nav.t_s[k]) - self.t_offset_s[cid], dt)
        return self.computer.actions_from_controls(np.c_[ang, np.ones(len(ang))])
