"""Penalised fitness for the evolutionary algorithms (maximised), built from the problem's own
constraint groups (:meth:`optimizers.common.problem.Problem.penalty_groups`).

``f = −obj / objective_scale − Σ_g w_g · factor_g · term_g / scale_g`` where ``term_g`` is the
Euclidean norm of the group's equality residuals plus the sum of its positive inequality
values. The algorithm supplies only the weights ``w`` (a schedule over generations); what is
penalised, in which units and with which relative factors is the problem's definition.

For [000]'s landing problem this is eq. (11): the velocity group (factor 5: σ1 = 5σ2) and the
radius group (factor 1) in units of sqrt(μ/r0) and r0, the objective m(tf)/m0 up to a constant.
"""

from __future__ import annotations

import numpy as np

from ..common.problem import Problem

__all__ = ["penalised_fitness", "penalty_terms", "paper_penalty_weight",
           "paper_penalty_weights", "PenalisedProblem"]


def _plan(problem) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """The problem's penalty groups as column indices of a fitness row and a multiplier
    ``factor / scale``, built once per problem (the GAs call the penalty every generation)."""
    groups = problem.penalty_groups()
    key = (problem.get_nec(), groups)
    cached = getattr(problem, "_penalty_plan_cache", None)
    if cached is not None and cached[0] == key:
        return cached[1]
    nec = problem.get_nec()
    plan = [(np.array([1 + i for i in g.eq], dtype=np.intp),
             np.array([1 + nec + i for i in g.ineq], dtype=np.intp), g.factor / g.scale)
            for g in groups]
    try:
        problem._penalty_plan_cache = (key, plan)
    except AttributeError:  # a problem that refuses attributes just rebuilds the plan
        pass
    return plan


def penalty_terms(problem, F: np.ndarray) -> np.ndarray:
    """Scaled, factored constraint terms ``factor_g · term_g / scale_g``, shape (n, n_groups).

    Non-finite fitness rows give +inf terms (so such a point is never preferred).
    """
    F = np.atleast_2d(F)
    plan = _plan(problem)
    out = np.zeros((F.shape[0], len(plan)))
    for j, (eq, ineq, mult) in enumerate(plan):
        t = np.zeros(F.shape[0])
        if eq.size:
            t += np.sqrt(np.einsum("ij,ij->i", F[:, eq], F[:, eq]))
        if ineq.size:
            t += np.maximum(F[:, ineq], 0.0).sum(axis=1)
        out[:, j] = mult * t
    return np.where(np.isfinite(out), out, np.inf)


def penalised_fitness(problem, F: np.ndarray, weights) -> np.ndarray:
    """Penalised fitness (to be **maximised**) of fitness rows ``F`` (n, n_f).

    Parameters
    ----------
    problem : Problem
    F : ndarray, shape (n, n_f)
    weights : float or array_like, shape (n_groups,)
        Penalty weight(s) of this generation (one for all groups, or one per group).

    Returns
    -------
    ndarray, shape (n,); −inf for non-finite rows.
    """
    F = np.atleast_2d(F)
    terms = penalty_terms(problem, F)
    w = np.broadcast_to(np.asarray(weights, dtype=float), (terms.shape[1],))
    with np.errstate(invalid="ignore"):
        f = -F[:, 0] / problem.objective_scale - terms @ w if terms.shape[1] else \
            -F[:, 0] / problem.objective_scale
    return np.where(np.isfinite(f), f, -np.inf)


def paper_penalty_weight(generation: int, n_generations: int) -> float:
    """σ2 of [000] eq. (11): ``max(1, 10^(2T/Tmax − 1))``, from 1 (T ≤ Tmax/2) to 10."""
    return max(1.0, 10.0 ** (2.0 * generation / n_generations - 1.0))


def paper_penalty_weights(generation: int, n_generations: int) -> tuple[float, float]:
    """(σ1, σ2) of [000] eq. (11) with σ1 = 5σ2 (kept for callers of the 0.1 API)."""
    s = paper_penalty_weight(generation, n_generations)
    return 5.0 * s, s



class PenalisedProblem(Problem):
    """Unconstrained wrapper: objective = −(penalised fitness), no constraints.

    For algorithms without constraint handling (pygmo's ``sade``, ``cmaes``, ``pso``): the same
    penalty as the GAs use (:func:`penalised_fitness`), with a *fixed* weight. The default is
    [000]'s final one (T = Tmax in eq. (11): σ2 = 10, and the problem's factor 5 on the velocity
    term makes σ1 = 50), i.e. the fitness ASAGA's result is judged by at the end of its run.
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
