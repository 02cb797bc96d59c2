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
   coarse direct collocation (:mod:`optimizers.transcription.collocation`, CasADi + IPOPT), which
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
direct method, Hermite–Simpson collocation with IPOPT
(:mod:`optimizers.transcription.collocation`, 100 intervals), gives 277.585200 kg (agreement
< 1e-6 kg, tested); a second one, direct shooting over degree-7 polynomial angles through the
compiled RK4 of :func:`lunar_env.integrators.integrate`
(:mod:`optimizers.transcription.polynomial_shooting`), gives 277.585200 kg; the best *cubic*
(paper 000's control family) 277.585210 kg.

The paper reports 277.5765 kg, 0.0087 kg (0.003 %) less. Not explained by constants: g0 =
9.80665 instead of 9.8 moves our optimum to 277.4571 kg (−0.128 kg), μ = 4902.8026 km³/s² to
277.5856 kg; the stated ω0 = 9.65e-4 rad/s is used exactly (v_t0 = 1691.645 m/s). The
measured sensitivity ∂fuel/∂v_t0 = 0.100 kg per m/s puts the gap at the fuel worth of 0.09 m/s
of Δv, the size of the terminal-speed tolerances the paper accepts (its ASAGA runs end at
0.06–0.11 m/s), so the paper's indirect value is most likely a solution converged to a
looser terminal tolerance or integration accuracy. (Reproduce: the docstring numbers are
printed by ``python -m optimizers.indirect.cli``.)

Public API
----------
:func:`solve_planar_min_fuel`, :class:`PontryaginSolution` (an :class:`~optimizers.common.
result.OptimResult`), :class:`PontryaginGuess`, :func:`nominal_guess`, :func:`replay_reference`;
the state–costate system is in :mod:`.planar_system`, the Newton iteration in :mod:`.newton`,
batches in :mod:`.batch` (:func:`~.batch.solve_many`), the command line in
:mod:`.cli`. The closed-loop re-planning expert built on them is
:class:`guidance.laws.pontryagin_planar.PontryaginExpert`.

>>> from lunar_env import get_scenario
>>> sol = solve_planar_min_fuel(get_scenario("zhu2007"))   # doctest: +SKIP
>>> round(sol.fuel_kg, 3), round(sol.tf_s, 3)               # doctest: +SKIP
(277.585, 604.519)
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from lunar_env import dynamics as dyn
from lunar_env.scenarios import PlanarScenario

from ..common.result import OptimResult, Trajectory
from ..problems.planar_ocp import PlanarOCP, as_planar_ocp
from ..transcription.collocation import solve_planar_min_time_collocation
from .newton import damped_newton
from .planar_system import N_STATE, hamiltonian, optimal_thrust_angle, system_for

__all__ = [
    "PontryaginGuess", "PontryaginSolution", "solve_planar_min_fuel", "nominal_guess",
    "replay_reference", "release_solvers",
]

_CHECKS = ("reference", "doubling", "grid")


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
class PontryaginSolution(OptimResult):
    """:class:`~optimizers.common.result.OptimResult` of :func:`solve_planar_min_fuel`, with the
    extremal's costates and interpolants.

    The common fields mean what they mean for every solver: ``x`` the shooting unknowns
    (λ_r, λ_v, λ_ω, λ_m at t0, tf_nd); ``fuel_kg`` ṁ·tf; ``tf_s``; ``terminal_errors`` the
    absolute SI errors ``radius_m``, ``radial_velocity_m_s``, ``tangential_velocity_m_s``,
    ``speed_m_s`` measured by ``check``; ``history`` the fuel (kg) of every accepted Newton
    iterate; ``n_fevals`` integrations of the state–costate system on the fine grid;
    ``n_iter`` Newton iterations (all stages); ``success`` converged *and* the problem's verdict
    (terminal errors within :attr:`PlanarOCP.tolerances`, enough propellant, above ground).

    Attributes
    ----------
    costates0 : ndarray, shape (5,)
        Initial costates (λ_r, λ_v, λ_θ, λ_ω, λ_m), conjugate to the normalised state,
        λ0 = 1 (J = tf in units of ``scaling.time_s``); λ_θ = 0.
    guess : PontryaginGuess
        Warm start for a neighbouring problem.
    check : str
        How ``terminal_errors`` were measured ("reference", "doubling" or "grid").
    residual_nd : float
        Final shooting residual (∞-norm, normalised).
    final_mass_kg : float
    x0_nd : ndarray, shape (5,)
        Normalised initial state.
    history_residual : ndarray
        Residual ∞-norm per accepted Newton iterate.
    ocp : PlanarOCP
        The problem solved.
    n_steps : int
        RK4 steps of the fine grid.
    """

    costates0: np.ndarray = field(default_factory=lambda: np.zeros(5))
    guess: PontryaginGuess | None = None
    check: str = "grid"
    residual_nd: float = math.nan
    final_mass_kg: float = math.nan
    x0_nd: np.ndarray = field(default_factory=lambda: np.zeros(5))
    history_residual: np.ndarray = field(default_factory=lambda: np.zeros(0))
    ocp: PlanarOCP | None = field(default=None, repr=False)
    n_steps: int = 400
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def scenario(self) -> PlanarScenario:
        return self.ocp.scenario

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
            sysm = system_for(self.ocp.params)
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
        return self._interp(self.ocp.scaling.time_nd(np.atleast_1d(t_s)))

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

    def sample(self, n: int = 201) -> Trajectory:
        """The optimal trajectory at ``n`` equally spaced times, SI.

        States: ``radius_m``, ``altitude_m`` (above the scenario's surface),
        ``radial_velocity_m_s``, ``theta_rad``, ``angular_rate_rad_s``,
        ``tangential_velocity_m_s``, ``mass_kg``; controls ``phi_rad`` and ``throttle``
        (always 1); also ``hamiltonian`` (normalised, ≈ 0) among the states.
        """
        n = int(n)
        if n < 2:
            raise ValueError(f"n = {n} must be >= 2")
        sc = self.ocp.scaling
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
            "hamiltonian": hamiltonian(self.ocp.params, x, lam, phi),
        }
        return Trajectory(t_s=t_s, states=states,
                          controls={"phi_rad": phi, "throttle": np.ones(n)})

    def control_at(self, t_s: float) -> np.ndarray:
        """(φ*(t), throttle 1) of the extremal at ``t_s`` seconds (clipped to [0, tf])."""
        return np.array([float(self.thrust_angle_at(float(t_s))), 1.0])

    def as_result(self, n_trajectory: int = 201) -> PontryaginSolution:
        """This result with ``trajectory`` sampled at ``n_trajectory`` times."""
        return dataclasses.replace(self, trajectory=self.sample(n_trajectory),
                                   extra={**self.extra, "costates0": self.costates0.copy()})


