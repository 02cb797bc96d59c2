"""Direct Hermite–Simpson collocation of the planar minimum-time (= minimum-fuel) landing.

A *direct* transcription of the same optimal-control problem the Pontryagin solver
(:mod:`optimizers.pontryagin`) solves indirectly, with CasADi and IPOPT. It has two jobs:

1. **Robust start** for the indirect shooting: a coarse grid (≈ 20 intervals) converges from a
   crude straight-line guess, and the multipliers of its defect constraints estimate the
   costates (see :attr:`CollocationSolution.costates_nd`).
2. **Independent check** of the indirect optimum: a dense grid (≥ 100 intervals) gives the
   optimum by a different method (no costates, no shooting), used in ``tests/test_pontryagin.py``.

Problem (normalised units of :mod:`lunar_env.dynamics`, μ = 1): minimise tf subject to the planar
equations of motion :func:`lunar_env.dynamics.planar_rhs_casadi` with the throttle fixed at 1
(paper 000's engine burns at constant thrust through the powered descent, so minimum fuel is
minimum time), x(0) given, r(tf) = r_f, v(tf) = v_f, r(tf)·ω(tf) = v_t,f, θ(tf) and m(tf) free.

Transcription: separated Hermite–Simpson on N equal intervals of the scaled time τ = t/tf ∈
[0, 1]; states and the thrust angle at the nodes and interval midpoints; tf is a decision
variable. Defects (h = tf/N)::

    x_{k+½} = (x_k + x_{k+1})/2 + h/8 (f_k − f_{k+1})
    x_{k+1} = x_k + h/6 (f_k + 4 f_{k+½} + f_{k+1})

Costate estimate. CasADi reports IPOPT's multipliers ν with the Lagrangian
L = tf + Σ ν_kᵀ g_k. For the Simpson defect g_k = x_{k+1} − x_k − h/6(...), stationarity in x_k
gives ν_k − ν_{k−1} ≈ −h ν ∂f/∂x, the costate equation λ' = −∂H/∂x; stationarity in tf gives
1 − mean_k(ν_k·f_k) ≈ 0. With the Pontryagin normalisation H = 1 + λᵀf = 0 of
:mod:`optimizers.pontryagin` (λ0 = 1), the costate is therefore λ(t_{k+½}) ≈ −ν_k, which is what
:attr:`CollocationSolution.costates_nd` holds (checked in the tests: the thrust angle that
minimises H with these costates matches the collocated angle).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from lunar_env import dynamics as dyn
from lunar_env.scenarios import PlanarScenario
from lunar_env.validation import require_finite_positive

__all__ = ["CollocationSolution", "solve_planar_min_time_collocation", "initial_state_nd"]


@dataclass
class CollocationSolution:
    """Result of :func:`solve_planar_min_time_collocation` (normalised unless stated).

    Attributes
    ----------
    success : bool
        IPOPT reported convergence.
    message : str
        IPOPT's return status.
    tf_nd : float
    tf_s : float
    fuel_kg : float
        Propellant used, mass flow × tf (constant thrust).
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
    wall_s : float
    """

    success: bool
    message: str
    tf_nd: float
    tf_s: float
    fuel_kg: float
    t_nd: np.ndarray
    states_nd: np.ndarray
    phi_rad: np.ndarray
    costates_nd: np.ndarray
    t_mid_nd: np.ndarray
    wall_s: float


def initial_state_nd(scenario: PlanarScenario, initial_state_si=None) -> np.ndarray:
    """Normalised initial state (5,) from an SI row (r m, vr m/s, θ rad, v_t m/s, m kg).

    ``None`` gives the scenario's nominal initial state.

    Raises
    ------
    TypeError
        If ``scenario`` is not a planar scenario.
    ValueError
        If the row has the wrong shape, is not finite, or has a non-positive radius or a mass
        at or below the dry mass.
    """
    if not isinstance(scenario, PlanarScenario):
        raise TypeError(f"scenario must be a PlanarScenario (e.g. get_scenario('zhu2007')), got "
                        f"{type(scenario).__name__}")
    if initial_state_si is None:
        return scenario.state_nd()
    row = np.asarray(initial_state_si, dtype=np.float64)
    if row.shape != (5,):
        raise ValueError(f"initial_state_si has shape {row.shape}; expected (5,) = "
                         "(r m, vr m/s, θ rad, v_t m/s, m kg)")
    if not np.all(np.isfinite(row)):
        raise ValueError(f"initial_state_si = {row!r} is not finite; all 5 components must be")
    if row[0] <= 0.0:
        raise ValueError(f"initial_state_si radius = {row[0]!r} m must be > 0")
    if row[4] <= scenario.vehicle.dry_mass_kg:
        raise ValueError(f"initial_state_si mass = {row[4]!r} kg must be > the dry mass "
                         f"{scenario.vehicle.dry_mass_kg!r} kg")
    return scenario.si_to_nd(row)


def target_nd(scenario: PlanarScenario) -> np.ndarray:
    """Normalised terminal targets (r_f, v_f, v_t,f), shape (3,)."""
    s = scenario.scaling()
    t = scenario.target
    return np.array([s.length_nd(t.radius_m), s.velocity_nd(t.radial_velocity_m_s),
                     s.velocity_nd(t.tangential_velocity_m_s)], dtype=np.float64)


def rocket_equation_tf_nd(scenario: PlanarScenario, x0_nd: np.ndarray) -> float:
    """First guess of tf from the rocket equation ([000] eq. 23) with the speed to remove.

    tf ≈ (1 − exp(−Δv/c))·m0·c/F, Δv = |(v0, r0ω0) − (v_f, v_t,f)|, normalised units.
    """
    p = scenario.params()
    tgt = target_nd(scenario)
    dv = np.hypot(x0_nd[dyn.VR] - tgt[1], x0_nd[dyn.R] * x0_nd[dyn.OMEGA] - tgt[2])
    c = p.exhaust_velocity_nd
    return float((1.0 - np.exp(-dv / c)) * x0_nd[dyn.M] * c / p.thrust_nd)


def solve_planar_min_time_collocation(
    scenario: PlanarScenario,
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
    scenario : PlanarScenario
        E.g. ``get_scenario("zhu2007")``. The throttle is fixed at 1 (constant thrust).
    initial_state_si : array_like, shape (5,), optional
        (r m, vr m/s, θ rad, v_t m/s, m kg); default the scenario's nominal initial state.
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
        On invalid input (see :func:`initial_state_nd`) or ``n_intervals < 2``.
    """
    import casadi as ca

    t_start = time.perf_counter()
    x0 = initial_state_nd(scenario, initial_state_si)
    n = int(n_intervals)
    if n < 2:
        raise ValueError(f"n_intervals = {n_intervals!r} must be >= 2")
    if not (np.isfinite(tol) and tol > 0):
        raise ValueError(f"tol = {tol!r} must be finite and > 0")
    params = scenario.params()
    s = scenario.scaling()
    tgt = target_nd(scenario)

    xs = ca.SX.sym("x", 5)
    us = ca.SX.sym("phi")
    f_fun = ca.Function("f", [xs, us], [dyn.planar_rhs_casadi(xs, ca.vertcat(us, 1.0), params)])

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
    g_term = ca.vertcat(xf[dyn.R] - tgt[0], xf[dyn.VR] - tgt[1],
                        xf[dyn.R] * xf[dyn.OMEGA] - tgt[2])
    w = ca.vertcat(ca.vec(opti_x), ca.vec(opti_xm), ca.vec(opti_u), ca.vec(opti_um), tf)
    g = ca.vertcat(ca.vec(g_simpson), ca.vec(g_mid), g_term)

    # Straight-line first guess; tf from the rocket equation; φ rising from 0 to 90°, the shape
    # of every braking-to-hover solution ([000] fig. 2).
    tf0 = rocket_equation_tf_nd(scenario, x0)
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
    flow = scenario.vehicle.mass_flow_kg_s
    return CollocationSolution(
        success=bool(stats["success"]),
        message=str(stats["return_status"]),
        tf_nd=tf_nd,
        tf_s=tf_nd * s.time_s,
        fuel_kg=flow * tf_nd * s.time_s,
        t_nd=tau * tf_nd,
        states_nd=states,
        phi_rad=phi,
        costates_nd=costates,
        t_mid_nd=taum * tf_nd,
        wall_s=time.perf_counter() - t_start,
    )
