"""Gauss pseudospectral method (Legendre–Gauss collocation), as [001] §2.1 states it.

[001] Peng, Li, Shen, Tang 2012, eq. (14)–(17), after Benson / Huntington's GPM:

- time t ∈ [t0, tf] maps to τ ∈ [−1, 1], t = t0 + (tf − t0)(τ + 1)/2; tf is a decision variable;
- states X_0 at τ0 = −1 and X_1..X_N at the N Legendre–Gauss (LG) points τ_1..τ_N (roots of
  P_N), plus the terminal state X_f; controls U_1..U_N at the LG points only;
- collocation (eq. 14): R_k = Σ_{i=0..N} D_ki X_i − (tf − t0)/2 · f(X_k, U_k) = 0, k = 1..N,
  with D ∈ R^{N×(N+1)} the derivative at τ_k of the Lagrange basis on (τ0, τ_1..τ_N);
- terminal state by Gauss quadrature (eq. 15): X_f = X_0 + (tf − t0)/2 Σ_k w_k f(X_k, U_k);
- boundary conditions φ(X_0, X_f) = 0 (eq. 16) and path constraints C(X_k, U_k) ≤ 0 at the LG
  points (eq. 17).

The NLP is solved by IPOPT through CasADi with exact first and second derivatives (the paper
used SQP). The paper's serial strategy is **feasible first** (§3 (1)): "first turn the equality
constraints into the objective, ignoring the real performance index, to get a feasible
solution; then solve the original problem from it". Phase 1 here minimises the sum of squares
of all equality residuals (collocation, quadrature, boundary) subject to the bounds and path
inequalities; phase 2 minimises the true objective from the phase-1 point.

Problem: an :class:`optimizers.common.ocp.OCP` (e.g. :class:`optimizers.problems.pinpoint.
PinpointOCP`); the transcription uses:

- ``n_state``, ``n_control``: int;
- ``rhs(x, u)``: CasADi right-hand side (from the shared dynamics core);
- ``initial_state``: ndarray (n_state,), fixed X_0 (an NLP parameter, so it can change without
  rebuilding);
- ``terminal_residual(xf)``: CasADi vector, = 0 at the end;
- ``path_constraints(x, u)``: (expr, lower (m,), upper (m,)) or None;
- ``control_lower``, ``control_upper``: ndarray (n_control,);
- ``state_bounds()``: (lower, upper), each (n_state,);
- ``tf_bounds_nd``: (float, float);
- ``objective(xf, tf)``: CasADi scalar to minimise (Mayer form).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..common.casadi_tools import casadi as _casadi
from ..common.casadi_tools import ipopt_options, nlp_counts
from ..common.quadrature import (
    gauss_differentiation_matrix,
    legendre_gauss,
)
from ..common.result import OptimResult

__all__ = ["GaussPseudospectral", "GPMGuess", "GPMSolution"]


@dataclass
class GPMGuess:
    """Initial guess on any time grid; interpolated onto the LG points.

    Attributes
    ----------
    tf_nd : float
    t_nd : ndarray, shape (n,)
        Increasing times in [0, tf] at which ``states`` and ``controls`` are given.
    states : ndarray, shape (n, n_state)
    controls : ndarray, shape (n, n_control)
    """

    tf_nd: float
    t_nd: np.ndarray
    states: np.ndarray
    controls: np.ndarray


@dataclass
class GPMSolution(OptimResult):
    """:class:`~optimizers.common.result.OptimResult` of a GPM transcription, with its arrays.

    ``x`` is the NLP's decision vector; ``fuel_kg``/``tf_s`` from the problem;
    ``terminal_errors`` those of the quadrature final state X_f; ``history`` the fuel (kg) per
    IPOPT iteration of the last phase; ``n_fevals``/``n_iter`` objective evaluations and
    iterations summed over the phases; ``success`` IPOPT's convergence and the problem's
    verdict.

    Attributes
    ----------
    tf_nd : float
    tau : ndarray, shape (N,)
        LG points.
    t_nd : ndarray, shape (N + 2,)
        Times of ``states``: t0, the N LG points, tf.
    states : ndarray, shape (N + 2, n_state)
        X_0, X_1..X_N, X_f.
    controls : ndarray, shape (N, n_control)
        U_1..U_N at the LG points.
    phases : list of dict
        Per phase: ``name``, ``status``, ``success``, ``iterations``, ``wall_s``,
        ``objective``, ``max_eq_residual``.
    max_eq_residual : float
    """

    tf_nd: float = float("nan")
    tau: np.ndarray = field(default_factory=lambda: np.zeros(0))
    t_nd: np.ndarray = field(default_factory=lambda: np.zeros(0))
    states: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    controls: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    phases: list = field(default_factory=list)
    max_eq_residual: float = float("nan")

    @property
    def t_lg_nd(self) -> np.ndarray:
        """Times of the controls (the LG points), shape (N,)."""
        return self.t_nd[1:-1]


class GaussPseudospectral:
    """Legendre–Gauss pseudospectral transcription with free final time ([001] §2.1).

    Parameters
    ----------
    n_nodes : int
        Number N of LG points; [001] uses N = 6 as its initial-guess generator.
    feasible_first : bool
        Run the feasibility phase (min Σ residual²) before the optimality phase ([001] §3).
    tol : float
        IPOPT tolerance (normalised units: 1e-10 of the lunar radius is 0.17 mm).
    max_iter : int
        IPOPT iteration limit per phase.
    max_wall_s : float, optional
        IPOPT wall-time limit per phase.
    verbose : bool
        Show IPOPT's output.

    Notes
    -----
    The NLP is built once per problem object and reused (the initial state is a parameter);
    repeated solves from other guesses pay only for IPOPT.
    """

    def __init__(self, n_nodes: int = 6, *, feasible_first: bool = True, tol: float = 1e-10,
                 max_iter: int = 500, max_wall_s: float | None = None,
                 verbose: bool = False) -> None:
        self.n_nodes = int(n_nodes)
        if self.n_nodes < 1:
            raise ValueError(f"n_nodes = {n_nodes!r} must be >= 1")
        self.feasible_first = bool(feasible_first)
        self.tol = float(tol)
        self.max_iter = int(max_iter)
        self.max_wall_s = max_wall_s
        self.verbose = bool(verbose)
        self.tau, self.weights = legendre_gauss(self.n_nodes)
        self.D = gauss_differentiation_matrix(self.n_nodes)
        self._cache: dict[int, dict] = {}

    def __repr__(self) -> str:
        return (f"GaussPseudospectral(n_nodes={self.n_nodes}, "
                f"feasible_first={self.feasible_first})")

    # ---- NLP construction ------------------------------------------------------------------
    def _build(self, ocp) -> dict:
        key = id(ocp)
        if key in self._cache and self._cache[key]["ocp"] is ocp:
            return self._cache[key]
        ca = _casadi()
        n, nx, nu = self.n_nodes, ocp.n_state, ocp.n_control
        X = ca.SX.sym("X", nx, n + 1)   # X_0..X_N (columns)
        Xf = ca.SX.sym("Xf", nx)
        U = ca.SX.sym("U", nu, n)
        tf = ca.SX.sym("tf")
        x0 = ca.SX.sym("x0", nx)
        half = tf / 2.0  # t0 = 0
        F = ca.horzcat(*[ocp.rhs(X[:, k + 1], U[:, k]) for k in range(n)])  # (nx, n)
        # eq. (14): D (N×(N+1)) times the state rows
        colloc = ca.mtimes(X, ca.DM(self.D.T)) - half * F            # (nx, n)
        quad = Xf - X[:, 0] - half * ca.mtimes(F, ca.DM(self.weights))  # eq. (15)
        term = ocp.terminal_residual(Xf)
        # X_0 = x0 is imposed through equal bounds at solve time (IPOPT then treats X_0 as
        # fixed); x0 stays an (unused) NLP parameter so the solve signature is uniform.
        eq = ca.vertcat(ca.vec(colloc), quad, term)
        ineq_parts, ineq_lo, ineq_hi = [], [], []
        for k in range(n):
            pc = ocp.path_constraints(X[:, k + 1], U[:, k])
            if pc is not None:
                expr, lo, hi = pc
                ineq_parts.append(expr)
                ineq_lo.append(np.asarray(lo, float))
                ineq_hi.append(np.asarray(hi, float))
        ineq = ca.vertcat(*ineq_parts) if ineq_parts else ca.SX(0, 1)
        z = ca.vertcat(ca.vec(X), Xf, ca.vec(U), tf)
        n_eq = eq.shape[0]
        n_in = ineq.shape[0]

        slo, shi = ocp.state_bounds()
        lbz = np.concatenate([np.tile(slo, n + 1), slo, np.tile(ocp.control_lower, n),
                              [ocp.tf_bounds_nd[0]]])
        ubz = np.concatenate([np.tile(shi, n + 1), shi, np.tile(ocp.control_upper, n),
                              [ocp.tf_bounds_nd[1]]])
        g_lo = np.concatenate([np.zeros(n_eq)] + ineq_lo) if n_in else np.zeros(n_eq)
        g_hi = np.concatenate([np.zeros(n_eq)] + ineq_hi) if n_in else np.zeros(n_eq)

        opts = ipopt_options(verbose=self.verbose, tol=self.tol, max_iter=self.max_iter,
                             max_wall_s=self.max_wall_s)
        obj = ocp.objective(Xf, tf)
        solver_opt = ca.nlpsol("gpm_opt", "ipopt",
                               {"x": z, "p": x0, "f": obj, "g": ca.vertcat(eq, ineq)}, opts)
        # Phase 1 ([001] §3: the equality constraints become the objective): the exact L1
        # penalty in elastic form, min Σ(s⁺ + s⁻) s.t. eq(z) = s⁺ − s⁻, s± ≥ 0, plus the path
        # inequalities. Unlike Σ eq², its minimum (zero) is non-degenerate for IPOPT.
        s_pos = ca.SX.sym("s_pos", n_eq)
        s_neg = ca.SX.sym("s_neg", n_eq)
        feas_opts = dict(opts)
        solver_feas = ca.nlpsol(
            "gpm_feas", "ipopt",
            {"x": ca.vertcat(z, s_pos, s_neg), "p": x0, "f": ca.sum1(s_pos + s_neg),
             "g": ca.vertcat(eq - s_pos + s_neg, ineq)}, feas_opts)
        eq_fn = ca.Function("gpm_eq", [z, x0], [eq])
        built = dict(ocp=ocp, opt=solver_opt, feas=solver_feas, eq=eq_fn, lbz=lbz, ubz=ubz,
                     g_lo=g_lo, g_hi=g_hi, n_eq=n_eq, n_in=n_in, nx=nx, nu=nu,
                     ineq_lo=(np.concatenate(ineq_lo) if n_in else np.zeros(0)),
                     ineq_hi=(np.concatenate(ineq_hi) if n_in else np.zeros(0)))
        self._cache[key] = built
        return built

    # ---- packing ---------------------------------------------------------------------------
    def _guess_vector(self, guess: GPMGuess, nx: int, nu: int) -> np.ndarray:
        tf = float(guess.tf_nd)
        t_nodes = tf * (np.concatenate([[-1.0], self.tau]) + 1.0) / 2.0
        tg = np.asarray(guess.t_nd, float)
        sg = np.asarray(guess.states, float)
        ug = np.asarray(guess.controls, float)
        if sg.shape != (len(tg), nx) or ug.shape != (len(tg), nu):
            raise ValueError(f"guess shapes t {tg.shape}, states {sg.shape}, controls "
                             f"{ug.shape}; expected (n,), (n, {nx}), (n, {nu})")
        Xg = np.stack([np.interp(t_nodes, tg, sg[:, j]) for j in range(nx)], axis=0)
        Xf = np.array([np.interp(tf, tg, sg[:, j]) for j in range(nx)])
        t_lg = t_nodes[1:]
        Ug = np.stack([np.interp(t_lg, tg, ug[:, j]) for j in range(nu)], axis=0)
        return np.concatenate([Xg.T.ravel(), Xf, Ug.T.ravel(), [tf]])

    def _unpack(self, z: np.ndarray, nx: int, nu: int):
        n = self.n_nodes
        i = 0
        X = z[i:i + nx * (n + 1)].reshape(n + 1, nx)
        i += nx * (n + 1)
        Xf = z[i:i + nx]
        i += nx
        U = z[i:i + nu * n].reshape(n, nu)
        i += nu * n
        return X, Xf, U, float(z[i])

    # ---- solve -----------------------------------------------------------------------------
    def solve(self, ocp, guess: GPMGuess, *, initial_state: np.ndarray | None = None
              ) -> GPMSolution:
        """Solve the transcription from ``guess`` (feasible first if configured).

        Parameters
        ----------
        ocp : problem following the protocol in the module docstring
        guess : GPMGuess
        initial_state : ndarray, shape (n_state,), optional
            Overrides ``ocp.initial_state``.

        Returns
        -------
        GPMSolution
            ``success`` False (with IPOPT's status in ``message``) if it did not converge.
        """
        t_start = time.perf_counter()
        b = self._build(ocp)
        nx, nu = b["nx"], b["nu"]
        x0 = np.asarray(ocp.initial_state if initial_state is None else initial_state, float)
        if x0.shape != (nx,) or not np.all(np.isfinite(x0)):
            raise ValueError(f"initial_state must be finite with shape ({nx},), got {x0!r}")
        lbz = b["lbz"].copy()
        ubz = b["ubz"].copy()
        lbz[:nx] = x0
        ubz[:nx] = x0
        z = np.clip(self._guess_vector(guess, nx, nu), lbz, ubz)
        phases = []
        if self.feasible_first:
            tp = time.perf_counter()
            r0 = np.asarray(b["eq"](z, x0)).ravel()
            n_eq = b["n_eq"]
            ze = np.concatenate([z, np.maximum(r0, 0.0), np.maximum(-r0, 0.0)])
            sol = b["feas"](x0=ze, p=x0, lbx=np.concatenate([lbz, np.zeros(2 * n_eq)]),
                            ubx=np.concatenate([ubz, np.full(2 * n_eq, np.inf)]),
                            lbg=np.concatenate([np.zeros(n_eq), b["ineq_lo"]]),
                            ubg=np.concatenate([np.zeros(n_eq), b["ineq_hi"]]))
            st = b["feas"].stats()
            z = np.asarray(sol["x"]).ravel()[:len(lbz)]
            phases.append(dict(name="feasibility", status=st["return_status"],
                               success=bool(st["success"]), iterations=int(st["iter_count"]),
                               wall_s=time.perf_counter() - tp, objective=float(sol["f"]),
                               max_eq_residual=float(np.max(np.abs(b["eq"](z, x0))))))
        tp = time.perf_counter()
        sol = b["opt"](x0=z, p=x0, lbx=lbz, ubx=ubz, lbg=b["g_lo"], ubg=b["g_hi"])
        st = b["opt"].stats()
        z = np.asarray(sol["x"]).ravel()
        eq_res = float(np.max(np.abs(b["eq"](z, x0))))
        phases.append(dict(name="optimality", status=st["return_status"],
                           success=bool(st["success"]), iterations=int(st["iter_count"]),
                           wall_s=time.perf_counter() - tp, objective=float(sol["f"]),
                           max_eq_residual=eq_res))
        X, Xf, U, tf = self._unpack(z, nx, nu)
        t_nodes = tf * (np.concatenate([[-1.0], self.tau, [1.0]]) + 1.0) / 2.0
        n_f = sum(nlp_counts(b[k])[0] for k in (("feas", "opt") if self.feasible_first
                                                 else ("opt",)))
        converged = bool(st["success"])
        errors = ocp.terminal_errors(Xf)
        states = np.vstack([X, Xf])
        verdict, why = ocp.success_from(errors, ocp.path_quantities(states))
        fuel = ocp.fuel_kg(tf)
        history = [ocp.fuel_kg(v) for v in st.get("iterations", {}).get("obj", [])]
        return GPMSolution(
            x=z, fuel_kg=fuel, tf_s=tf * ocp.scaling.time_s, terminal_errors=errors,
            history=np.asarray(history or [fuel]), n_fevals=n_f,
            n_iter=sum(p["iterations"] for p in phases), wall_s=time.perf_counter() - t_start,
            success=converged and bool(verdict), message=f"IPOPT: {st['return_status']}; {why}",
            fun=fuel, algorithm=repr(self), problem=repr(ocp),
            tf_nd=tf, tau=self.tau.copy(), t_nd=t_nodes, states=states, controls=U,
            phases=phases, max_eq_residual=eq_res)
