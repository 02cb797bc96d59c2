"""Pontryagin (indirect) solution of the [001] pinpoint landing: an independent optimum check.

Minimum time (= minimum fuel at constant thrust) on the shared Moon-fixed model with the thrust
angles bounded (α ∈ [α_min, α_max], β ∈ [β_min, β_max]); the |u|, |w| and fuel path
constraints of [001] are inactive at the optimum (measured: u ∈ [−77, 0] m/s, w ∈ [0, 37] m/s,
fuel 282 kg < 300 kg), so they are left out and checked afterwards.

Necessary conditions, H = λ·f(x, α, β) (λ0 = 1, Mayer cost tf):

- costate λ' = −∂H/∂x (CasADi derivative of the *shared* right-hand side
  :func:`lunar_env.dynamics.moon3d_rhs_casadi`);
- control: min over the box of p·ê(α, β), p = λ_v in the orbital frame. Because cos α > 0 on
  the box, β is optimised first (β* = direction of −(p_y, p_z), projected onto [β_min, β_max]
  on the circle centred on the box), then α (α* = direction of −(p_x, q), q = p_y cos β +
  p_z sin β, projected the same way): the exact box minimiser of a cosine in each angle;
- transversality: λ_m(tf) = 0 (mass free), H(tf) = −1 (free tf); λ_r(tf), λ_v(tf) free
  (position and velocity fixed).

Solved backwards from tf (the terminal state is known up to the mass, m(tf) = m0 − ṁ tf):
unknowns λ_r(tf), λ_v(tf), tf; residuals x(0) − x0 (position, velocity) and H(tf) + 1. The
guess comes from a primer-vector fit to a direct solution's thrust directions
(λ_v(t) ≈ c + d (tf − t), λ_r ≈ d, flat-gravity), then Levenberg–Marquardt (scipy) with
CasADi Jacobians through an RK4 integration with ``n_steps`` uniform steps.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.optimize import least_squares

from lunar_env import dynamics as dyn

from ..common.casadi_tools import casadi as _casadi
from ..common.casadi_tools import rk4_step
from ..common.result import OptimResult
from ..problems.pinpoint import PinpointOCP

__all__ = ["solve_pinpoint_min_time"]


def _wrap_clip(angle, lo: float, hi: float):
    """Project an angle onto [lo, hi] on the circle (nearest end), CasADi-friendly."""
    ca = _casadi()
    centre = 0.5 * (lo + hi)
    a = centre + ca.atan2(ca.sin(angle - centre), ca.cos(angle - centre))
    return ca.fmin(ca.fmax(a, lo), hi)


def _optimal_control(ocp: PinpointOCP, x, lam_v):
    n = ocp.params.plane_normal
    xr, yr, zr, xt, yt, zt, xn, yn, zn = dyn.orbital_frame(x[0], x[1], x[2], n[0], n[1], n[2])
    px = lam_v[0] * xr + lam_v[1] * yr + lam_v[2] * zr
    py = lam_v[0] * xt + lam_v[1] * yt + lam_v[2] * zt
    pz = lam_v[0] * xn + lam_v[1] * yn + lam_v[2] * zn
    ca = _casadi()
    beta = _wrap_clip(ca.atan2(-pz, -py), *ocp.beta_bounds_rad)
    q = py * ca.cos(beta) + pz * ca.sin(beta)
    alpha = _wrap_clip(ca.atan2(-px, -q), *ocp.alpha_bounds_rad)
    return ca.vertcat(alpha, beta)


def _functions(ocp: PinpointOCP, n_steps: int):
    ca = _casadi()
    x = ca.SX.sym("x", 7)
    lam = ca.SX.sym("lam", 7)
    u = ca.SX.sym("u", 2)
    f = ocp.rhs(x, u)
    H = ca.dot(lam, f)
    dlam = -ca.jacobian(H, x).T
    ustar = _optimal_control(ocp, x, lam[3:6])
    rhs = ca.Function("canon", [x, lam], [ca.substitute(f, u, ustar),
                                          ca.substitute(dlam, u, ustar)])
    ham = ca.Function("ham", [x, lam], [ca.substitute(H, u, ustar)])
    uf = ca.Function("ustar", [x, lam], [ustar])
    def F(yy):
        a, b = rhs(yy[:7], yy[7:])
        return ca.vertcat(a, b)

    step = rk4_step(F, 14, name="step")
    acc = step.mapaccum("acc", n_steps)
    z = ca.MX.sym("z", 7)  # λ_r(tf), λ_v(tf), tf
    tf = z[6]
    m_f = ocp.x0_nd[6] - ocp.mass_flow_nd * tf
    x_f = ca.vertcat(ocp.target_position_nd, ca.MX.zeros(3), m_f)
    lam_f = ca.vertcat(z[:6], 0.0)
    traj = acc(ca.vertcat(x_f, lam_f), ca.repmat(-tf / n_steps, 1, n_steps))
    y0 = traj[:, -1]
    res = ca.vertcat(y0[:6] - ocp.x0_nd[:6], ham(x_f, lam_f) + 1.0)
    G = ca.Function("G", [z], [res])
    J = ca.Function("J", [z], [ca.jacobian(res, z)])
    path = ca.Function("path", [z], [ca.horzcat(ca.vertcat(x_f, lam_f), traj)])
    return G, J, path, uf, ham


def _primer_guess(ocp: PinpointOCP, t_nd: np.ndarray, e_thrust: np.ndarray, tf_nd: float,
                  x_f: np.ndarray, g_f: np.ndarray, accel_f: float) -> np.ndarray:
    """λ_v(t) ≈ c + d (tf − t) ∝ −ê(t) on the interior arc; scale from H(tf) = −1."""
    s = tf_nd - t_nd
    A = np.zeros((3 * len(s), 6))
    # unknowns (c, d) up to scale: fix the scale with c = −ê(tf) (|c| = 1 direction)
    c = -e_thrust[-1]
    rhs = []
    rows = []
    for k in range(len(s)):
        # (c + d s) ∥ −ê  <=>  (I − ê êᵀ)(c + d s) = 0
        P = np.eye(3) - np.outer(e_thrust[k], e_thrust[k])
        rows.append(P * s[k])
        rhs.append(-P @ c)
    A = np.vstack(rows)
    d, *_ = np.linalg.lstsq(A, np.concatenate(rhs), rcond=None)
    # H(tf) = λ_v·(a ê + g) with V = 0 -> scale k with k c·(a ê_f + g_f) = −1
    k = -1.0 / float(c @ (accel_f * e_thrust[-1] + g_f))
    return np.concatenate([k * d, k * c, [tf_nd]])


def solve_pinpoint_min_time(ocp: PinpointOCP, direct_result, *, n_steps: int = 2000,
                            max_nfev: int = 200) -> OptimResult:
    """Indirect solution started from a direct one (e.g. the serial strategy's result).

    Returns
    -------
    OptimResult
        ``x`` = (λ_r(tf), λ_v(tf), tf_nd); ``fuel_kg``, ``tf_s``; ``terminal_errors`` the
        mismatch at the *initial* state of the backward integration (``position_m``,
        ``velocity_m_s``) and the Hamiltonian residual; ``success`` converged (Levenberg–
        Marquardt) and the mismatch within 1 m, 0.01 m/s, |H + 1| < 1e-6; ``n_fevals`` residual
        evaluations; ``extra``: ``max_abs_u_m_s``, ``max_abs_w_m_s``, ``min_alpha_deg``,
        ``min_beta_deg``, ``costate_tf``, ``n_steps`` (path constraints checked afterwards).
    """
    t0 = time.perf_counter()
    G, J, path, uf, ham = _functions(ocp, n_steps)
    s = ocp.scaling
    tr = direct_result.trajectory
    t_nd = tr.t_s / s.time_s
    a = tr.controls["alpha_rad"]
    b = tr.controls["beta_rad"]
    # thrust unit vectors in the Moon-fixed frame along the direct solution
    n = ocp.params.plane_normal
    X = np.stack([tr.states["x_m"], tr.states["y_m"], tr.states["z_m"]], 1) / s.length_m
    fr = dyn.orbital_frame(X[:, 0], X[:, 1], X[:, 2], n[0], n[1], n[2])
    xr, xt, xn = (np.stack(fr[i:i + 3], 1) for i in (0, 3, 6))
    e = (np.sin(a)[:, None] * xr + (np.cos(a) * np.cos(b))[:, None] * xt
         + (np.cos(a) * np.sin(b))[:, None] * xn)
    interior = (a > ocp.alpha_bounds_rad[0] + 1e-3) & (b > ocp.beta_bounds_rad[0] + 1e-3)
    tf_nd = direct_result.tf_s / s.time_s
    xf = ocp.target_position_nd
    g_f = -xf / np.linalg.norm(xf) ** 3
    m_f = ocp.x0_nd[6] - ocp.mass_flow_nd * tf_nd
    z0 = _primer_guess(ocp, t_nd[interior], e[interior], tf_nd, xf, g_f,
                       ocp.params.thrust_nd / m_f)
    sol = least_squares(lambda z: np.asarray(G(z)).ravel(), z0,
                        jac=lambda z: np.asarray(J(z)), method="lm", xtol=1e-15,
                        ftol=1e-15, gtol=1e-15, max_nfev=max_nfev)
    z = sol.x
    res = np.asarray(G(z)).ravel()
    Y = np.asarray(path(z))  # (14, n_steps + 1), from tf backwards
    states = Y[:7, ::-1].T
    d = dyn.moon3d_derived(states, ocp.params)
    U = np.array([np.asarray(uf(Y[:7, k], Y[7:, k])).ravel() for k in range(Y.shape[1])])
    tf = float(z[6])
    pos_err = np.linalg.norm(res[:3]) * s.length_m
    vel_err = np.linalg.norm(res[3:6]) * s.velocity_m_s
    ok = bool(pos_err < 1.0 and vel_err < 1e-2 and abs(res[6]) < 1e-6)
    fuel = ocp.fuel_kg(tf)
    return OptimResult(
        x=z.copy(), fuel_kg=fuel, tf_s=tf * s.time_s,
        terminal_errors={"initial_position_m": float(pos_err),
                         "initial_velocity_m_s": float(vel_err),
                         "hamiltonian_residual": float(res[6])},
        history=np.array([fuel]), n_fevals=int(sol.nfev), n_iter=int(sol.nfev),
        wall_s=time.perf_counter() - t0, success=ok,
        message=("converged" if ok else "did not converge") + f" ({sol.message})", fun=fuel,
        feasible=ok, algorithm="Pontryagin shooting backward from the target (LM)",
        problem=repr(ocp),
        extra={"max_abs_u_m_s": float(np.max(np.abs(d["u_nd"])) * s.velocity_m_s),
               "max_abs_w_m_s": float(np.max(np.abs(d["w_nd"])) * s.velocity_m_s),
               "min_alpha_deg": float(np.degrees(U[:, 0].min())),
               "min_beta_deg": float(np.degrees(U[:, 1].min())),
               "costate_tf": z[:6].tolist(), "n_steps": int(n_steps)})


def _selftest() -> None:  # pragma: no cover - manual
    from ..transcription.serial import solve_serial

    ocp = PinpointOCP(__import__("lunar_env").get_scenario("peng2012"))
    r = solve_serial(ocp)
    print(solve_pinpoint_min_time(ocp, r))


if __name__ == "__main__":  # pragma: no cover
    _selftest()
