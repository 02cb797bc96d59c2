"""Damped inexact Newton for shooting problems (residual fine, Jacobian coarse)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["damped_newton"]


def damped_newton(res_fine, res_jac_coarse, p, *, tol: float, max_iter: int, history: list,
                  iterates: list | None = None) -> tuple[np.ndarray, float, bool, int]:
    """Damped inexact Newton: residual on the fine grid, Jacobian from the coarse grid.

    Backtracking on the 2-norm of the fine residual; the last unknown (a final time) is kept
    positive. ``history`` receives the residual ∞-norm of every accepted iterate, ``iterates``
    (optional) the iterates themselves.

    Returns
    -------
    (p, ‖res‖∞, converged, iterations)
    """
    res = res_fine(p)
    nrm = float(np.max(np.abs(res))) if np.all(np.isfinite(res)) else math.inf
    history.append(nrm)
    if iterates is not None:
        iterates.append(np.array(p, copy=True))
    it = 0
    while it < max_iter:
        if nrm <= tol:
            return p, nrm, True, it
        if not math.isfinite(nrm):
            return p, nrm, False, it
        it += 1
        jac = res_jac_coarse(p)
        try:
            dp = np.linalg.solve(jac, -res)
        except np.linalg.LinAlgError:
            return p, nrm, False, it
        if not np.all(np.isfinite(dp)):
            return p, nrm, False, it
        alpha = 1.0
        if p[-1] + dp[-1] < 0.5 * p[-1]:  # do not let tf collapse in one step
            alpha = 0.5 * p[-1] / abs(dp[-1])
        merit = float(np.linalg.norm(res))
        accepted = False
        while alpha > 1e-4:
            p_try = p + alpha * dp
            r_try = res_fine(p_try)
            if np.all(np.isfinite(r_try)) and np.linalg.norm(r_try) < (1 - 1e-4 * alpha) * merit:
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            # At the round-off floor a full step cannot decrease the residual any further.
            return p, nrm, nrm <= 100 * tol, it
        p, res = p_try, r_try
        nrm = float(np.max(np.abs(res)))
        history.append(nrm)
        if iterates is not None:
            iterates.append(np.array(p, copy=True))
    return p, nrm, nrm <= tol, it
