"""An unconstrained meta-problem (pygmo's ``unconstrain``): a problem's constraints folded
into its objective by the penalty of its own constraint groups."""

from __future__ import annotations

import numpy as np

from ..common.penalties import penalised_fitness
from ..common.problem import Problem

__all__ = ["PenalisedProblem"]


class PenalisedProblem(Problem):
    """Unconstrained wrapper: objective = −(penalised fitness), no constraints.

    For algorithms without constraint handling (pygmo's ``sade``, ``cmaes``, ``pso``): the same
    penalty as the GAs use (:func:`optimizers.common.penalties.penalised_fitness`), with a
    *fixed* weight. The default is [000]'s final one (T = Tmax in eq. (11): σ2 = 10, and the
    problem's factor 5 on the velocity term makes σ1 = 50), i.e. the fitness ASAGA's result is
    judged by at the end of its run.
    :meth:`assess` is the wrapped problem's verdict.

    Parameters
    ----------
    problem : Problem
    weight : float or array_like
        Penalty weight (one for all groups, or one per group).
    """

    def __init__(self, problem: Problem, weight=10.0) -> None:
        super().__init__()
        self.problem = problem
        self.weight = weight

    def get_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.problem.get_bounds()

    def get_name(self) -> str:
        return f"Penalised[{self.problem.get_name()}]"

    def _batch_fitness(self, X: np.ndarray) -> np.ndarray:
        F = self.problem.batch_fitness(X)
        return -penalised_fitness(self.problem, F, self.weight)[:, None]

    def assess(self, x: np.ndarray, f: np.ndarray | None = None):
        return self.problem.assess(x)

    def decode(self, x: np.ndarray):
        return self.problem.decode(x)

    def _fingerprint_items(self) -> list:
        return super()._fingerprint_items() + [self.problem.fingerprint(), repr(self.weight)]
