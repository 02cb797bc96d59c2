"""Penalised fitness built from a problem's own constraint groups
(:meth:`optimizers.common.problem.Problem.penalty_groups`), maximised.

``f = −obj / objective_scale − Σ_g w_g · factor_g · term_g / scale_g`` where ``term_g`` is the
Euclidean norm of the group's equality residuals plus the sum of its positive inequality
values. The caller supplies only the weights ``w`` (an evolutionary algorithm's schedule over
generations, or the fixed weight of :class:`optimizers.problems.penalised.PenalisedProblem`);
what is penalised, in which units and with which relative factors is the problem's definition.

For [000]'s landing problem this is eq. (11): the velocity group (factor 5: σ1 = 5σ2) and the
radius group (factor 1) in units of sqrt(μ/r0) and r0, the objective m(tf)/m0 up to a constant.
"""

from __future__ import annotations

import numpy as np

__all__ = ["penalised_fitness", "penalty_terms"]


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
