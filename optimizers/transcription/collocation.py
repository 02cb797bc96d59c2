"""Direct Hermite–Simpson collocation of the planar minimum-time (= minimum-fuel) landing.

A *direct* transcription of the same optimal-control problem
(:class:`optimizers.problems.planar_ocp.PlanarOCP`) the Pontryagin solver
(:mod:`optimizers.indirect.planar`) solves indirectly, with CasADi and IPOPT. It has two jobs:

1. **Robust start** for the indirect shooting: a coarse grid (≈ 20 intervals) converges from a
   crude straight-line guess, and the multipliers of its defect constraints estimate the
   costates (see :attr:`CollocationSolution.costates_nd`).
2. **Independent check** of the indirect optimum: a dense grid (≥ 100 intervals) gives the
   optimum by a different method (no costates, no shooting), used in ``tests/test_pontryagin.py``.

Problem: :class:`~optimizers.problems.planar_ocp.PlanarOCP` (normalised units, μ = 1): minimise
tf subject to its right-hand side (the shared planar model, throttle fixed at 1: minimum fuel is
minimum time), x(0) given and its terminal residual (r, v, r·ω at tf; θ(tf), m(tf) free).

Transcription: separated Hermite–Simpson on N equal intervals of the scaled time τ = t/tf ∈
[0, 1]; states and the thrust angle at the nodes and interval midpoints; tf is a decision
variable. Defects (h = tf/N)::

    x_{k+½} = (x_k + x_{k+1})/2 + h/8 (f_k − f_{k+1})
    x_{k+1} = x_k + h/6 (f_k + 4 f_{k+½} + f_{k+1})

Costate estimate. CasADi reports IPOPT's multipliers ν with the Lagrangian
L = tf + Σ ν_kᵀ g_k. For the Simpson defect g_k = x_{k+1} − x_k − h/6(...), stationarity in x_k
gives ν_k − ν_{k−1} ≈ −h ν ∂f/∂x, the costate equation λ' = −∂H/∂x; stationarity in tf gives
1 − mean_k(ν_k·f_k) ≈ 0. With the Pontryagin normalisation H = 1 + λᵀf = 0 of
:mod:`optimizers.indirect.planar` (λ0 = 1), the costate is therefore λ(t_{k+½}) ≈ −ν_k, which
is what :attr:`CollocationSolution.costates_nd` holds (checked in the tests: the thrust angle that
minimises H with these costates matches the collocated angle).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from lunar_env import dynamics as dyn
from lunar_env.validation import require_finite_positive

from ..common.casadi_tools import casadi, nlp_counts
from ..common.result import OptimResult
from ..problems.planar_ocp import PlanarOCP, as_planar_ocp

__all__ = ["CollocationSolution", "solve_planar_min_time_collocation"]


@dataclass
class CollocationSolution(OptimResult):
    """:class:`~optimizers.common.result.OptimResult` of
    :func:`solve_planar_min_time_collocation`, with the transcription's arrays (normalised).

    ``x`` is the NLP's decision vector; ``history`` the fuel (kg) at each IPOPT iteration;
    ``terminal_errors`` those of the collocated final state; ``success`` IPOPT's convergence
    and the problem's verdict.

    Attributes
    ----------
    tf_nd : float
    t_nd : ndarray, shape (N + 1,)
        Node times.
    states_nd : ndarray, shape (N + 1, 5)
        Node states (r, v, θ, ω, m).
    phi_rad : ndarray, shape (N + 1,)
        Thrust angle at the nodes, wrapped to [−π, π).
    costates_nd : ndarray, shape (N, 5)
        Costate estimates λ(t_{k+½}) ≈ −ν_k from the Simpson defect multipliers (see the
        module docstring), normalised with λ0 = 1.
    t_mid_nd : ndarray, shape (N,)
        Interval midpoints (where ``costates_nd`` apply).
    """

    tf_nd: float = float("nan")
    t_nd: np.ndarray = field(default_factory=lambda: np.zeros(0))
    states_nd: np.ndarray = field(default_factory=lambda: np.zeros((0, 5)))
    phi_rad: np.ndarray = field(default_factory=lambda: np.zeros(0))
    costates_nd: np.ndarray = field(default_factory=lambda: np.zeros((0, 5)))
    t_mid_nd: np.ndarray = field(default_factory=lambda: np.zeros(0))


def solve_planar_min_time_collocation(
    problem: PlanarOCP,
    initial_state_si=None,
    *,
    n_intervals: int = 20,
    tol: float = 1e-10,
    print_level: int = 0,
    max_iter: int = 500,
    min_radius_m: float | None = None,
) -> CollocationSolution:
    """Minimum-time planar landing by separated Hermite–Simpson collocation (CasADi + IPOPT).

    Parameters
    ----------
    problem : PlanarOCP (or a PlanarScenario / scenario name, made into one)
        E.g. ``PlanarOCP("zhu2007")``. The throttle is fixed at 1 (constant thrust).
    initial_state_si : array_like, shape (5,), optional
        (r m, vr m/s, θ rad, v_t m/s, m kg); default the problem's initial state.
    n_intervals : int
        Number N of equal collocation intervals (≥ 2).
    tol : float
        IPOPT ``tol``.
    print_level : int
        IPOPT verbosity (0 silent).
    max_iter : int
        IPOPT iteration limit.
    min_radius_m : float, optional
        Path constraint r ≥ min_radius_m at every node and midpoint (e.g. the surface radius,
        for states whose unconstrained optimum would pass below the ground). Default: none
        (the problem the indirect solver solves).

    Returns
    -------
    CollocationSolution
        ``success`` False (not an exception) when IPOPT does not converge.

    Raises
    ------
    ValueError, TypeError
        On invalid input (see :class:`~optimizers.problems.planar_ocp.PlanarOCP`) or
        ``n_intervals < 2``.
    """
    ca = casadi()
    t_start = time.perf_counter()
    ocp = as_planar_ocp(problem, initial_state_si)
    x0 = ocp.x0_nd
    n = int(n_intervals)
    if n < 2:
        raise ValueError(f"n_intervals = {n_intervals!r} must be >= 2")
    if not (np.isfinite(tol) and tol > 0):
        raise ValueError(f"tol = {tol!r} must be finite and > 0")
    params = ocp.params
    s = ocp.scaling
    tgt = ocp.target_nd

    xs = ca.SX.sym("x", 5)
    us = ca.SX.sym("phi")
    f_fun = ca.Function("f", [xs, us], [ocp.rhs(xs, ca.vertcat(us))])

    opti_x = ca.MX.sym("X", 5, n + 1)
    opti_xm = ca.MX.sym("Xm", 5, n)
    opti_u = ca.MX.sym("U", 1, n + 1)
    opti_um = ca.MX.sym("Um", 1, n)
    tf = ca.MX.sym("tf")
    h = tf / n
    fmap = f_fun.map(n + 1)
    fmid = f_fun.map(n)
    fk = fmap(opti_x, opti_u)
    fm = fmid(opti_xm, opti_um)
    xa, xb = opti_x[:, :-1], opti_x[:, 1:]
    fa, fb = fk[:, :-1], fk[:, 1:]
    g_mid = opti_xm - (0.5 * (xa + xb) + h / 8.0 * (fa - fb))
    g_simpson = xb - xa - h / 6.0 * (fa + 4.0 * fm + fb)
    xf = opti_x[:, -1]
    g_term = ocp.terminal_residual(xf)
    w = ca.vertcat(ca.vec(opti_x), ca.vec(opti_xm), ca.vec(opti_u), ca.vec(opti_um), tf)
    g = ca.vertcat(ca.vec(g_simpson), ca.vec(g_mid), g_term)

    # Straight-line first guess; tf from the rocket equation; φ rising from 0 to 90°, the shape
    # of every braking-to-hover solution ([000] fig. 2).
    tf0 = ocp.rocket_equation_tf_nd()
    tau = np.linspace(0.0, 1.0, n + 1)
    taum = 0.5 * (tau[:-1] + tau[1:])
    xf_guess = np.array([tgt[0], tgt[1], 0.0, tgt[2] / tgt[0],
                         x0[dyn.M] - params.thrust_nd / params.exhaust_velocity_nd * tf0])
    xf_guess[dyn.THETA] = x0[dyn.THETA] + 0.5 * x0[dyn.OMEGA] * tf0

    def line(tt):
        return x0[:, None] * (1.0 - tt)[None, :] + xf_guess[:, None] * tt[None, :]

    w0 = np.concatenate([line(tau).T.ravel(), line(taum).T.ravel(), 0.5 * np.pi * tau,
                         0.5 * np.pi * taum, [tf0]])
    big = 1e3
    lbw = np.full(w0.shape, -big)
    ubw = np.full(w0.shape, big)
    nx = 5 * (n + 1)
    lbw[:5] = x0
    ubw[:5] = x0
    # Radii and masses stay positive (keeps IPOPT away from the 1/r² and 1/m poles).
    n_state_vars = nx + 5 * n
    lbw_states = lbw[:n_state_vars].reshape(-1, 5)  # view: node rows, then midpoint rows
    lbw_states[1:, dyn.R] = 0.5
    if min_radius_m is not None:
        require_finite_positive("min_radius_m", min_radius_m)
        lbw_states[1:, dyn.R] = max(0.5, float(s.length_nd(min_radius_m)))
    lbw_states[1:, dyn.M] = 0.05
    lbw[-1] = 1e-3 * tf0
    ubw[-1] = 20.0 * tf0
    nlp = {"x": w, "f": tf, "g": g}
    opts = {"ipopt.print_level": int(print_level), "print_time": False, "ipopt.tol": float(tol),
            "ipopt.max_iter": int(max_iter), "ipopt.sb": "yes"}
    solver = ca.nlpsol("hs_landing", "ipopt", nlp, opts)
    ng = int(g.shape[0])
    sol = solver(x0=w0, lbx=lbw, ubx=ubw, lbg=np.zeros(ng), ubg=np.zeros(ng))
    stats = solver.stats()
    wv = np.asarray(sol["x"]).ravel()
    lam_g = np.asarray(sol["lam_g"]).ravel()
    states = wv[:nx].reshape(n + 1, 5)
    off = nx + 5 * n
    phi = np.mod(wv[off:off + n + 1] + np.pi, 2.0 * np.pi) - np.pi  # wrap to [−π, π)
    tf_nd = float(wv[-1])
    costates = -lam_g[:5 * n].reshape(n, 5)
    n_f, n_it = nlp_counts(solver)
    fuel = ocp.fuel_kg(tf_nd)
    errors = ocp.terminal_errors(states[-1])
    r_min_m = float(np.min(states[:, dyn.R])) * s.length_m
    ok, why = ocp.success_from(errors, {
        "final_mass_kg": float(states[-1, dyn.M]) * s.mass_kg,
        "min_altitude_m": r_min_m - ocp.scenario.surface_radius_m})
    converged = bool(stats["success"])
    iters = stats.get("iterations", {}).get("obj", [])
    history = np.asarray([ocp.fuel_kg(v) for v in iters] or [fuel], dtype=np.float64)
    return CollocationSolution(
        x=wv, fuel_kg=fuel, tf_s=tf_nd * s.time_s, terminal_errors=errors, history=history,
        n_fevals=n_f, n_iter=n_it, wall_s=time.perf_counter() - t_start,
        success=converged and ok,
        message=f"IPOPT: {stats['return_status']}; {why}", fun=fuel,
        algorithm=f"Hermite–Simpson collocation ({n} intervals)", problem=repr(ocp),
        tf_nd=tf_nd, t_nd=tau * tf_nd, states_nd=states, phi_rad=phi, costates_nd=costates,
        t_mid_nd=taum * tf_nd)