_NOMINAL_GUESS: dict[tuple, PontryaginGuess] = {}


def nominal_guess(problem: PlanarOCP | PlanarScenario | str, n_steps: int = 400
                  ) -> PontryaginGuess:
    """Warm start from the optimum from the scenario's nominal initial state (solved once per
    process, cached).

    Raises
    ------
    RuntimeError
        If the nominal problem itself has no solution.
    """
    scenario = as_planar_ocp(problem).scenario
    key = (scenario, int(n_steps))
    if key not in _NOMINAL_GUESS:
        sol = solve_planar_min_fuel(scenario, n_steps=n_steps, check="grid")
        if not sol.success:
            raise RuntimeError(f"{scenario.name}: the nominal Pontryagin problem did not solve: "
                               f"{sol.message}")
        _NOMINAL_GUESS[key] = sol.guess
    return _NOMINAL_GUESS[key]


class _Solver:
    """Shooting for one problem family (vehicle, target) and grid: holds the CasADi functions.
    The initial state is a run-time argument, so one solver serves every initial state."""

    def __init__(self, ocp: PlanarOCP, n_steps: int, n_jac_steps: int) -> None:
        self.params = ocp.params
        self.system = system_for(self.params)
        self.n_steps = n_steps
        self.n_jac_steps = n_jac_steps
        self.fine = self.system.shooting(n_steps, with_jacobian=False)
        self.coarse = self.system.shooting(n_jac_steps, with_jacobian=True)
        self.tgt = ocp.target_nd
        self.n_fine_evals = 0

    def run(self, p0, x0, *, tol, max_iter, history, iterates):
        """Newton from ``p0``; returns (p, ‖res‖∞, converged, iterations, Z grid of p)."""
        grids: dict[bytes, np.ndarray] = {}

        def res_fine(p):
            self.n_fine_evals += 1
            res, z = self.fine(p, x0, self.tgt)
            grids.clear()
            grids[p.tobytes()] = z
            return np.asarray(res).ravel()

        def jac(p):
            return np.asarray(self.coarse(p, x0, self.tgt)[1])

        p, nrm, ok, it = damped_newton(res_fine, jac, np.asarray(p0, dtype=np.float64),
                                       tol=tol, max_iter=max_iter, history=history,
                                       iterates=iterates)
        z = grids.get(p.tobytes())
        if z is None:
            z = self.fine(p, x0, self.tgt)[1]
        return p, nrm, ok, it, np.asarray(z)


