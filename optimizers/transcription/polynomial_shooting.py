"""Direct single shooting of the planar minimum-time landing with a polynomial thrust angle.

A second *direct* method for the certification of the Pontryagin optimum
(:mod:`optimizers.indirect.planar`) of a :class:`~optimizers.problems.planar_ocp.PlanarOCP`, on
a different integration path: the compiled batched RK4 of
:func:`lunar_env.integrators.integrate` (the one the GAs evaluate their populations with).
The thrust angle is a Chebyshev series of degree ``degree`` on [0, tf],
φ(t) = Σ a_k T_k(2t/tf − 1); the unknowns (a_0..a_degree, tf) are found by SLSQP minimising tf
subject to the three terminal equalities r = r_f, v = v_f, r·ω = v_t,f. The constraint
Jacobian is by central differences, all perturbed trajectories integrated in one batched call.

``success`` is the problem's verdict on the terminal state (as for every solver); whether SLSQP
also met its own stopping test is ``extra["slsqp_converged"]``: an iteration limit reached on a
trajectory that lands is a feasible (upper-bound) answer, not a failure.

Being a restriction of the control space, its optimum is an upper bound of the true one
(up to the RK4 error): with degree 3 (the least-squares cubic of paper 000) it lies 1e-5 kg
above the indirect optimum of ``zhu2007``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from lunar_env.integrators import PLANAR, PiecewisePolynomial, integrate

from ..common.result import OptimResult
from ..problems.planar_ocp import PlanarOCP, as_planar_ocp

__all__ = ["PolynomialShootingSolution", "solve_planar_min_time_polynomial"]


@dataclass
class PolynomialShootingSolution(OptimResult):
    """:class:`~optimizers.common.result.OptimResult` of
    :func:`solve_planar_min_time_polynomial` (``x`` = (a_0..a_degree, tf_nd)).

    Attributes
    ----------
    chebyshev_coefs : ndarray, shape (degree + 1,)
        a_k of φ(t) = Σ a_k T_k(2t/tf − 1), radians.
    """

    chebyshev_coefs: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def thrust_angle_at(self, t_s) -> np.ndarray:
        """φ (rad) at times ``t_s`` (s), any shape (the same shape back)."""
        x = 2.0 * np.asarray(t_s, dtype=np.float64) / self.tf_s - 1.0
        return np.polynomial.chebyshev.chebval(x, self.chebyshev_coefs)


def _power_coefs(cheb: np.ndarray, tf_nd: float) -> np.ndarray:
    """Ascending power coefficients in t of Σ a_k T_k(2t/tf − 1)."""
    series = np.polynomial.Chebyshev(cheb, domain=[0.0, tf_nd])
    return series.convert(kind=np.polynomial.Polynomial).coef


def solve_planar_min_time_polynomial(
    problem: PlanarOCP,
    initial_state_si=None,
    *,
    degree: int = 3,
    n_steps: int = 1000,
    fd_step: float = 1e-7,
    max_iter: int = 100,
    ftol: float = 1e-13,
) -> PolynomialShootingSolution:
    """Minimum-time landing over polynomial thrust-angle laws (direct single shooting).

    Parameters
    ----------
    problem : PlanarOCP (or a PlanarScenario / scenario name)
    initial_state_si : array_like, shape (5,), optional
        SI row (r m, vr m/s, θ rad, v_t m/s, m kg); default the problem's initial state.
    degree : int
        Polynomial degree of φ(t) (≥ 1).
    n_steps : int
        RK4 steps of :func:`lunar_env.integrators.integrate` over [0, tf].
    fd_step : float
        Central-difference step of the constraint Jacobian (normalised unknowns).
    max_iter : int
        SLSQP iterations.
    ftol : float
        SLSQP's ``ftol`` (on tf, normalised).

    Returns
    -------
    PolynomialShootingSolution

    Raises
    ------
    ValueError, TypeError
        Bad state (see :class:`~optimizers.problems.planar_ocp.PlanarOCP`), degree < 1,
        n_steps < 1.
    """
    from scipy.optimize import minimize

    t_start = time.perf_counter()
    ocp = as_planar_ocp(problem, initial_state_si)
    x0 = ocp.x0_nd
    degree = int(degree)
    if degree < 1:
        raise ValueError(f"degree = {degree} must be >= 1")
    if int(n_steps) < 1:
        raise ValueError(f"n_steps = {n_steps!r} must be >= 1")
    params = ocp.params
    tgt = ocp.target_nd
    s = ocp.scaling
    n_c = degree + 1

    def residuals(zs: np.ndarray) -> np.ndarray:
        zs = np.atleast_2d(zs)
        b = len(zs)
        coefs = np.zeros((b, 2, n_c))
        for i, z in enumerate(zs):
            pc = _power_coefs(z[:n_c], z[-1])
            coefs[i, 0, :len(pc)] = pc
        coefs[:, 1, 0] = 1.0  # throttle
        tf = zs[:, -1]
        ctrl = PiecewisePolynomial.polynomial(coefs, np.zeros(b), tf)
        y = integrate(PLANAR, np.repeat(x0[None], b, axis=0), t0_nd=0.0, dt_nd=tf / n_steps,
                      n_steps=int(n_steps), control=ctrl, params=params).y_end
        return np.stack([y[:, 0] - tgt[0], y[:, 1] - tgt[1], y[:, 0] * y[:, 3] - tgt[2]], axis=1)

    cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def cons(z):
        key = z.tobytes()
        if key not in cache:
            e = np.eye(len(z)) * fd_step
            g = residuals(np.vstack([z, z + e, z - e]))
            cache.clear()
            cache[key] = (g[0], (g[1:len(z) + 1] - g[len(z) + 1:]).T / (2 * fd_step))
        return cache[key]

    z0 = np.zeros(n_c + 1)
    z0[0] = np.pi / 4  # φ rising from 0 to π/2 over the burn ([000] fig. 2)
    z0[1] = np.pi / 4
    z0[-1] = ocp.rocket_equation_tf_nd()
    e_tf = np.zeros(n_c + 1)
    e_tf[-1] = 1.0
    bounds = [(None, None)] * n_c + [(0.2 * z0[-1], 5.0 * z0[-1])]
    res = minimize(lambda z: z[-1], z0, jac=lambda z: e_tf, method="SLSQP", bounds=bounds,
                   constraints=[{"type": "eq", "fun": lambda z: cons(z)[0],
                                 "jac": lambda z: cons(z)[1]}],
                   options={"ftol": float(ftol), "maxiter": int(max_iter)})
    g = residuals(res.x)[0]
    tf_s = float(res.x[-1] * s.time_s)
    errors = ocp.terminal_errors(np.array([tgt[0] + g[0], tgt[1] + g[1], 0.0,
                                           (tgt[2] + g[2]) / (tgt[0] + g[0]), 1.0]))
    ok, why = ocp.success_from(errors)
    fuel = ocp.fuel_kg(res.x[-1])
    return PolynomialShootingSolution(
        x=res.x.copy(), fuel_kg=fuel, tf_s=tf_s, terminal_errors=errors,
        history=np.array([fuel]), n_fevals=int(res.nfev), n_iter=int(res.nit),
        wall_s=time.perf_counter() - t_start, success=ok,
        message=f"SLSQP: {res.message}; {why}", fun=fuel,
        extra={"slsqp_converged": bool(res.success)},
        algorithm=f"polynomial single shooting (degree {degree}, SLSQP)", problem=repr(ocp),
        chebyshev_coefs=res.x[:n_c].copy())
