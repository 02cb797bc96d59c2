"""The planar state–costate system of Pontryagin's minimum principle (CasADi).

Minimum time at constant thrust on the shared planar model (see :mod:`optimizers.indirect.planar`
for the derivation): H = 1 + λᵀ f(x, φ), λ' = −∂H/∂x by automatic differentiation of
:func:`lunar_env.dynamics.planar_rhs_casadi`, and the optimal angle φ* = atan2(−λ_v, λ_ω / r).
The state–costate vector is z = (x, λ), shape (10,); λ starts at index :data:`N_STATE`.
"""

from __future__ import annotations

import numpy as np

from lunar_env import dynamics as dyn

from ..common.casadi_tools import casadi, rk4_step

__all__ = ["PlanarPMPSystem", "system_for", "optimal_thrust_angle", "hamiltonian", "N_STATE"]

N_STATE = 5  # z = (x, λ): the costate λ starts here


def _params_of(problem) -> dyn.PlanarParams:
    if isinstance(problem, dyn.PlanarParams):
        return problem
    params = problem.params
    return params() if callable(params) else params


class PlanarPMPSystem:
    """CasADi functions of the state–costate system for one set of vehicle parameters."""

    def __init__(self, thrust_nd: float, exhaust_velocity_nd: float) -> None:
        ca = casadi()
        self.params = dyn.PlanarParams(thrust_nd, exhaust_velocity_nd)
        x = ca.SX.sym("x", 5)
        lam = ca.SX.sym("lam", 5)
        u = ca.SX.sym("u", 2)
        f = dyn.planar_rhs_casadi(x, u, self.params)
        h_expr = 1.0 + ca.dot(lam, f)
        dh_dx = ca.gradient(h_expr, x)  # ∂H/∂x at fixed control (AD of the shared rhs)
        phi = ca.atan2(-lam[dyn.VR], lam[dyn.OMEGA] / x[dyn.R])
        u_star = ca.vertcat(phi, 1.0)
        z = ca.vertcat(x, lam)
        rhs = ca.vertcat(ca.substitute(f, u, u_star), -ca.substitute(dh_dx, u, u_star))
        self.rhs = ca.Function("pmp_rhs", [z], [rhs])
        self.ham = ca.Function("pmp_hamiltonian", [z], [ca.substitute(h_expr, u, u_star)])
        self.phi = ca.Function("pmp_phi", [z], [phi])
        self.step = rk4_step(self.rhs, 2 * N_STATE, name="pmp_rk4")
        self._shooting: dict[tuple[int, bool], object] = {}
        self._grid: dict[int, object] = {}
        self._evals: dict[int, object] = {}

    @staticmethod
    def initial(ca, p, x0):
        return ca.vertcat(x0, p[0], p[1], 0.0, p[2], p[3])

    def residual_of(self, ca, zf, tgt):
        return ca.vertcat(zf[dyn.R] - tgt[0], zf[dyn.VR] - tgt[1],
                          zf[dyn.R] * zf[dyn.OMEGA] - tgt[2], zf[N_STATE + dyn.M], self.ham(zf))

    def shooting(self, n_steps: int, with_jacobian: bool):
        """RK4 unrolled as SX (fast to evaluate).

        With the Jacobian: ``(p, x0, tgt) -> (res (5,), jac (5, 5))``; without:
        ``(p, x0, tgt) -> (res (5,), Z (10, n_steps + 1))`` (the grid).
        """
        key = (n_steps, with_jacobian)
        if key not in self._shooting:
            ca = casadi()
            p = ca.SX.sym("p", 5)
            x0 = ca.SX.sym("x0", 5)
            tgt = ca.SX.sym("tgt", 3)
            z = self.initial(ca, p, x0)
            zs = [z]
            h = p[4] / n_steps
            for _ in range(n_steps):
                z = self.step(z, h)
                zs.append(z)
            res = self.residual_of(ca, z, tgt)
            outs = [res, ca.jacobian(res, p)] if with_jacobian else [res, ca.horzcat(*zs)]
            self._shooting[key] = ca.Function(f"pmp_shoot_{n_steps}", [p, x0, tgt], outs)
        return self._shooting[key]

    def grid(self, n_steps: int):
        """``(p, x0) -> Z (10, n_steps + 1)``: the RK4 grid (MX map-accumulate; cheap to build)."""
        if n_steps not in self._grid:
            ca = casadi()
            acc = self.step.mapaccum("pmp_acc", n_steps)
            p = ca.MX.sym("p", 5)
            x0 = ca.MX.sym("x0", 5)
            z0 = self.initial(ca, p, x0)
            zs = acc(z0, ca.repmat(p[4] / n_steps, 1, n_steps))
            self._grid[n_steps] = ca.Function(f"pmp_grid_{n_steps}", [p, x0],
                                              [ca.horzcat(z0, zs)])
        return self._grid[n_steps]

    def evaluate(self, zgrid: np.ndarray):
        """rhs (10, n), H (n,), φ (n,) at the columns of ``zgrid``."""
        n = zgrid.shape[1]
        if n not in self._evals:
            ca = casadi()
            zz = ca.SX.sym("z", 10)
            fun = ca.Function("pmp_eval", [zz], [self.rhs(zz), self.ham(zz), self.phi(zz)])
            self._evals[n] = fun.map(n)
        rhs, ham, phi = self._evals[n](zgrid)
        return np.asarray(rhs), np.asarray(ham).ravel(), np.asarray(phi).ravel()


_SYSTEMS: dict[tuple[float, float], PlanarPMPSystem] = {}


def system_for(params: dyn.PlanarParams) -> PlanarPMPSystem:
    """The (process-wide cached) state–costate system of these vehicle parameters."""
    key = (float(params.thrust_nd), float(params.exhaust_velocity_nd))
    if key not in _SYSTEMS:
        _SYSTEMS[key] = PlanarPMPSystem(*key)
    return _SYSTEMS[key]


def optimal_thrust_angle(state_nd: np.ndarray, costate_nd: np.ndarray) -> np.ndarray:
    """φ* = atan2(−λ_v, λ_ω / r), the angle that minimises H (see the module docstring).

    Parameters
    ----------
    state_nd : ndarray, shape (..., 5)
    costate_nd : ndarray, shape (..., 5)

    Returns
    -------
    ndarray, shape (...,), radians in (−π, π].
    """
    s = np.asarray(state_nd, dtype=np.float64)
    lam = np.asarray(costate_nd, dtype=np.float64)
    return np.arctan2(-lam[..., dyn.VR], lam[..., dyn.OMEGA] / s[..., dyn.R])


def hamiltonian(problem, state_nd, costate_nd, phi_rad) -> np.ndarray:
    """H = 1 + λᵀ f(x, φ) with the throttle at 1 (normalised); shapes broadcast to (...,).

    ``problem``: a :class:`~optimizers.problems.planar_ocp.PlanarOCP`, a PlanarScenario or
    :class:`lunar_env.dynamics.PlanarParams`.
    """
    params = _params_of(problem)
    s = np.atleast_2d(np.asarray(state_nd, dtype=np.float64))
    lam = np.atleast_2d(np.asarray(costate_nd, dtype=np.float64))
    phi = np.atleast_1d(np.asarray(phi_rad, dtype=np.float64))
    s, lam, phi = np.broadcast_arrays(s, lam, phi[..., None])
    u = np.stack([phi[..., 0], np.ones(phi.shape[:-1])], axis=-1)
    f = dyn.planar_rhs(s, u, params)
    return 1.0 + np.sum(lam * f, axis=-1)