_SOLVERS: dict[tuple, _Solver] = {}


def release_solvers() -> None:
    """Drop the process's cached shooting functions (each set of vehicle parameters holds a
    few MB of CasADi functions): for callers that solve many different plants once each, such
    as a campaign's omniscient optima, whose caches would otherwise grow without bound."""
    from . import planar_system

    _SOLVERS.clear()
    planar_system._SYSTEMS.clear()


def _solver(ocp: PlanarOCP, n_steps: int, n_jac_steps: int) -> _Solver:
    key = (ocp.scenario, n_steps, n_jac_steps)
    if key not in _SOLVERS:
        _SOLVERS[key] = _Solver(ocp, n_steps, n_jac_steps)
    return _SOLVERS[key]


def _collocation_guess(ocp: PlanarOCP, x0_nd, n_intervals: int) -> PontryaginGuess | None:
    col = solve_planar_min_time_collocation(ocp, n_intervals=n_intervals, tol=1e-8)
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
    problem: PlanarOCP | PlanarScenario | str,
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
    problem : PlanarOCP, PlanarScenario or scenario name
        The problem (:class:`~optimizers.problems.planar_ocp.PlanarOCP`); a scenario is made
        into one. E.g. ``get_scenario("zhu2007")``.
    initial_state_si : array_like, shape (5,), optional
        (r m, vr m/s, θ rad, v_t m/s, m kg); default the problem's initial state.
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
        ``problem`` is not planar, or ``guess`` has the wrong type.
    ValueError
        ``initial_state_si`` has the wrong shape or non-finite values, a non-positive radius
        or a mass at or below the dry mass; bad ``n_steps``, ``tol``, ``check``.
    """
    t_start = time.perf_counter()
    ocp = as_planar_ocp(problem, initial_state_si)
    x0 = ocp.x0_nd
    n_steps = int(n_steps)
    n_jac_steps = int(n_jac_steps)
    if n_steps < 4 or n_jac_steps < 4:
        raise ValueError(f"n_steps = {n_steps} and n_jac_steps = {n_jac_steps} must be >= 4")
    if not (math.isfinite(tol) and tol > 0):
        raise ValueError(f"tol = {tol!r} must be finite and > 0")
    if check not in _CHECKS:
        raise ValueError(f"check = {check!r} is not one of {_CHECKS}")
    g = _as_guess(guess)
    solver = _solver(ocp, n_steps, n_jac_steps)
    at_target, _ = ocp.success_from(ocp.terminal_errors(x0))
    if at_target:  # tf = 0 is the degenerate optimum: no extremal to shoot for
        return _finish(ocp, solver, np.array([0.0, 0.0, 0.0, 0.0, 0.0]), math.inf, False,
                       ["none: the initial state already meets the terminal conditions"], [],
                       [], 0, 0, check, tol, t_start, None)
    n_evals0 = solver.n_fine_evals
    history: list[float] = []
    iterates: list[np.ndarray] = []
    n_iter = 0
    attempts: list[str] = []

    grid: list[np.ndarray] = []

    def attempt(p0, x_start):
        nonlocal n_iter
        p, nrm, ok, it, z = solver.run(p0, x_start, tol=tol, max_iter=max_iter, history=history,
                                       iterates=iterates)
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
            cg = _collocation_guess(ocp, x0, n_int)
            if cg is None:
                continue
            attempts.append(f"collocation({n_int})")
            p, nrm, ok = attempt(cg.unknowns(), x0)
            if ok:
                break
    if p is None:
        p = np.array([0.0, 0.0, 1.0, 0.0, ocp.rocket_equation_tf_nd()])
    if not grid or attempts[-1] == "continuation" and not ok:
        grid[:] = []  # the last grid belongs to an intermediate state of the continuation
    return _finish(ocp, solver, p, nrm, ok, attempts, history, iterates, n_iter,
                   solver.n_fine_evals - n_evals0, check, tol, t_start, grid[0] if grid else None)


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


def _finish(ocp: PlanarOCP, solver: _Solver, p, nrm, ok, attempts, history, iterates, n_iter,
            n_fevals, check, tol, t_start, z_grid) -> PontryaginSolution:
    sc = ocp.scaling
    x0 = ocp.x0_nd
    lam0 = np.array([p[0], p[1], 0.0, p[2], p[3]])
    tf_nd = float(p[4])
    fuel_kg = ocp.fuel_kg(tf_nd)
    final_mass_kg = float(x0[dyn.M] * sc.mass_kg - fuel_kg)
    how = " -> ".join(attempts) if attempts else "none"
    converged = bool(ok) and tf_nd > 0 and math.isfinite(tf_nd)
    sol = PontryaginSolution(
        x=np.asarray(p, dtype=np.float64).copy(), fuel_kg=fuel_kg, tf_s=tf_nd * sc.time_s,
        terminal_errors={}, history=np.array([ocp.fuel_kg(q[-1]) for q in iterates]),
        n_fevals=int(n_fevals), wall_s=0.0, success=False, message="", n_iter=int(n_iter),
        fun=fuel_kg, algorithm="Pontryagin shooting (damped Newton)", problem=repr(ocp),
        costates0=lam0, guess=PontryaginGuess(lam0, tf_nd, np.asarray(x0, float).copy()),
        check=check, residual_nd=float(nrm), final_mass_kg=final_mass_kg,
        x0_nd=np.asarray(x0, float).copy(), history_residual=np.asarray(history), ocp=ocp,
        n_steps=solver.n_steps)
    if z_grid is not None:
        sol._cache["z"] = z_grid
    if not converged:
        # errors of the last iterate of *this* initial state when it is a real trajectory
        # (tf > 0), else unknown: a failed solve has no terminal accuracy to report
        real = z_grid is not None and math.isfinite(tf_nd) and tf_nd > 1e-9
        sol.terminal_errors = (ocp.terminal_errors(z_grid[:5, -1]) if real
                               else {k: math.nan for k in _ERROR_KEYS})
        sol.message = (f"shooting did not converge ({how}); best residual {nrm:.2e} "
                       f"(tol {tol:.0e})")
        sol.wall_s = time.perf_counter() - t_start
        return sol
    z = sol._cache["z"] if z_grid is not None else sol._grid()["z"]
    r_min_m = float(np.min(z[dyn.R])) * sc.length_m
    sol.terminal_errors = _terminal_errors(sol, solver, check)
    verdict, why = ocp.success_from(sol.terminal_errors, {
        "final_mass_kg": final_mass_kg,
        "min_altitude_m": r_min_m - ocp.scenario.surface_radius_m})
    sol.success = bool(verdict)
    sol.feasible = bool(verdict)
    sol.message = (f"converged ({how}), residual {nrm:.2e}; {why}" if verdict else
                   f"extremal found ({how}) but it {why}")
    sol.wall_s = time.perf_counter() - t_start
    return sol


_ERROR_KEYS = ("radius_m", "radial_velocity_m_s", "tangential_velocity_m_s", "speed_m_s")


def _terminal_errors(sol: PontryaginSolution, solver: _Solver, check: str) -> dict[str, float]:
    p = sol.guess.unknowns()
    if check == "grid":
        xf = sol._cache["z"][:5, -1] if "z" in sol._cache else sol._grid()["z"][:5, -1]
    elif check == "doubling":
        xf = np.asarray(solver.system.grid(2 * solver.n_steps)(p, sol.x0_nd))[:5, -1]
    else:
        xf = replay_reference(sol)
    return sol.ocp.terminal_errors(xf)


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
    rows = [dyn.R, N_STATE + dyn.VR, N_STATE + dyn.OMEGA]
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
                              sol.ocp.params, rtol=rtol, atol=atol)
    return out.y[:, -1]
