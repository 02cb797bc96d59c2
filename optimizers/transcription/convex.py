"""Successive convexification (SCvx) of the minimum-fuel landing, solved as SOCPs with cvxpy.

References
----------
- [SCvx] Mao, Szmuk & Açıkmeşe, "Successive convexification of non-convex optimal control
  problems and its convergence properties", IEEE CDC 2016: linearise about the previous
  iterate, add *virtual control* ν (penalised with its 1-norm) so that every subproblem is
  feasible, bound the step by a *trust region* whose radius follows the ratio ρ of the actual
  to the predicted decrease of the penalised cost (accept ρ ≥ ρ₀, shrink below ρ₁, grow above
  ρ₂).
- [Szmuk] Szmuk & Açıkmeşe, "Successive convexification for 6-DoF Mars rocket powered landing
  with free-final-time", AIAA SciTech 2018: the free final time as a scaled variable σ = tf
  (dynamics dx/dτ = σ f(x, u) on τ ∈ [0, 1]) that is linearised with the rest; exact
  discretisation of the linearised system over each interval of a held control.
- [LCvx] Açıkmeşe & Ploen, "Convex programming approach to powered descent guidance for Mars
  landing", JGCD 30(5), 2007: the thrust-magnitude constraint ρ₁ ≤ |T| ≤ ρ₂ is relaxed with a
  slack Γ, |T| ≤ Γ, and the mass flow is driven by Γ; at the optimum |T| = Γ (lossless).
- [Reynolds] Reynolds, Malyuk, Mammarella, Açıkmeşe, "Real-time algorithms for
  powered-descent guidance", JGCD 43(2), 2020: the ~100 ms per re-plan figure this solver is
  measured against.

What is solved
--------------
The problem is an :class:`~optimizers.common.ocp.OCP` of the project — the planar landing
(:class:`~optimizers.problems.planar_ocp.PlanarOCP`, [000]) or the 3D pinpoint landing on the
rotating Moon (:class:`~optimizers.problems.pinpoint.PinpointOCP`, [001]) — with their own
initial state, terminal residual, path constraints and verdict. The papers' engine burns at
constant thrust and is steered only, a *nonconvex* control set (|u| = 1). Following [LCvx] the
solver flies the **throttled** engine instead:

    w ∈ R^d (throttle-scaled thrust direction: (up, brake) planar, (radial, along-track,
    cross-track) of the orbital frame in 3D),   ‖w‖₂ ≤ Γ ≤ 1,   ṁ = −F Γ / c,

which are exactly the *control halves* of the shared equations of motion
(:func:`lunar_env.dynamics.planar_eom_terms` and :func:`~lunar_env.dynamics.moon3d_eom_terms`
take ``(up, brake, throttle)`` and ``(e_r, e_t, e_n, throttle)``), so no equation is re-typed:
the discretisation evaluates those functions on CasADi symbols. For a minimum-fuel landing the
relaxed optimum has ‖w‖ = Γ (the relaxation is tight) and is bang-bang; the result reports
``extra["tightness"]`` = min over burning intervals of ‖w‖/Γ and ``extra["min_throttle"]``,
and the replayed control is the physical one, direction w/‖w‖ at throttle Γ. Minimum fuel is
maximum final mass, a linear objective. Two engines (``engine=``):

- ``"constant"`` (default, the papers' vehicle): Γ = 1, the direction relaxed to ‖w‖ ≤ 1;
  minimum fuel is minimum time. Measured tight (‖w‖ ≥ 1 − 1e-7) on zhu2007 and peng2012.
- ``"throttled"``: Γ ∈ [0, 1]. Measured bang-bang: zhu2007 burns at full thrust throughout
  (the same optimum), while peng2012 coasts about 19 s before a full-thrust burn (Γ = 0.023
  on the first of 29 intervals, i.e. the switch inside it) and saves 1.8 % of the
  constant-thrust optimum's fuel: the throttled problem is a different, cheaper problem.

Transcription
-------------
- K nodes τ_k = k/(K − 1); the control (w, Γ) is held over each of the K − 1 intervals (zero
  order hold: the replayed law is piecewise constant, exactly what the envs fly between
  decisions); the states at the K nodes are variables (multiple shooting).
- Exact discretisation of the linearisation: x_{k+1} = F(x_k, u_k, σ) where F is ``n_rk4``
  classical RK4 steps of σ f over the interval (the integrator the papers use), and the
  linearised dynamics are the Jacobians of F by CasADi's algorithmic differentiation,
  x_{k+1} = A_k x_k + B_k u_k + S_k σ + z_k + ν_k. The DOP853 replay meets the problem's
  tolerances (tested).
- Terminal conditions: the OCP's residual linearised exactly (hard equality). State path
  constraints (3D: |u|, |w| bounds and the surface; planar: the surface) linearised at every
  node with a penalised slack; mass bounds and the control set are convex as they stand (the
  3D elevation/azimuth bounds of [001] are half-spaces in (w, Γ)).
- The cvxpy problem is built **once** per solver and problem type; linearisation matrices,
  reference trajectory, trust-region radius and the initial state are ``cp.Parameter`` s
  (DPP), so every iteration and every re-plan only updates parameters and re-solves (Clarabel).

Decisions where the papers are silent
-------------------------------------
- Trust region: a box ‖x_k − x̄_k‖∞, ‖u_k − ū_k‖∞, |σ − σ̄| ≤ η (linear, keeps the problem a
  small SOCP); initial η = ``trust_region``; ratio thresholds (ρ₀, ρ₁, ρ₂) = (0, 0.25, 0.7),
  shrink ÷2, grow ×2 up to ``trust_region_max``.
- Convergence: every interval defect below ``defect_tol`` and either an accepted step whose
  largest change is below ``step_tol`` or a predicted decrease below ``cost_tol`` (θ, the
  planar downrange angle, is free and may wander at the 1e-7 level between optimal solves).
- Cold start: states interpolated between the start and the target (3D: slerp of the position
  direction), braking full-thrust control, tf from the rocket equation.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from lunar_env import dynamics as dyn
from lunar_env.integrators import PiecewisePolynomial

from ..common.casadi_tools import casadi as _casadi
from ..common.casadi_tools import rk4_step
from ..common.result import ControlLaw, OptimResult, Trajectory
from .convex_model import ConvexModel

__all__ = ["SuccessiveConvexification", "ConvexSolution", "ConvexGuess", "solve_convex"]


def _cvxpy():
    try:
        import cvxpy as cp
    except ImportError as exc:  # pragma: no cover  (the extra is part of [test])
        raise ImportError("the SCvx solver needs cvxpy and clarabel: pip install "
                          "'lunar-descent-guidance[convex]'") from exc
    return cp


@dataclass
class ConvexGuess:
    """A reference trajectory on the solver's node grid (e.g. a previous solution shifted).

    Attributes
    ----------
    tf_nd : float
        Final time (normalised), > 0.
    states : ndarray, shape (n_nodes, n_state)
        Node states (normalised).
    controls : ndarray, shape (n_nodes - 1, d + 1)
        Held controls (w, Γ) per interval.
    """

    tf_nd: float
    states: np.ndarray
    controls: np.ndarray

    def shifted(self, elapsed_nd: float, n_nodes: int | None = None) -> ConvexGuess:
        """The same plan ``elapsed_nd`` later: the remaining part resampled on ``n_nodes``
        nodes (state linear between nodes, control held), tf reduced by ``elapsed_nd``.

        Raises
        ------
        ValueError
            ``elapsed_nd`` outside [0, tf).
        """
        if not (math.isfinite(elapsed_nd) and 0.0 <= elapsed_nd < self.tf_nd):
            raise ValueError(f"elapsed_nd = {elapsed_nd!r} must be in [0, tf_nd = "
                             f"{self.tf_nd!r})")
        k = len(self.states) if n_nodes is None else int(n_nodes)
        t_old = np.linspace(0.0, self.tf_nd, len(self.states))
        t_new = elapsed_nd + np.linspace(0.0, self.tf_nd - elapsed_nd, k)
        states = np.stack([np.interp(t_new, t_old, self.states[:, j])
                           for j in range(self.states.shape[1])], axis=1)
        mid = 0.5 * (t_new[:-1] + t_new[1:])
        idx = np.clip(np.searchsorted(t_old, mid, side="right") - 1, 0, len(self.controls) - 1)
        return ConvexGuess(self.tf_nd - elapsed_nd, states, self.controls[idx].copy())


@dataclass
class ConvexSolution(OptimResult):
    """:class:`~optimizers.common.result.OptimResult` of :class:`SuccessiveConvexification`.

    ``x`` packs ``[σ, states.ravel(), controls.ravel()]``; ``fuel_kg``/``tf_s`` from the
    single-shooting propagation of the held controls from the initial state (the discrete
    model F); ``terminal_errors`` the problem's, of that propagation; ``history`` the fuel (kg)
    of each accepted iterate; ``n_iter`` SCvx iterations (convex solves); ``n_fevals``
    evaluations of the discretisation (propagation + Jacobians of all intervals);
    ``success`` SCvx converged and the problem's verdict holds. ``extra``: ``tightness``,
    ``min_throttle``, ``max_defect_nd``, ``solver_s`` (the solver's own reported
    ``solve_time``, summed; Clarabel 0.11's timer reads above the wall time around the call on
    this machine, so the benchmark times the hand-over itself),
    ``solve_s`` (cvxpy ``solve`` calls, summed), ``linearise_s``, ``build_s`` (the one-off
    problem construction), ``statuses``.

    Attributes
    ----------
    tf_nd : float
    t_nd : ndarray, shape (n_nodes,)
    states : ndarray, shape (n_nodes, n_state)
        The solution's node states (normalised).
    controls : ndarray, shape (n_nodes - 1, d + 1)
        Held (w, Γ) per interval.
    model_controls : ndarray, shape (n_nodes - 1, n_model_control)
        The same as the model's controls: (φ, throttle) planar, (α, β, throttle) 3D.
    """

    tf_nd: float = float("nan")
    t_nd: np.ndarray = field(default_factory=lambda: np.zeros(0))
    states: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    controls: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    model_controls: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    def guess(self) -> ConvexGuess:
        """This solution as a warm start (see :meth:`ConvexGuess.shifted`)."""
        return ConvexGuess(self.tf_nd, self.states.copy(), self.controls.copy())


class SuccessiveConvexification:
    """SCvx minimum-fuel landing with free final time ([SCvx], [Szmuk], [LCvx]).

    Parameters
    ----------
    n_nodes : int
        Temporal nodes K (≥ 2); the control is held over the K − 1 intervals. Default 30.
    n_rk4 : int
        RK4 steps per interval in the discretisation F (≥ 1). Default 4.
    trust_region : float
        Initial trust-region radius η (normalised units, > 0). Default 0.5.
    trust_region_max : float
        Largest radius (≥ ``trust_region``). Default 2.
    virtual_control_weight : float
        λ of the 1-norm penalty on virtual control and path slack (> 0). Default 1e3.
    max_iter : int
        SCvx iterations (convex solves) per call (≥ 1). Default 40.
    step_tol, cost_tol, defect_tol : float
        Convergence (normalised units, > 0): an accepted step smaller than ``step_tol`` or a
        predicted decrease of the penalised cost below ``cost_tol`` (the final mass: 1e-8 is
        6 mg on a 600 kg lander), with every interval defect and path violation below
        ``defect_tol``. Defaults 1e-7, 1e-8 and 1e-9.
    engine : {"constant", "throttled"}
        ``"constant"`` (default): the papers' engine, always at full thrust (Γ = 1, only the
        direction steered; the relaxed set is ‖w‖ ≤ 1 and minimum fuel is minimum time);
        ``"throttled"``: Γ ∈ [0, Γ_max] (the envs' throttle channel, [003]'s engine).
    throttle_max : float
        Γ_max of the throttled engine, in (0, 1]. Default 1. Below 1 the plan keeps a thrust
        margin (e.g. 0.94: three 1σ of a 2 % thrust error) for a re-planning law to spend
        when the engine is weaker than the model; the fuel it costs is the price of that
        margin (measured on zhu2007's planar descent: 0.94 costs +1.77 kg, +0.64 %). Only
        with ``engine="throttled"``.
    solver : str
        cvxpy solver name. Default ``"CLARABEL"``.
    solver_options : dict, optional
        Settings passed to the solver on every solve (default: the solver's defaults).

    Raises
    ------
    ValueError
        A setting outside its range (the message names it and what is allowed).

    Notes
    -----
    One instance builds one cvxpy problem per problem *type* (model, node count) on its first
    :meth:`solve` and re-uses it for every later call on any problem of the same scenario:
    pass the initial state of a re-plan as ``initial_state``. First solve: compilation
    (seconds); later iterations and re-plans: parameter updates only.
    """

    def __init__(self, n_nodes: int = 30, *, n_rk4: int = 4, trust_region: float = 0.5,
                 trust_region_max: float = 2.0, virtual_control_weight: float = 1e3,
                 max_iter: int = 40, step_tol: float = 1e-7, cost_tol: float = 1e-8,
                 defect_tol: float = 1e-9, engine: str = "constant",
                 throttle_max: float = 1.0,
                 solver: str = "CLARABEL", solver_options: dict | None = None) -> None:
        def _int(name, v, lo):
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < lo:
                raise ValueError(f"{name} = {v!r} is not allowed; it must be an integer >= {lo}")
            return int(v)

        def _pos(name, v):
            try:
                f = float(v)
            except (TypeError, ValueError):
                f = math.nan
            if isinstance(v, bool) or not (math.isfinite(f) and f > 0):
                raise ValueError(f"{name} = {v!r} is not allowed; it must be finite and > 0")
            return f

        self.n_nodes = _int("n_nodes", n_nodes, 2)
        self.n_rk4 = _int("n_rk4", n_rk4, 1)
        self.max_iter = _int("max_iter", max_iter, 1)
        self.trust_region = _pos("trust_region", trust_region)
        self.trust_region_max = _pos("trust_region_max", trust_region_max)
        if self.trust_region_max < self.trust_region:
            raise ValueError(f"trust_region_max = {trust_region_max!r} must be >= trust_region "
                             f"= {trust_region!r}")
        self.virtual_control_weight = _pos("virtual_control_weight", virtual_control_weight)
        self.step_tol = _pos("step_tol", step_tol)
        self.cost_tol = _pos("cost_tol", cost_tol)
        self.defect_tol = _pos("defect_tol", defect_tol)
        if engine not in ("constant", "throttled"):
            raise ValueError(f"engine = {engine!r} is not allowed; use 'constant' (the papers' "
                             "full-thrust engine, Γ = 1) or 'throttled' (Γ ∈ [0, 1])")
        self.engine = engine
        self.throttle_max = _pos("throttle_max", throttle_max)
        if self.throttle_max > 1.0:
            raise ValueError(f"throttle_max = {throttle_max!r} is not allowed; it must be in "
                             "(0, 1] (a fraction of the engine's maximum thrust)")
        if engine == "constant" and self.throttle_max != 1.0:
            raise ValueError(f"throttle_max = {throttle_max!r} needs engine='throttled'; the "
                             "constant engine always burns at full thrust")
        if not isinstance(solver, str) or not solver:
            raise ValueError(f"solver = {solver!r} must be a cvxpy solver name, e.g. 'CLARABEL'")
        self.solver = solver.upper()
        if solver_options is not None and not isinstance(solver_options, dict):
            raise ValueError(f"solver_options = {solver_options!r} must be a dict of the "
                             "solver's settings (e.g. {'tol_feas': 1e-7}) or None")
        self.solver_options = dict(solver_options or {})
        self._built: dict = {}

    def __repr__(self) -> str:
        return (f"SuccessiveConvexification(n_nodes={self.n_nodes}, n_rk4={self.n_rk4}, "
                f"trust_region={self.trust_region}, max_iter={self.max_iter})")

    # ---- construction ----------------------------------------------------------------------
    def _key(self, ocp) -> tuple:
        # everything the built problem bakes in: model constants, the scenario (surface, mass
        # floor, tf bound) and the pinpoint path options; the start and the linearisation are
        # parameters
        return (type(ocp).__name__, repr(ocp.params), repr(getattr(ocp, "scenario", None)),
                getattr(ocp, "min_altitude_m", None), getattr(ocp, "floor_margin_m", None),
                getattr(ocp, "floor_margin_range_m", None))

    def _build(self, ocp) -> dict:
        key = self._key(ocp)
        if key in self._built:
            return self._built[key]
        t0 = time.perf_counter()
        cp = _cvxpy()
        ca = _casadi()
        model = ConvexModel(ocp)
        nx, nu, K = model.n_x, model.n_u, self.n_nodes
        nk = K - 1
        # discretisation F over one interval of τ (length 1/(K−1)), σ scaling the rhs
        step = rk4_step(model.rhs, nx, nu)
        xs, us, sg = ca.SX.sym("x", nx), ca.SX.sym("u", nu), ca.SX.sym("s")
        h = sg / (nk * self.n_rk4)
        xe = xs
        for _ in range(self.n_rk4):
            xe = step(xe, us, h)
        fun = ca.Function("F", [xs, us, sg],
                          [xe, ca.jacobian(xe, xs), ca.jacobian(xe, us), ca.jacobian(xe, sg)])
        fmap = fun.map(nk)
        # the same F without derivatives, chained over the intervals (single shooting)
        shoot = ca.Function("F0", [xs, us, sg], [xe]).mapaccum("shoot", nk, [0], [0])

        X = cp.Variable((nx, K), name="x")
        U = cp.Variable((nu, nk), name="u")
        sigma = cp.Variable(name="sigma")
        V = cp.Variable((nx, nk), name="nu")
        P = {
            "x0": cp.Parameter(nx, name="x0"),
            "A": cp.Parameter((nx * nx, nk), name="A"),
            "B": cp.Parameter((nx * nu, nk), name="B"),
            "S": cp.Parameter((nx, nk), name="S"),
            "z": cp.Parameter((nx, nk), name="z"),
            "Xr": cp.Parameter((nx, K), name="Xr"),
            "Ur": cp.Parameter((nu, nk), name="Ur"),
            "sr": cp.Parameter(name="sigma_ref"),
            "eta": cp.Parameter(nonneg=True, name="eta"),
            "G": cp.Parameter((model.n_term, nx), name="G"),
            "g0": cp.Parameter(model.n_term, name="g0"),
            "C": cp.Parameter((model.n_path * nx, K), name="C"),
            "c0": cp.Parameter((model.n_path, K), name="c0"),
        }
        cons = [X[:, 0] == P["x0"]]
        for i in range(nx):
            rhs = P["z"][i, :] + P["S"][i, :] * sigma + V[i, :]
            for j in range(nx):
                rhs = rhs + cp.multiply(P["A"][i * nx + j, :], X[j, :nk])
            for j in range(nu):
                rhs = rhs + cp.multiply(P["B"][i * nu + j, :], U[j, :])
            cons.append(X[i, 1:] == rhs)
        d = model.d
        P["gmin"] = cp.Parameter(nonneg=True, name="throttle_min")
        P["gmax"] = cp.Parameter(nonneg=True, name="throttle_max")
        cons += [cp.norm(U[:d, :], 2, axis=0) <= U[d, :], U[d, :] <= P["gmax"],
                 U[d, :] >= P["gmin"]]
        if len(model.halfspaces):
            cons.append(model.halfspaces @ U <= 0.0)
        cons.append(X[model.mass_index, :] >= model.mass_min)
        cons.append(P["G"] @ X[:, K - 1] + P["g0"] == 0.0)
        slack = cp.Variable((model.n_path, K), nonneg=True, name="path_slack")
        for i in range(model.n_path):
            expr = P["c0"][i, :]
            for j in range(nx):
                expr = expr + cp.multiply(P["C"][i * nx + j, :], X[j, :])
            if np.isfinite(model.path_lo[i]):
                cons.append(expr >= model.path_lo[i] - slack[i, :])
            if np.isfinite(model.path_hi[i]):
                cons.append(expr <= model.path_hi[i] + slack[i, :])
        lo_tf, hi_tf = ocp.tf_bounds_nd
        cons += [sigma >= 1e-3 * hi_tf, sigma <= hi_tf,
                 X - P["Xr"] <= P["eta"], P["Xr"] - X <= P["eta"],
                 U - P["Ur"] <= P["eta"], P["Ur"] - U <= P["eta"],
                 sigma - P["sr"] <= P["eta"], P["sr"] - sigma <= P["eta"]]
        lam = self.virtual_control_weight
        penalty = lam * (cp.sum(cp.abs(V)) + cp.sum(slack))
        objective = cp.Minimize(-X[model.mass_index, K - 1] + penalty)
        prob = cp.Problem(objective, cons)
        assert prob.is_dcp(dpp=True)
        built = {"model": model, "fmap": fmap, "path_map": model.path_fn.map(K),
                 "shoot": shoot, "prob": prob, "X": X, "U": U, "sigma": sigma, "V": V,
                 "slack": slack, "P": P, "build_s": time.perf_counter() - t0}
        self._built[key] = built
        return built

    # ---- numerics --------------------------------------------------------------------------
    def _linearise(self, b: dict, Xr: np.ndarray, Ur: np.ndarray, sr: float) -> dict:
        """Propagate every interval from the reference nodes and take the Jacobians."""
        model = b["model"]
        nx, nu = model.n_x, model.n_u
        nk = self.n_nodes - 1
        xe, ja, jb, js = b["fmap"](Xr[:, :nk], Ur, sr * np.ones((1, nk)))
        xe = np.asarray(xe)
        A = np.asarray(ja).reshape(nx, nk, nx).transpose(0, 2, 1)   # (i, j, k)
        Bm = np.asarray(jb).reshape(nx, nk, nu).transpose(0, 2, 1)
        S = np.asarray(js).reshape(nx, nk)
        z = xe - np.einsum("ijk,jk->ik", A, Xr[:, :nk]) - np.einsum("ijk,jk->ik", Bm, Ur) \
            - S * sr
        defect = Xr[:, 1:] - xe
        g, G = model.term_fn(Xr[:, -1])
        g, G = np.asarray(g).ravel(), np.asarray(G)
        c, C = b["path_map"](Xr)
        cv = np.asarray(c).reshape(model.n_path, self.n_nodes)                 # (q, K)
        Cv = np.asarray(C).reshape(model.n_path, self.n_nodes, nx).transpose(1, 0, 2)
        c0 = cv - np.einsum("kqj,jk->qk", Cv, Xr)
        viol = np.maximum(model.path_lo[:, None] - cv, 0.0) + np.maximum(
            cv - model.path_hi[:, None], 0.0)
        return {"A": A.reshape(nx * nx, nk), "B": Bm.reshape(nx * nu, nk), "S": S, "z": z,
                "G": G, "g0": g - G @ Xr[:, -1], "C": Cv.transpose(1, 2, 0).reshape(-1,
                self.n_nodes), "c0": c0, "defect": defect, "path_viol": viol,
                "term": g}

    def _merit(self, b: dict, Xr: np.ndarray, lin: dict) -> float:
        """Nonlinear penalised cost: −m_f + λ(Σ|defects| + Σ path violations)."""
        m = b["model"]
        return float(-Xr[m.mass_index, -1] + self.virtual_control_weight * (
            np.abs(lin["defect"]).sum() + lin["path_viol"].sum()))

    def cold_guess(self, ocp, initial_state: np.ndarray | None = None) -> ConvexGuess:
        """Straight-line start: states interpolated from the start to the target, full-thrust
        braking, tf from the rocket equation (:class:`PlanarOCP`) or the middle of the tf
        bounds' lower third (3D)."""
        model = ConvexModel(ocp) if not self._built else self._build(ocp)["model"]
        x0 = np.asarray(ocp.initial_state if initial_state is None else initial_state, float)
        K = self.n_nodes
        s = np.linspace(0.0, 1.0, K)
        lo, hi = ocp.tf_bounds_nd
        if model.kind == "planar":
            tgt = ocp.target_nd
            dv = math.hypot(x0[dyn.VR] - tgt[1], x0[dyn.R] * x0[dyn.OMEGA] - tgt[2])
            c = ocp.params.exhaust_velocity_nd
            tf = (1.0 - math.exp(-dv / c)) * x0[dyn.M] * c / ocp.params.thrust_nd
            tf = float(np.clip(tf, lo, hi))
            xf = x0.copy()
            xf[dyn.R], xf[dyn.VR], xf[dyn.OMEGA] = tgt[0], tgt[1], tgt[2] / tgt[0]
            X = x0[None, :] + s[:, None] * (xf - x0)[None, :]
            X[:, dyn.THETA] = x0[dyn.THETA] + tf * np.cumsum(
                np.r_[0.0, 0.5 * (X[1:, dyn.OMEGA] + X[:-1, dyn.OMEGA])]) / (K - 1)
            u = np.array([0.0, 1.0, 1.0])
        else:
            tf = float(lo + (hi - lo) / 3.0)
            p0, pf = x0[:3], ocp.target_position_nd
            r0, rf = np.linalg.norm(p0), np.linalg.norm(pf)
            e0, ef = p0 / r0, pf / rf
            ang = math.acos(float(np.clip(e0 @ ef, -1.0, 1.0)))
            dirs = (np.sin((1 - s) * ang)[:, None] * e0 + np.sin(s * ang)[:, None] * ef) \
                / math.sin(ang) if ang > 1e-9 else np.tile(e0, (K, 1))
            pos = dirs * (r0 + s * (rf - r0))[:, None]
            vel = (1 - s)[:, None] * x0[3:6]
            X = np.column_stack([pos, vel, np.zeros(K)])
            X[:, dyn.M3] = x0[dyn.M3]
            # braking along the track: (radial, along, cross) = (0, −1, 0)
            u = np.array([0.0, -1.0, 0.0, 1.0])
        X[:, model.mass_index] = x0[model.mass_index] - s * tf * ocp.mass_flow_nd
        X[:, model.mass_index] = np.maximum(X[:, model.mass_index], model.mass_min)
        return ConvexGuess(tf, X, np.tile(u, (K - 1, 1)))

    # ---- solve -----------------------------------------------------------------------------
    def solve(self, ocp, guess: ConvexGuess | None = None, *,
              initial_state: np.ndarray | None = None, max_iter: int | None = None
              ) -> ConvexSolution:
        """Minimum-fuel landing from ``initial_state`` (default the problem's).

        Parameters
        ----------
        ocp : PlanarOCP or PinpointOCP
        guess : ConvexGuess, optional
            Reference trajectory on ``n_nodes`` nodes (e.g. a previous solution shifted by
            :meth:`ConvexGuess.shifted`); default :meth:`cold_guess`.
        initial_state : ndarray, shape (n_state,), optional
            Normalised start replacing the problem's (a re-plan from the navigated state).
        max_iter : int, optional
            Overrides the solver's ``max_iter`` for this call.

        Returns
        -------
        ConvexSolution
            ``success`` False (never an exception or NaN) when SCvx does not converge, the
            convex solver fails, or the problem's verdict fails (e.g. not enough propellant).

        Raises
        ------
        ValueError
            A malformed initial state or guess (shape, non-finite values).
        """
        t_start = time.perf_counter()
        b = self._build(ocp)
        model = b["model"]
        nx, nu, K = model.n_x, model.n_u, self.n_nodes
        x0 = np.asarray(ocp.initial_state if initial_state is None else initial_state,
                        dtype=np.float64)
        if x0.shape != (nx,) or not np.all(np.isfinite(x0)):
            raise ValueError(f"initial_state must be {nx} finite normalised values, got "
                             f"{x0!r}")
        guess = self.cold_guess(ocp, x0) if guess is None else guess
        Xr = np.asarray(guess.states, dtype=np.float64).T.copy()
        Ur = np.asarray(guess.controls, dtype=np.float64).T.copy()
        sr = float(guess.tf_nd)
        if Xr.shape != (nx, K) or Ur.shape != (nu, K - 1) or not (
                np.all(np.isfinite(Xr)) and np.all(np.isfinite(Ur)) and math.isfinite(sr)
                and sr > 0):
            raise ValueError(f"guess must have states ({K}, {nx}), controls ({K - 1}, {nu}) and "
                             f"tf_nd > 0, all finite; got {Xr.T.shape}, {Ur.T.shape}, {sr!r}")
        Xr[:, 0] = x0
        P, prob = b["P"], b["prob"]
        P["x0"].value = x0
        P["gmin"].value = 1.0 if self.engine == "constant" else 0.0
        P["gmax"].value = self.throttle_max
        if self.engine == "throttled":
            Ur[model.d] = np.minimum(Ur[model.d], self.throttle_max)
        if self.engine == "constant":
            Ur[model.d] = 1.0
        max_iter = self.max_iter if max_iter is None else int(max_iter)
        eta = self.trust_region
        lin = self._linearise(b, Xr, Ur, sr)
        n_fevals = 1
        merit = self._merit(b, Xr, lin)
        history, statuses = [], []
        solver_s = solve_s = 0.0
        lin_s = 0.0
        converged = False
        message = "SCvx reached max_iter without converging"
        it = 0
        while it < max_iter:
            it += 1
            for name in ("A", "B", "S", "z", "G", "g0", "C", "c0"):
                P[name].value = lin[name]
            P["Xr"].value, P["Ur"].value, P["sr"].value = Xr, Ur, sr
            P["eta"].value = eta
            ts = time.perf_counter()
            try:
                prob.solve(solver=self.solver, warm_start=True, **self.solver_options)
                status = prob.status
            except Exception as exc:  # noqa: BLE001  (a solver failure is a value)
                status = f"solver error: {exc}"
            solve_s += time.perf_counter() - ts
            stats = getattr(prob, "solver_stats", None)
            if stats is not None and stats.solve_time is not None:
                solver_s += float(stats.solve_time)
            statuses.append(str(status))
            if status not in ("optimal", "optimal_inaccurate") or b["X"].value is None:
                message = f"convex subproblem {status} at iteration {it}"
                break
            Xn, Un, sn = b["X"].value.copy(), b["U"].value.copy(), float(b["sigma"].value)
            Xn[:, 0] = x0
            predicted = float(prob.value)
            tl = time.perf_counter()
            lin_new = self._linearise(b, Xn, Un, sn)
            lin_s += time.perf_counter() - tl
            n_fevals += 1
            merit_new = self._merit(b, Xn, lin_new)
            d_pred = merit - predicted
            d_act = merit - merit_new
            step = max(np.abs(Xn - Xr).max(), np.abs(Un - Ur).max(), abs(sn - sr))
            feasible_ref = np.abs(lin["defect"]).max() <= self.defect_tol and \
                lin["path_viol"].max(initial=0.0) <= self.defect_tol
            if feasible_ref and d_pred <= self.cost_tol:
                # the convex model predicts no further decrease from a dynamically feasible
                # reference: the reference is the (local) solution
                converged = True
                message = f"SCvx converged in {it} iterations (no predicted decrease)"
                break
            rho = d_act / d_pred if abs(d_pred) > 1e-14 else 1.0
            if rho < 0.0 and step > self.step_tol:
                eta = eta / 2.0          # reject: keep the reference, shrink
                if eta < 1e-10:
                    message = "trust region collapsed"
                    break
                continue
            Xr, Ur, sr, lin, merit = Xn, Un, sn, lin_new, merit_new
            history.append((1.0 - Xr[model.mass_index, -1] / x0[model.mass_index])
                           * x0[model.mass_index] * ocp.scaling.mass_kg)
            if rho < 0.25:
                eta = eta / 2.0
            elif rho > 0.7:
                eta = min(2.0 * eta, self.trust_region_max)
            if (step <= self.step_tol or d_pred <= self.cost_tol) \
                    and np.abs(lin["defect"]).max() <= self.defect_tol \
                    and lin["path_viol"].max(initial=0.0) <= self.defect_tol:
                converged = True
                message = f"SCvx converged in {it} iterations"
                break
        return self._result(ocp, b, x0, Xr, Ur, sr, lin, converged, message, it, n_fevals,
                            history, statuses, solver_s, solve_s, lin_s,
                            time.perf_counter() - t_start)

    def _result(self, ocp, b, x0, Xr, Ur, sr, lin, converged, message, n_iter, n_fevals,
                history, statuses, solver_s, solve_s, lin_s, wall_s) -> ConvexSolution:
        model = b["model"]
        K = self.n_nodes
        nk = K - 1
        # single shooting of the held controls from x0 through F: the discrete model's replay
        traj = np.vstack([x0, np.asarray(b["shoot"](x0, Ur, sr * np.ones((1, nk)))).T])
        finite = bool(np.all(np.isfinite(traj)))
        s = ocp.scaling
        mi = model.mass_index
        if finite:
            errors = ocp.terminal_errors(traj[-1])
            path = ocp.path_quantities(traj)
            ok, why = ocp.success_from(errors, path)
            fuel = float((x0[mi] - traj[-1, mi]) * s.mass_kg)
        else:  # pragma: no cover  (a diverged reference never reaches here finite-less)
            errors = {k: math.inf for k in ocp.tolerances}
            ok, why, fuel = False, "the propagation is not finite", math.inf
        success = bool(converged and ok)
        if not converged:
            message += (f" (largest interval defect {np.abs(lin['defect']).max():.2g}: virtual "
                        "control still needed, the start may be infeasible)")
        msg = f"{message}; {why}"
        t_nd = sr * np.linspace(0.0, 1.0, K)
        mc = model.model_controls(Ur.T)
        pp = PiecewisePolynomial(t_nd[None, :], mc[None, :, :, None])
        control = ControlLaw(pp, s.time_s)
        gam = Ur[model.d]
        wn = np.linalg.norm(Ur[:model.d], axis=0)
        burning = gam > 1e-3
        tight = float(np.min(wn[burning] / gam[burning])) if burning.any() else 1.0
        names = dyn.PLANAR_STATE_NAMES if model.kind == "planar" else dyn.MOON3D_STATE_NAMES
        t_s = t_nd * s.time_s
        ctrl_names = ("phi_rad", "throttle") if model.kind == "planar" else (
            "alpha_rad", "beta_rad", "throttle")
        trajectory = Trajectory(
            t_s=t_s, states={f"{n}_nd": traj[:, i] for i, n in enumerate(names)},
            controls={n: np.r_[mc[:, i], mc[-1, i]] for i, n in enumerate(ctrl_names)})
        xvec = np.concatenate([[sr], Xr.T.ravel(), Ur.T.ravel()])
        extra = {"tightness": tight, "min_throttle": float(gam.min()),
                 "max_defect_nd": float(np.abs(lin["defect"]).max()),
                 "solver_s": solver_s, "solve_s": solve_s, "linearise_s": lin_s,
                 "build_s": float(b["build_s"]), "statuses": statuses,
                 "converged": bool(converged)}
        return ConvexSolution(
            x=xvec, fuel_kg=fuel, tf_s=float(sr * s.time_s), terminal_errors=errors,
            history=np.asarray(history, dtype=float), n_fevals=int(n_fevals),
            wall_s=float(wall_s), success=success, message=msg, trajectory=trajectory,
            extra=extra, n_iter=int(n_iter), fun=fuel, feasible=bool(ok),
            constraint_violation=0.0 if ok else math.inf,
            algorithm=f"SCvx(K={K})", problem=type(ocp).__name__, control=control,
            tf_nd=float(sr), t_nd=t_nd, states=Xr.T.copy(), controls=Ur.T.copy(),
            model_controls=mc)


def solve_convex(problem="zhu2007", **kwargs) -> ConvexSolution:
    """One SCvx solve of a scenario name, a scenario or an OCP (settings as keyword arguments
    of :class:`SuccessiveConvexification`)."""
    from lunar_env.scenarios import PinpointScenario, get_scenario

    from ..problems.pinpoint import PinpointOCP
    from ..problems.planar_ocp import PlanarOCP

    ocp = problem
    if isinstance(problem, str):
        problem = get_scenario(problem)
    if isinstance(problem, PinpointScenario):
        ocp = PinpointOCP(problem)
    elif not isinstance(problem, PlanarOCP | PinpointOCP):
        ocp = PlanarOCP(problem)
    return SuccessiveConvexification(**kwargs).solve(ocp)
