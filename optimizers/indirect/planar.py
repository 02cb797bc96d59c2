"""Pontryagin (indirect) shooting for the planar minimum-fuel landing with free final time.

Not in the papers, but every paper measures itself against "the Pontryagin optimum"; this
module computes it for any planar scenario (paper 000's nominal case ``zhu2007`` first) and
from any initial state, fast enough to be a per-case reference over a dispersion and a
closed-loop re-planning expert.

Problem
-------
Normalised units of :mod:`lunar_env.dynamics` (μ = 1, ``scenario.scaling()``). State
x = (r, v, θ, ω, m), control φ (thrust angle to the local horizontal), throttle fixed at 1:
paper 000's engine burns at constant thrust through the powered descent, so the propellant
used is ṁ·tf and **minimum fuel is minimum time**. Minimise J = tf subject to
x' = f(x, φ) = :func:`lunar_env.dynamics.planar_rhs_casadi`, x(0) = x0 and the terminal
conditions r(tf) = r_f, v(tf) = v_f, r(tf)·ω(tf) = v_t,f (θ(tf), m(tf) free).

Necessary conditions (derived here, on CasADi symbols of the shared right-hand side)
-------------------------------------------------------------------------------------
Hamiltonian, with the cost multiplier normalised to λ0 = 1 (normal extremal)::

    H(x, λ, φ) = 1 + λᵀ f(x, φ),     λ = (λ_r, λ_v, λ_θ, λ_ω, λ_m)

* Costate equations λ' = −∂H/∂x, obtained by **automatic differentiation** (CasADi) of
  ``planar_rhs_casadi`` with φ held fixed; nothing is re-typed by hand.
* Optimal thrust angle. φ enters H only through (F/m)·(λ_v sin φ − (λ_ω/r) cos φ). Writing
  A = λ_v, B = −λ_ω/r, the term A sin φ + B cos φ is minimised over φ by
  (sin φ, cos φ) = −(A, B)/√(A² + B²), i.e. ::

      φ* = atan2(−λ_v, λ_ω / r)

  the primer-vector law in this frame: the thrust points along −(λ_v, −λ_ω/r) in (radial,
  braking-horizontal) components. The minimum is unique whenever (λ_v, λ_ω) ≠ 0; the tests
  check H(φ*) ≤ H(φ) on a grid of φ along the optimal arc. Sign conventions: φ > 0 tilts the
  thrust upward; cos φ > 0 brakes the horizontal motion (as in :mod:`lunar_env.dynamics`).
* θ is free at tf and absent from f, so λ_θ' = 0 and λ_θ(tf) = 0 give λ_θ ≡ 0: it is fixed to
  zero and not an unknown.
* m(tf) is free: λ_m(tf) = 0. The mass costate does not feed back into φ* (constant thrust)
  but is integrated with the rest and enters H through λ_m·ṁ, so it is handled consistently.
* Free tf, autonomous problem: H ≡ 0 along the arc; imposed as H(tf) = 0 (transversality). The
  tests check that H stays at 0 along the whole arc.

Shooting
--------
Unknowns p = (λ_r(0), λ_v(0), λ_ω(0), λ_m(0), tf) (5); residuals (5)::

    r(tf) − r_f,  v(tf) − v_f,  r(tf)ω(tf) − v_t,f,  λ_m(tf),  H(tf)

The state–costate system is integrated on τ = t/tf ∈ [0, 1] with fixed-step RK4 written as
CasADi expressions that call the shared right-hand side (``n_steps`` steps, default 400), and
solved by a damped Newton method whose Jacobian is exact (CasADi AD) on a coarser grid
(``n_jac_steps``, default 50): an inexact Newton that converges to the fine-grid solution
(the coarse and fine Jacobians differ by O(h⁴), so the iteration contracts by ~1e-4 per step).

Robust start
------------
1. A warm start (``guess``) from a neighbouring solution, e.g. the previous case of a batch;
2. if Newton fails from it: continuation in the initial state from the guess's own initial
   state to the requested one (adaptive steps);
3. otherwise (and when no guess is given): costates estimated from the defect multipliers of a
   coarse direct collocation (:mod:`optimizers.planar_collocation`, CasADi + IPOPT), which
   converges from a straight-line guess.

Accuracy check
--------------
``check="reference"`` replays the solution's thrust angle through
:func:`lunar_env.integrators.integrate_reference` (scipy DOP853, rtol 1e-13) and reports the
terminal errors in SI; ``"doubling"`` re-integrates the state–costate system with 2·n_steps
(estimates the RK4 error, cheap); ``"grid"`` reports the shooting residual itself.

Paper 000's nominal case
------------------------
``zhu2007`` (g0 = 9.8 as in the paper): fuel **277.58520 kg**, tf **604.51888 s**, final thrust
angle 35.4°; terminal errors on the DOP853 replay ≈ 2e-7 m and 4e-10 m/s. An independent
direct method, Hermite–Simpson collocation with IPOPT (:mod:`optimizers.planar_collocation`,
100 intervals), gives 277.585200 kg (agreement < 1e-6 kg, tested); a second one, direct
shooting over degree-7 polynomial angles through the compiled RK4 of
:func:`lunar_env.integrators.integrate` (:mod:`optimizers.planar_direct_shooting`), gives
277.585200 kg; the best *cubic* (paper 000's control family) 277.585210 kg.

The paper reports 277.5765 kg, 0.0087 kg (0.003 %) less. Not explained by constants: g0 =
9.80665 instead of 9.8 moves our optimum to 277.4571 kg (−0.128 kg), μ = 4902.8026 km³/s² to
277.5856 kg; the stated ω0 = 9.65e-4 rad/s is used exactly (v_t0 = 1691.645 m/s). The
measured sensitivity ∂fuel/∂v_t0 = 0.100 kg per m/s puts the gap at the fuel worth of 0.09 m/s
of Δv, the size of the terminal-speed tolerances the paper accepts (its ASAGA runs end at
0.06–0.11 m/s), so the paper's indirect value is most likely a solution converged to a
looser terminal tolerance or integration accuracy. (Reproduce: the docstring numbers are
printed by ``python -m optimizers.pontryagin``.)

Public API
----------
:func:`solve_planar_min_fuel`, :func:`solve_many`, :class:`PontryaginSolution`,
:class:`PontryaginGuess`. The closed-loop re-planning expert built on them is
:class:`agents.experts.PontryaginExpert`.

>>> from lunar_env import get_scenario
>>> sol = solve_planar_min_fuel(get_scenario("zhu2007"))   # doctest: +SKIP
>>> round(sol.fuel_kg, 3), round(sol.tf_s, 3)               # doctest: +SKIP
(277.585, 604.519)
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from lunar_env import dynamics as dyn
from lunar_env.scenarios import PlanarScenario

from ..common.result import OptimResult, Trajectory
from ..transcription.collocation import (
    initial_state_nd,
    rocket_equation_tf_nd,
    solve_planar_min_time_collocation,
    target_nd,
)

__all__ = [
    "PontryaginGuess", "PontryaginSolution", "solve_planar_min_fuel",
    "solve_many", "nominal_guess", "nearest_neighbour_order", "optimal_thrust_angle",
    "hamiltonian", "replay_reference",
]

# Index of the state-costate vector z = (x, λ) (10,).
_LAM = 5
_CHECKS = ("reference", "doubling", "grid")


# ---------------------------------------------------------------------------------------------
# CasADi systems (built once per (params, grid) and cached per process)
# ---------------------------------------------------------------------------------------------


class _System:
    """CasADi functions of the state–costate system for one set of vehicle parameters."""

    def __init__(self, thrust_nd: float, exhaust_velocity_nd: float) -> None:
        import casadi as ca

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
        zs = ca.SX.sym("zs", 10)
        hs = ca.SX.sym("hs")
        k1 = self.rhs(zs)
        k2 = self.rhs(zs + 0.5 * hs * k1)
        k3 = self.rhs(zs + 0.5 * hs * k2)
        k4 = self.rhs(zs + hs * k3)
        self.step = ca.Function("pmp_rk4", [zs, hs], [zs + hs / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)])
        self._shooting: dict[tuple[int, bool], object] = {}
        self._grid: dict[int, object] = {}
        self._evals: dict[int, object] = {}

    @staticmethod
    def initial(ca, p, x0):
        return ca.vertcat(x0, p[0], p[1], 0.0, p[2], p[3])

    def residual_of(self, ca, zf, tgt):
        return ca.vertcat(zf[dyn.R] - tgt[0], zf[dyn.VR] - tgt[1],
                          zf[dyn.R] * zf[dyn.OMEGA] - tgt[2], zf[_LAM + dyn.M], self.ham(zf))

    def shooting(self, n_steps: int, with_jacobian: bool):
        """RK4 unrolled as SX (fast to evaluate).

        With the Jacobian: ``(p, x0, tgt) -> (res (5,), jac (5, 5))``; without:
        ``(p, x0, tgt) -> (res (5,), Z (10, n_steps + 1))`` (the grid).
        """
        key = (n_steps, with_jacobian)
        if key not in self._shooting:
            import casadi as ca

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
            import casadi as ca

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
            import casadi as ca

            zz = ca.SX.sym("z", 10)
            fun = ca.Function("pmp_eval", [zz], [self.rhs(zz), self.ham(zz), self.phi(zz)])
            self._evals[n] = fun.map(n)
        rhs, ham, phi = self._evals[n](zgrid)
        return np.asarray(rhs), np.asarray(ham).ravel(), np.asarray(phi).ravel()


_SYSTEMS: dict[tuple[float, float], _System] = {}


def _system(params: dyn.PlanarParams) -> _System:
    key = (float(params.thrust_nd), float(params.exhaust_velocity_nd))
    if key not in _SYSTEMS:
        _SYSTEMS[key] = _System(*key)
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


def hamiltonian(scenario: PlanarScenario, state_nd, costate_nd, phi_rad) -> np.ndarray:
    """H = 1 + λᵀ f(x, φ) with the throttle at 1 (normalised); shapes broadcast to (...,)."""
    params = scenario.params()
    s = np.atleast_2d(np.asarray(state_nd, dtype=np.float64))
    lam = np.atleast_2d(np.asarray(costate_nd, dtype=np.float64))
    phi = np.atleast_1d(np.asarray(phi_rad, dtype=np.float64))
    s, lam, phi = np.broadcast_arrays(s, lam, phi[..., None])
    u = np.stack([phi[..., 0], np.ones(phi.shape[:-1])], axis=-1)
    f = dyn.planar_rhs(s, u, params)
    return 1.0 + np.sum(lam * f, axis=-1)


# ---------------------------------------------------------------------------------------------
# Results
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PontryaginGuess:
    """A starting point for the shooting (normalised; reusable as a warm start).

    Attributes
    ----------
    costates0_nd : ndarray, shape (5,)
        (λ_r, λ_v, λ_θ, λ_ω, λ_m) at the initial time, λ0 = 1 normalisation; λ_θ is ignored
        (it is identically zero).
    tf_nd : float
        Time to go, normalised.
    x0_nd : ndarray, shape (5,) or None
        The initial state these costates belong to (enables continuation from it).
    """

    costates0_nd: np.ndarray
    tf_nd: float
    x0_nd: np.ndarray | None = None

    def unknowns(self) -> np.ndarray:
        lam = np.asarray(self.costates0_nd, dtype=np.float64)
        return np.array([lam[dyn.R], lam[dyn.VR], lam[dyn.OMEGA], lam[dyn.M], self.tf_nd])


@dataclass
class PontryaginSolution:
    """Result of :func:`solve_planar_min_fuel`.

    Attributes
    ----------
    success : bool
        Shooting converged (residual ≤ tol), tf > 0 and the fuel suffices; see ``message``.
    message : str
    fuel_kg : float
        Propellant used, ṁ·tf.
    tf_s : float
        Optimal final time (s).
    costates0 : ndarray, shape (5,)
        Initial costates (λ_r, λ_v, λ_θ, λ_ω, λ_m), conjugate to the normalised state,
        λ0 = 1 (J = tf in units of ``scaling.time_s``); λ_θ = 0.
    terminal_errors : dict of str -> float
        Absolute terminal errors in SI: ``radius_m``, ``radial_velocity_m_s``,
        ``tangential_velocity_m_s``, ``speed_m_s`` (norm of the two velocity errors), from the
        check named in ``check``.
    wall_s : float
        Wall time of the solve (including the check).
    guess : PontryaginGuess
        Warm start for a neighbouring problem.
    check : str
        How ``terminal_errors`` were measured ("reference", "doubling" or "grid").
    n_iter : int
        Newton iterations (all stages).
    residual_nd : float
        Final shooting residual (∞-norm, normalised).
    final_mass_kg : float
    x0_nd : ndarray, shape (5,)
        Normalised initial state.
    history : ndarray
        Residual ∞-norm per Newton iteration.
    """

    success: bool
    message: str
    fuel_kg: float
    tf_s: float
    costates0: np.ndarray
    terminal_errors: dict[str, float]
    wall_s: float
    guess: PontryaginGuess
    check: str
    n_iter: int
    residual_nd: float
    final_mass_kg: float
    x0_nd: np.ndarray
    history: np.ndarray
    scenario: PlanarScenario = field(repr=False)
    n_steps: int = 400
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    # ---- pickling: drop the (re-computable) grid cache --------------------------------------
    def __getstate__(self):
        d = dict(self.__dict__)
        d["_cache"] = {}
        return d

    @property
    def tf_nd(self) -> float:
        return float(self.guess.tf_nd)

    def _grid(self) -> dict:
        """The fine RK4 grid of the state–costate system and its derivatives (cached)."""
        if "dz" not in self._cache:
            sysm = _system(self.scenario.params())
            p = self.guess.unknowns()
            z = self._cache.get("z")
            if z is None:
                z = np.asarray(sysm.grid(self.n_steps)(p, self.x0_nd))
            rhs, ham, phi = sysm.evaluate(z)
            t = np.linspace(0.0, p[4], self.n_steps + 1)
            self._cache.update(z=z, dz=rhs, H=ham, phi=phi, t=t)
        return self._cache

    def _interp(self, t_nd) -> np.ndarray:
        """Cubic Hermite interpolation of z on the RK4 grid; t_nd (n,) -> (n, 10)."""
        g = self._grid()
        t = np.clip(np.atleast_1d(np.asarray(t_nd, dtype=np.float64)), 0.0, g["t"][-1])
        h = g["t"][1] - g["t"][0]
        k = np.clip((t / h).astype(np.int64), 0, self.n_steps - 1)
        s = (t - g["t"][k]) / h
        z0, z1 = g["z"][:, k], g["z"][:, k + 1]
        d0, d1 = g["dz"][:, k] * h, g["dz"][:, k + 1] * h
        s2, s3 = s * s, s * s * s
        out = ((2 * s3 - 3 * s2 + 1) * z0 + (s3 - 2 * s2 + s) * d0 + (-2 * s3 + 3 * s2) * z1
               + (s3 - s2) * d1)
        return out.T

    def state_costate_at(self, t_s) -> np.ndarray:
        """Normalised (x, λ) at times ``t_s`` (s, clipped to [0, tf]); shape (n, 10)."""
        return self._interp(self.scenario.scaling().time_nd(np.atleast_1d(t_s)))

    def thrust_angle_at(self, t_s):
        """Optimal thrust angle φ (rad) at time(s) ``t_s`` since the initial state.

        Parameters
        ----------
        t_s : float or ndarray, shape (n,)
            Times (s), clipped to [0, tf].

        Returns
        -------
        float or ndarray, shape (n,)
        """
        z = self.state_costate_at(t_s)
        phi = optimal_thrust_angle(z[:, :5], z[:, 5:])
        return float(phi[0]) if np.ndim(t_s) == 0 else phi

    def trajectory(self, n: int = 201) -> Trajectory:
        """The optimal trajectory at ``n`` equally spaced times, SI.

        States: ``radius_m``, ``altitude_m`` (above the scenario's surface),
        ``radial_velocity_m_s``, ``theta_rad``, ``angular_rate_rad_s``,
        ``tangential_velocity_m_s``, ``mass_kg``; controls ``phi_rad`` and ``throttle``
        (always 1); also ``hamiltonian`` (normalised, ≈ 0) among the states.
        """
        n = int(n)
        if n < 2:
            raise ValueError(f"n = {n} must be >= 2")
        sc = self.scenario.scaling()
        t_s = np.linspace(0.0, self.tf_s, n)
        z = self.state_costate_at(t_s)
        x, lam = z[:, :5], z[:, 5:]
        phi = optimal_thrust_angle(x, lam)
        r_m = x[:, dyn.R] * sc.length_m
        states = {
            "radius_m": r_m,
            "altitude_m": r_m - self.scenario.surface_radius_m,
            "radial_velocity_m_s": x[:, dyn.VR] * sc.velocity_m_s,
            "theta_rad": x[:, dyn.THETA],
            "angular_rate_rad_s": x[:, dyn.OMEGA] / sc.time_s,
            "tangential_velocity_m_s": x[:, dyn.R] * x[:, dyn.OMEGA] * sc.velocity_m_s,
            "mass_kg": x[:, dyn.M] * sc.mass_kg,
            "hamiltonian": hamiltonian(self.scenario, x, lam, phi),
        }
        return Trajectory(t_s=t_s, states=states,
                          controls={"phi_rad": phi, "throttle": np.ones(n)})

    def as_result(self, n_trajectory: int = 201) -> OptimResult:
        """The solution as an :class:`OptimResult` (x = the shooting unknowns)."""
        return OptimResult(
            x=self.guess.unknowns(), fuel_kg=self.fuel_kg, tf_s=self.tf_s,
            terminal_errors=dict(self.terminal_errors), history=np.asarray(self.history),
            n_fevals=self.n_iter, wall_s=self.wall_s, success=self.success,
            message=self.message, trajectory=self.trajectory(n_trajectory),
            extra={"method": "pontryagin", "costates0": self.costates0.copy(),
                   "check": self.check, "residual_nd": self.residual_nd,
                   "final_mass_kg": self.final_mass_kg, "n_steps": self.n_steps})


# ---------------------------------------------------------------------------------------------
# Newton
# ---------------------------------------------------------------------------------------------


def _newton(res_fine, res_jac_coarse, p, *, tol: float, max_iter: int, history: list
            ) -> tuple[np.ndarray, float, bool, int]:
    """Damped inexact Newton: residual on the fine grid, Jacobian from the coarse grid.

    Backtracking on the 2-norm of the fine residual; tf kept positive. Returns
    (p, ‖res‖∞, converged, iterations).
    """
    res = res_fine(p)
    nrm = float(np.max(np.abs(res))) if np.all(np.isfinite(res)) else math.inf
    history.append(nrm)
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
        if p[4] + dp[4] < 0.5 * p[4]:  # do not let tf collapse in one step
            alpha = 0.5 * p[4] / abs(dp[4])
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
    return p, nrm, nrm <= tol, it


class _Solver:
    """Shooting for one scenario and grid: holds the CasADi functions."""

    def __init__(self, scenario: PlanarScenario, n_steps: int, n_jac_steps: int) -> None:
        self.scenario = scenario
        self.params = scenario.params()
        self.system = _system(self.params)
        self.n_steps = n_steps
        self.n_jac_steps = n_jac_steps
        self.fine = self.system.shooting(n_steps, with_jacobian=False)
        self.coarse = self.system.shooting(n_jac_steps, with_jacobian=True)
        self.tgt = target_nd(scenario)

    def run(self, p0, x0, *, tol, max_iter, history):
        """Newton from ``p0``; returns (p, ‖res‖∞, converged, iterations, Z grid of p)."""
        grids: dict[bytes, np.ndarray] = {}

        def res_fine(p):
            res, z = self.fine(p, x0, self.tgt)
            grids.clear()
            grids[p.tobytes()] = z
            return np.asarray(res).ravel()

        def jac(p):
            return np.asarray(self.coarse(p, x0, self.tgt)[1])

        p, nrm, ok, it = _newton(res_fine, jac, np.asarray(p0, dtype=np.float64), tol=tol,
                                 max_iter=max_iter, history=history)
        z = grids.get(p.tobytes())
        if z is None:
            z = self.fine(p, x0, self.tgt)[1]
        return p, nrm, ok, it, np.asarray(z)


_SOLVERS: dict[tuple, _Solver] = {}


def _solver(scenario: PlanarScenario, n_steps: int, n_jac_steps: int) -> _Solver:
    key = (scenario, n_steps, n_jac_steps)
    if key not in _SOLVERS:
        _SOLVERS[key] = _Solver(scenario, n_steps, n_jac_steps)
    return _SOLVERS[key]


def _collocation_guess(scenario, x0_nd, n_intervals: int) -> PontryaginGuess | None:
    s = scenario.scaling()
    row = np.array([x0_nd[dyn.R] * s.length_m, x0_nd[dyn.VR] * s.velocity_m_s, x0_nd[dyn.THETA],
                    x0_nd[dyn.R] * x0_nd[dyn.OMEGA] * s.velocity_m_s, x0_nd[dyn.M] * s.mass_kg])
    col = solve_planar_min_time_collocation(scenario, row, n_intervals=n_intervals, tol=1e-8)
    if not col.success:
        return None
    # ν_0 estimates λ at the first interval's midpoint; good enough for Newton.
    return PontryaginGuess(col.costates_nd[0].copy(), col.tf_nd, np.asarray(x0_nd, float).copy())


# ---------------------------------------------------------------------------------------------
# Public: one solve
# ---------------------------------------------------------------------------------------------


def _as_guess(guess) -> PontryaginGuess | None:
    if guess is None or isinstance(guess, PontryaginGuess):
        return guess
    if isinstance(guess, PontryaginSolution):
        return guess.guess
    raise TypeError(f"guess must be a PontryaginGuess, a PontryaginSolution or None, got "
                    f"{type(guess).__name__}")


def solve_planar_min_fuel(
    scenario: PlanarScenario,
    initial_state_si=None,
    *,
    guess: PontryaginGuess | PontryaginSolution | None = None,
    n_steps: int = 400,
    n_jac_steps: int = 50,
    tol: float = 1e-13,
    max_iter: int = 30,
    check: str = "reference",
    continuation: bool = True,
    collocation_fallback: bool = True,
) -> PontryaginSolution:
    """Minimum-fuel (= minimum-time, constant thrust) planar landing by Pontryagin shooting.

    Parameters
    ----------
    scenario : PlanarScenario
        E.g. ``get_scenario("zhu2007")``; its vehicle, target and scaling are used.
    initial_state_si : array_like, shape (5,), optional
        (r m, vr m/s, θ rad, v_t m/s, m kg); default the scenario's nominal initial state.
    guess : PontryaginGuess or PontryaginSolution, optional
        Warm start (e.g. a neighbour's ``solution.guess``). Default: a coarse collocation.
    n_steps : int
        RK4 steps of the state–costate integration (accuracy; default 400 gives terminal errors
        ≪ 1e-6 m on zhu2007).
    n_jac_steps : int
        RK4 steps of the grid on which the Newton Jacobian is computed (speed).
    tol : float
        Convergence: ∞-norm of the normalised shooting residual.
    max_iter : int
        Newton iterations per attempt.
    check : {"reference", "doubling", "grid"}
        How ``terminal_errors`` are measured (see the module docstring).
    continuation : bool
        On failure from ``guess``, continue in the initial state from ``guess.x0_nd``.
    collocation_fallback : bool
        On failure, restart from a collocation estimate of the costates.

    Returns
    -------
    PontryaginSolution
        ``success`` False (not an exception) when no extremal was found.

    Raises
    ------
    TypeError
        ``scenario`` is not planar, or ``guess`` has the wrong type.
    ValueError
        ``initial_state_si`` has the wrong shape or non-finite values, a non-positive radius
        or a mass at or below the dry mass; bad ``n_steps``, ``tol``, ``check``.
    """
    t_start = time.perf_counter()
    x0 = initial_state_nd(scenario, initial_state_si)
    n_steps = int(n_steps)
    n_jac_steps = int(n_jac_steps)
    if n_steps < 4 or n_jac_steps < 4:
        raise ValueError(f"n_steps = {n_steps} and n_jac_steps = {n_jac_steps} must be >= 4")
    if not (math.isfinite(tol) and tol > 0):
        raise ValueError(f"tol = {tol!r} must be finite and > 0")
    if check not in _CHECKS:
        raise ValueError(f"check = {check!r} is not one of {_CHECKS}")
    g = _as_guess(guess)
    solver = _solver(scenario, n_steps, n_jac_steps)
    history: list[float] = []
    n_iter = 0
    attempts: list[str] = []

    grid: list[np.ndarray] = []

    def attempt(p0, x_start):
        nonlocal n_iter
        p, nrm, ok, it, z = solver.run(p0, x_start, tol=tol, max_iter=max_iter, history=history)
        n_iter += it
        grid[:] = [z]
        return p, nrm, ok and p[4] > 0

    p = None
    ok = False
    nrm = math.inf
    if g is not None:
        attempts.append("warm start")
        p, nrm, ok = attempt(g.unknowns(), x0)
        if not ok and continuation and g.x0_nd is not None:
            attempts.append("continuation")
            p, nrm, ok = _continuation(attempt, g, x0)
    if not ok and (g is None or collocation_fallback):
        for n_int in (20, 60):
            cg = _collocation_guess(scenario, x0, n_int)
            if cg is None:
                continue
            attempts.append(f"collocation({n_int})")
            p, nrm, ok = attempt(cg.unknowns(), x0)
            if ok:
                break
    if p is None:
        p = np.array([0.0, 0.0, 1.0, 0.0, rocket_equation_tf_nd(scenario, x0)])
    if not grid or attempts[-1] == "continuation" and not ok:
        grid[:] = []  # the last grid belongs to an intermediate state of the continuation
    return _finish(scenario, solver, x0, p, nrm, ok, attempts, history, n_iter, check, tol,
                   t_start, grid[0] if grid else None)


def _continuation(attempt, g: PontryaginGuess, x0: np.ndarray):
    """Walk the initial state from ``g.x0_nd`` to ``x0`` with adaptive steps."""
    xa = np.asarray(g.x0_nd, dtype=np.float64)
    p = g.unknowns()
    s, ds = 0.0, 0.25
    nrm = math.inf
    while s < 1.0:
        s_try = min(1.0, s + ds)
        p_try, nrm, ok = attempt(p, xa + s_try * (x0 - xa))
        if ok:
            s, p = s_try, p_try
            ds = min(0.5, 2 * ds)
        else:
            ds *= 0.5
            if ds < 1.0 / 64:
                return p, nrm, False
    return p, nrm, True


def _finish(scenario, solver: _Solver, x0, p, nrm, ok, attempts, history, n_iter, check, tol,
            t_start, z_grid) -> PontryaginSolution:
    sc = scenario.scaling()
    params = solver.params
    lam0 = np.array([p[0], p[1], 0.0, p[2], p[3]])
    tf_nd = float(p[4])
    flow = params.thrust_nd / params.exhaust_velocity_nd
    mf_nd = float(x0[dyn.M] - flow * tf_nd)
    final_mass_kg = mf_nd * sc.mass_kg
    fuel_kg = float(x0[dyn.M] * sc.mass_kg - final_mass_kg)
    guess = PontryaginGuess(lam0, tf_nd, np.asarray(x0, float).copy())
    how = " -> ".join(attempts) if attempts else "none"
    if ok and final_mass_kg <= scenario.vehicle.dry_mass_kg:
        ok = False
        message = (f"extremal found ({how}) but it needs {fuel_kg:.3f} kg: more than the "
                   f"propellant above the dry mass")
    elif ok:
        message = f"converged ({how}), residual {nrm:.2e}"
    else:
        message = f"shooting did not converge ({how}); best residual {nrm:.2e} (tol {tol:.0e})"
    sol = PontryaginSolution(
        success=bool(ok), message=message, fuel_kg=fuel_kg, tf_s=tf_nd * sc.time_s,
        costates0=lam0, terminal_errors={}, wall_s=0.0, guess=guess, check=check,
        n_iter=int(n_iter), residual_nd=float(nrm), final_mass_kg=final_mass_kg,
        x0_nd=np.asarray(x0, float).copy(), history=np.asarray(history), scenario=scenario,
        n_steps=solver.n_steps)
    if z_grid is not None:
        sol._cache["z"] = z_grid
    if ok:
        z = sol._cache["z"] if z_grid is not None else sol._grid()["z"]
        r_min = float(np.min(z[dyn.R])) * sc.length_m
        if r_min < scenario.surface_radius_m - 1.0:
            sol.success = False
            depth_m = scenario.surface_radius_m - r_min
            sol.message = (f"extremal found ({how}) but it passes {depth_m:.1f} m below the "
                           "surface")
    sol.terminal_errors = _terminal_errors(sol, solver, check)
    sol.wall_s = time.perf_counter() - t_start
    return sol


def _errors_si(scenario, xf: np.ndarray) -> dict[str, float]:
    sc = scenario.scaling()
    tgt = target_nd(scenario)
    dr = abs(xf[dyn.R] - tgt[0]) * sc.length_m
    dv = (xf[dyn.VR] - tgt[1]) * sc.velocity_m_s
    dvt = (xf[dyn.R] * xf[dyn.OMEGA] - tgt[2]) * sc.velocity_m_s
    return {"radius_m": float(dr), "radial_velocity_m_s": float(abs(dv)),
            "tangential_velocity_m_s": float(abs(dvt)), "speed_m_s": float(math.hypot(dv, dvt))}


def _terminal_errors(sol: PontryaginSolution, solver: _Solver, check: str) -> dict[str, float]:
    p = sol.guess.unknowns()
    if check == "grid":
        xf = sol._cache["z"][:5, -1] if "z" in sol._cache else sol._grid()["z"][:5, -1]
    elif check == "doubling":
        xf = np.asarray(solver.system.grid(2 * solver.n_steps)(p, sol.x0_nd))[:5, -1]
    else:
        xf = replay_reference(sol)
    return _errors_si(sol.scenario, xf)


def replay_reference(sol: PontryaginSolution, *, rtol: float = 1e-13,
                     atol: float = 1e-15) -> np.ndarray:
    """Replay ``sol``'s thrust angle through :func:`lunar_env.integrators.integrate_reference`.

    The control is φ(t) from the solution's costates (cubic Hermite on the RK4 grid); the state
    is integrated by scipy DOP853 on the shared NumPy right-hand side. Returns the normalised
    final state (5,).
    """
    from lunar_env.integrators import PLANAR, integrate_reference

    # Scalar fast path of the cubic Hermite interpolant for the three components φ* needs
    # (r, λ_v, λ_ω): scipy calls this ~10⁴ times.
    g = sol._grid()
    rows = [dyn.R, _LAM + dyn.VR, _LAM + dyn.OMEGA]
    h = float(g["t"][1] - g["t"][0])
    z = g["z"][rows].T.copy()
    dz = g["dz"][rows].T.copy() * h
    n_seg = sol.n_steps
    t_end = float(g["t"][-1])

    def control(t_nd):
        t = min(max(float(t_nd), 0.0), t_end)
        k = min(int(t / h), n_seg - 1)
        s = t / h - k
        s2 = s * s
        s3 = s2 * s
        h00, h10, h01, h11 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2
        r, lv, lw = h00 * z[k] + h10 * dz[k] + h01 * z[k + 1] + h11 * dz[k + 1]
        return (math.atan2(-lv, lw / r), 1.0)

    out = integrate_reference(PLANAR, sol.x0_nd, (0.0, sol.tf_nd), control,
                              sol.scenario.params(), rtol=rtol, atol=atol)
    return out.y[:, -1]


# ---------------------------------------------------------------------------------------------
# Public: batches
# ---------------------------------------------------------------------------------------------


def _check_states(initial_states_si) -> np.ndarray:
    states = np.asarray(initial_states_si, dtype=np.float64)
    if states.ndim != 2 or states.shape[1] != 5:
        raise ValueError(f"initial_states_si has shape {states.shape}; expected (N, 5) rows "
                         "(r m, vr m/s, θ rad, v_t m/s, m kg)")
    if not np.all(np.isfinite(states)):
        bad = np.argwhere(~np.all(np.isfinite(states), axis=1)).ravel()
        raise ValueError(f"initial_states_si rows {bad[:10].tolist()} are not finite")
    return states


def nearest_neighbour_order(scenario: PlanarScenario, initial_states_si) -> np.ndarray:
    """Order rows so that each is close to the previous one (greedy chain).

    Distance: normalised (r, v, r·ω, m); θ is ignored because the solution does not depend on
    it (θ is cyclic). The chain starts at the row nearest the scenario's nominal state.

    Returns
    -------
    ndarray of int, shape (N,)
    """
    states = _check_states(initial_states_si)
    nd = scenario.si_to_nd(states)
    feat = np.stack([nd[:, dyn.R], nd[:, dyn.VR], nd[:, dyn.R] * nd[:, dyn.OMEGA],
                     nd[:, dyn.M]], axis=1)
    x_nom = scenario.state_nd()
    nom = np.array([x_nom[dyn.R], x_nom[dyn.VR], x_nom[dyn.R] * x_nom[dyn.OMEGA], x_nom[dyn.M]])
    n = len(feat)
    order = np.empty(n, dtype=np.int64)
    left = np.ones(n, dtype=bool)
    cur = int(np.argmin(np.sum((feat - nom) ** 2, axis=1)))
    for i in range(n):
        order[i] = cur
        left[cur] = False
        if i == n - 1:
            break
        d = np.sum((feat - feat[cur]) ** 2, axis=1)
        d[~left] = np.inf
        cur = int(np.argmin(d))
    return order


_NOMINAL_GUESS: dict[tuple, PontryaginGuess] = {}


def nominal_guess(scenario: PlanarScenario, n_steps: int = 400) -> PontryaginGuess:
    """Warm start from the scenario's nominal optimum (solved once per process, cached).

    Raises
    ------
    RuntimeError
        If the nominal problem itself has no solution.
    """
    key = (scenario, int(n_steps))
    if key not in _NOMINAL_GUESS:
        sol = solve_planar_min_fuel(scenario, n_steps=n_steps, check="grid")
        if not sol.success:
            raise RuntimeError(f"{scenario.name}: the nominal Pontryagin problem did not solve: "
                               f"{sol.message}")
        _NOMINAL_GUESS[key] = sol.guess
    return _NOMINAL_GUESS[key]


def _solve_chain(scenario, states_si, start: PontryaginGuess | None, kwargs) -> list:
    """Solve rows in the given order, each warm-started from the previous success."""
    out = []
    g = start
    for row in states_si:
        sol = solve_planar_min_fuel(scenario, row, guess=g, **kwargs)
        out.append(sol)
        if sol.success:
            g = sol.guess
    return out


def solve_many(
    scenario: PlanarScenario,
    initial_states_si,
    *,
    n_workers: int = 1,
    progress: bool = True,
    chunk_size: int = 50,
    n_steps: int = 400,
    check: str = "grid",
    **kwargs,
) -> list[PontryaginSolution]:
    """Solve the minimum-fuel landing from many initial states (e.g. a dispersion).

    The rows are chained by :func:`nearest_neighbour_order`; each solve is warm-started from
    the previous success in the chain (the first from the nominal optimum), with the
    continuation and collocation fallbacks of :func:`solve_planar_min_fuel`.

    Parameters
    ----------
    scenario : PlanarScenario
    initial_states_si : array_like, shape (N, 5)
        SI rows (r m, vr m/s, θ rad, v_t m/s, m kg), e.g. ``scenario.sample_initial(rng, N)``.
    n_workers : int
        1 solves in this process; more uses a process pool (spawned; each worker builds its
        CasADi functions once, ~0.5 s) over contiguous chunks of the chain. Spawned workers
        re-import the main module: in a script, call from under ``if __name__ == "__main__":``.
        On a busy 2-core machine one worker is usually as fast.
    progress : bool
        Show a tqdm progress bar.
    chunk_size : int
        Rows per pool task (each chunk restarts from the nominal guess).
    n_steps, check, **kwargs
        Passed to :func:`solve_planar_min_fuel` (default ``check="grid"``: the terminal errors
        are the shooting residual; use ``"doubling"`` for an RK4 error estimate).

    Returns
    -------
    list of PontryaginSolution, in the order of the input rows.

    Raises
    ------
    ValueError
        Bad shape, non-finite rows, ``n_workers < 1`` or ``chunk_size < 1``.
    """
    states = _check_states(initial_states_si)
    n_workers = int(n_workers)
    if n_workers < 1:
        raise ValueError(f"n_workers = {n_workers} must be >= 1")
    if int(chunk_size) < 1:
        raise ValueError(f"chunk_size = {chunk_size!r} must be >= 1")
    for i, row in enumerate(states):  # validate every row before any work
        try:
            initial_state_nd(scenario, row)
        except ValueError as exc:
            raise ValueError(f"initial_states_si row {i}: {exc}") from None
    n = len(states)
    if n == 0:
        return []
    order = nearest_neighbour_order(scenario, states)
    kwargs = dict(kwargs, n_steps=n_steps, check=check)
    start = nominal_guess(scenario, n_steps)
    results: list[PontryaginSolution | None] = [None] * n
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=n, desc=f"Pontryagin {scenario.name}", unit="state")
    try:
        if n_workers == 1:
            g = start
            for idx in order:
                sol = solve_planar_min_fuel(scenario, states[idx], guess=g, **kwargs)
                results[idx] = sol
                if sol.success:
                    g = sol.guess
                if bar is not None:
                    bar.update(1)
        else:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor, as_completed

            chunks = [order[i:i + int(chunk_size)] for i in range(0, n, int(chunk_size))]
            ctx = mp.get_context("spawn")
            with ProcessPoolExecutor(max_workers=n_workers, mp_context=ctx) as pool:
                futs = {pool.submit(_solve_chain, scenario, states[c], start, kwargs): c
                        for c in chunks}
                for fut in as_completed(futs):
                    c = futs[fut]
                    for idx, sol in zip(c, fut.result(), strict=True):
                        results[idx] = sol
                    if bar is not None:
                        bar.update(len(c))
    finally:
        if bar is not None:
            bar.close()
    return results  # type: ignore[return-value]


# ---------------------------------------------------------------------------------------------
# Command line: the numbers of the module docstring, measured
# ---------------------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    """``python -m optimizers.pontryagin [--scenario zhu2007] [--n 1000] [--workers 1]
    [--json FILE]``: nominal optimum with its DOP853 check, the independent collocation value,
    the paper-comparison variants, and the timing of a batch of dispersed states."""
    import argparse
    import dataclasses
    import json

    from lunar_env.scenarios import get_scenario

    ap = argparse.ArgumentParser(prog="python -m optimizers.pontryagin", description=main.__doc__)
    ap.add_argument("--scenario", default="zhu2007")
    ap.add_argument("--n", type=int, default=1000, help="dispersed states to solve (0: none)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--seed", type=int, default=2007)
    ap.add_argument("--json", default=None, help="write the measured values to this file")
    args = ap.parse_args(argv)
    sc = get_scenario(args.scenario)
    out: dict = {"scenario": sc.name}

    t0 = time.perf_counter()
    sol = solve_planar_min_fuel(sc)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    again = solve_planar_min_fuel(sc)
    second = time.perf_counter() - t0
    print(f"{sc.name}: {sol.message}")
    print(f"  optimum fuel {sol.fuel_kg:.6f} kg, tf {sol.tf_s:.6f} s, final angle "
          f"{math.degrees(sol.thrust_angle_at(sol.tf_s)):.3f} deg")
    print("  terminal errors (DOP853 replay): " + ", ".join(
        f"{k} {v:.2e}" for k, v in sol.terminal_errors.items()))
    print(f"  wall: first call {first:.3f} s (CasADi build + collocation start), "
          f"second {second:.3f} s")
    out["pontryagin"] = {"fuel_kg": sol.fuel_kg, "tf_s": sol.tf_s, "success": sol.success,
                         "terminal_errors": sol.terminal_errors, "wall_first_s": first,
                         "wall_second_s": second, "costates0": sol.costates0.tolist()}
    del again

    t0 = time.perf_counter()
    col = solve_planar_min_time_collocation(sc, n_intervals=100)
    print(f"  independent: Hermite-Simpson collocation (100 intervals, IPOPT) {col.fuel_kg:.6f} "
          f"kg, tf {col.tf_s:.6f} s ({col.message}, {time.perf_counter() - t0:.2f} s); "
          f"difference {col.fuel_kg - sol.fuel_kg:+.2e} kg")
    out["collocation"] = {"fuel_kg": col.fuel_kg, "tf_s": col.tf_s, "success": col.success}
    from ..transcription.polynomial_shooting import solve_planar_min_time_polynomial

    out["direct_shooting"] = {}
    # Its first guess (φ rising from 0 to π/2) is a landing's; run it on the landing case only.
    for degree in (3, 7) if sc.name == "zhu2007" else ():
        ds = solve_planar_min_time_polynomial(sc, degree=degree)
        print(f"  independent: direct shooting, degree-{degree} polynomial angle, compiled RK4 "
              f"(SLSQP) {ds.fuel_kg:.6f} kg ({ds.message}, {ds.wall_s:.2f} s); difference "
              f"{ds.fuel_kg - sol.fuel_kg:+.2e} kg")
        out["direct_shooting"][f"degree_{degree}"] = {"fuel_kg": ds.fuel_kg, "tf_s": ds.tf_s,
                                                      "success": ds.success}

    if sc.name == "zhu2007":
        variants = {
            "g0 = 9.80665": dataclasses.replace(
                sc, vehicle=dataclasses.replace(sc.vehicle, g0_m_s2=9.80665)),
            "mu = 4902.8026e9": dataclasses.replace(
                sc, body=dataclasses.replace(sc.body, mu_m3_s2=4902.8026e9)),
        }
        out["variants"] = {}
        print("  paper 000 reports 277.5765 kg; variants:")
        for name, var in variants.items():
            v = solve_planar_min_fuel(var, check="grid")
            out["variants"][name] = v.fuel_kg
            print(f"    {name:18s} {v.fuel_kg:.4f} kg")
        x = np.array([sc.initial.radius_m, sc.initial.radial_velocity_m_s, 0.0,
                      sc.initial.tangential_velocity_m_s, sc.vehicle.mass_kg])
        fuels = []
        for dv in (-0.1, 0.1):
            fuels.append(solve_planar_min_fuel(sc, x + np.array([0, 0, 0, dv, 0]), guess=sol,
                                               check="grid").fuel_kg)
        sens = (fuels[1] - fuels[0]) / 0.2
        out["dfuel_dvt0_kg_per_m_s"] = sens
        print(f"    d fuel / d v_t0    {sens:.4f} kg per m/s -> the gap "
              f"{sol.fuel_kg - 277.5765:.4f} kg is worth {(sol.fuel_kg - 277.5765) / sens:.3f} m/s")

    if args.n > 0:
        rng = np.random.default_rng(args.seed)
        states = sc.sample_initial(rng, args.n)
        t0 = time.perf_counter()
        sols = solve_many(sc, states, n_workers=args.workers, progress=True)
        wall = time.perf_counter() - t0
        ok = np.array([s.success for s in sols])
        fuel = np.array([s.fuel_kg for s in sols])
        per = np.array([s.wall_s for s in sols])
        print(f"  {args.n} dispersed states (seed {args.seed}, {args.workers} worker(s)): "
              f"{ok.sum()} solved, batch wall {wall:.2f} s = {1e3 * wall / args.n:.2f} ms/state "
              f"(median solve {1e3 * np.median(per):.2f} ms, max {1e3 * per.max():.1f} ms); "
              f"fuel {fuel.min():.3f}..{fuel.max():.3f} kg")
        out["batch"] = {"n": args.n, "n_success": int(ok.sum()), "wall_s": wall,
                        "ms_per_state": 1e3 * wall / args.n,
                        "median_solve_ms": float(1e3 * np.median(per)),
                        "fuel_kg_min": float(fuel.min()), "fuel_kg_max": float(fuel.max())}
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
