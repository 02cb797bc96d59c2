"""Legendre–Gauss collocation with one phase per throttle arc: the direct method of the touchdown
optimum (:class:`~optimizers.problems.touchdown.TouchdownOCP`).

A minimum-fuel landing with a throttle bounded in [Γ_min, 1] is bang–bang (full thrust, minimum
throttle, full thrust for [001]'s start, :data:`~optimizers.problems.touchdown.MAX_MIN_MAX`):
its throttle jumps, so a single-interval pseudospectral transcription converges only slowly. As
in multi-phase GPM (Benson 2005; Rao et al., "GPOPS", ACM TOMS 37(2), 2010), each arc is a phase
of its own with the throttle held at its level and a free duration; inside a phase the control
(the thrust direction) is smooth and the collocation converges spectrally.

Per phase p with N_p Legendre–Gauss (LG) points ([001] eq. (14)–(15), as
:mod:`optimizers.transcription.gpm`): states X_p,0 at τ = −1 and X_p,1..N at the LG points,
thrust directions U_p,1..N (orbital-frame unit vectors, ‖U‖² = 1), duration Δt_p >= the
minimum (``min_arc_s``);

- collocation D X_p − (Δt_p/2) f(X_p,k, U_p,k, Γ_p) = 0;
- the phase's end by Gauss quadrature, X_p,f = X_p,0 + (Δt_p/2) Σ w_k f_k, which is the next
  phase's start (X_{p+1},0 = X_p,f) and, after the last phase, the touchdown state;
- X_1,0 = the initial state; the problem's terminal residual at the last X_f;
- thrust elevation above its bound (e_r >= sin α_min), the state box and the mass floor;
- objective −m(tf).

The initial state and the engine (thrust, exhaust velocity) are NLP *parameters*: one build
serves every start and every plant of a scenario. The terminal constraints' multipliers are
the costate at touchdown (the transversality condition λ(tf) = ∂(φ + νᵀψ)/∂x; Benson et al.,
JGCD 29(6), 2006, costate mapping of the GPM), which starts the indirect method
(:mod:`optimizers.indirect.touchdown`).

Decisions where the references are silent: an arc's duration is bounded below. At zero
duration a phase's directions drop out of the problem and IPOPT can stop on the spurious
stationary point "no arc, any direction" (measured on [001]'s start from the cold guess: the
first full-thrust arc collapsed to 0 s, 1.5e-6 of the propellant above the optimum, instead of
its 7.4 s; with a floor of 0.1 s it stopped at the floor on 22 of the 32 corners of the
dispersion), while with a floor of 1 s (:data:`MIN_ARC_S`) a phase's direction weighs enough
for IPOPT to find the arc's true length. Shorter arcs exist, though: at the dispersion's corners
the first full-thrust arc lasts from 0.8 s to nothing (min–max). :func:`solve_structure`
therefore solves with the 1 s floor, frees an arc found at it down to
:data:`MIN_ARC_FLOOR_S` (0.01 s) starting from that solution, and removes an arc that sits at
the lower floor (its bound multiplier active), solving once more without it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..common.casadi_tools import casadi as _casadi
from ..common.casadi_tools import ipopt_options, nlp_counts
from ..common.quadrature import (
    gauss_differentiation_matrix,
    lagrange_interpolate,
    legendre_gauss,
)
from ..common.result import OptimResult

__all__ = ["PhasedGaussPseudospectral", "PhasedGuess", "PhasedSolution", "solve_structure",
           "replay", "MIN_ARC_S", "MIN_ARC_FLOOR_S"]

#: Lower bound of an arc's duration in the first solve (s); see the module docstring.
MIN_ARC_S = 1.0
#: Lower bound when an arc found at :data:`MIN_ARC_S` is freed (s); an arc at it is removed.
MIN_ARC_FLOOR_S = 0.01


@dataclass
class PhasedGuess:
    """A guess on the solver's own nodes (e.g. a neighbouring case's solution).

    Attributes
    ----------
    durations_nd : ndarray, shape (n_arcs,)
    states : list of ndarray, each (N_p + 1, 7)
        States at τ = −1 and the LG points of each phase.
    directions : list of ndarray, each (N_p, 3)
        Orbital-frame thrust directions at the LG points.
    """

    durations_nd: np.ndarray
    states: list
    directions: list


@dataclass
class PhasedSolution(OptimResult):
    """:class:`~optimizers.common.result.OptimResult` of :class:`PhasedGaussPseudospectral`.

    ``fuel_kg`` from the final mass (m0 − m(tf)); ``terminal_errors`` of the quadrature's final
    state; ``success`` IPOPT converged and the problem's verdict on the node states.

    Attributes
    ----------
    levels : tuple of float
        Throttle of each arc.
    durations_nd : ndarray, shape (n_arcs,)
    tau : list of ndarray
        LG points of each phase.
    states : list of ndarray, each (N_p + 1, 7)
    directions : list of ndarray, each (N_p, 3)
    final_state : ndarray, shape (7,)
    costate_tf : ndarray, shape (7,)
        λ(tf) from the terminal multipliers (λ_m(tf) = −1).
    at_min : ndarray of bool, shape (n_arcs,)
        The arc's duration sits at its lower bound (the arc does not exist).
    """

    levels: tuple = ()
    durations_nd: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tau: list = field(default_factory=list)
    states: list = field(default_factory=list)
    directions: list = field(default_factory=list)
    final_state: np.ndarray = field(default_factory=lambda: np.zeros(7))
    costate_tf: np.ndarray = field(default_factory=lambda: np.zeros(7))
    at_min: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    def guess(self) -> PhasedGuess:
        """This solution as a warm start on the same nodes."""
        return PhasedGuess(self.durations_nd.copy(), [s.copy() for s in self.states],
                           [d.copy() for d in self.directions])

    def direction_at(self, t_nd) -> np.ndarray:
        """Thrust directions (n, 3) (orbital frame, unit) at times ``t_nd`` (n,) since the
        start: each phase's Lagrange interpolant through its LG points, normalised (the
        collocation's own control representation)."""
        t = np.atleast_1d(np.asarray(t_nd, dtype=float))
        out = np.empty((len(t), 3))
        edges = np.concatenate([[0.0], np.cumsum(self.durations_nd)])
        k = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, len(self.durations_nd) - 1)
        for p in range(len(self.durations_nd)):
            sel = k == p
            if sel.any():
                tau = 2.0 * (t[sel] - edges[p]) / self.durations_nd[p] - 1.0
                out[sel] = lagrange_interpolate(self.tau[p], self.directions[p], tau)
        return out / np.linalg.norm(out, axis=1)[:, None]

    def throttle_at(self, t_nd) -> np.ndarray:
        """Throttle (n,) at times ``t_nd`` (n,) since the start."""
        t = np.atleast_1d(np.asarray(t_nd, dtype=float))
        edges = np.concatenate([[0.0], np.cumsum(self.durations_nd)])
        k = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, len(self.durations_nd) - 1)
        return np.asarray(self.levels)[k]


class PhasedGaussPseudospectral:
    """Multi-phase LG collocation of a :class:`~optimizers.problems.touchdown.TouchdownOCP`
    (see the module docstring).

    Parameters
    ----------
    n_nodes_last : int
        LG points of the last phase (the long final burn to touchdown). Default 30.
    n_nodes_other : int
        LG points of every other phase (arcs of seconds to tens of seconds). Default 10.
    min_arc_s : float
        Lower bound of an arc's duration (s). Default :data:`MIN_ARC_S`.
    tol : float
        IPOPT tolerance (normalised units). Default 1e-12.
    max_iter : int
        IPOPT iterations. Default 500.

    With the defaults, [001]'s start's optimum replayed by DOP853 lands within 3e-7 m and
    3e-10 m/s of the target, and 16/16/40 points change its propellant by 4e-11 of it
    (measured): the defaults resolve the optimum far below the certification's 1e-6.
    """

    def __init__(self, *, n_nodes_last: int = 30, n_nodes_other: int = 10,
                 min_arc_s: float = MIN_ARC_S, tol: float = 1e-12, max_iter: int = 500,
                 verbose: bool = False) -> None:
        for name, v in (("n_nodes_last", n_nodes_last), ("n_nodes_other", n_nodes_other)):
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 2:
                raise ValueError(f"{name} = {v!r} must be an integer >= 2")
        if not (math.isfinite(min_arc_s) and min_arc_s > 0):
            raise ValueError(f"min_arc_s = {min_arc_s!r} must be finite and > 0")
        self.n_nodes_last = int(n_nodes_last)
        self.n_nodes_other = int(n_nodes_other)
        self.min_arc_s = float(min_arc_s)
        self.tol = float(tol)
        self.max_iter = int(max_iter)
        self.verbose = bool(verbose)
        self._cache: dict = {}

    def __repr__(self) -> str:
        return (f"PhasedGaussPseudospectral(n_nodes_last={self.n_nodes_last}, "
                f"n_nodes_other={self.n_nodes_other})")

    def nodes(self, n_arcs: int) -> tuple[int, ...]:
        """LG points per phase of an ``n_arcs`` structure."""
        return (self.n_nodes_other,) * (n_arcs - 1) + (self.n_nodes_last,)

    @staticmethod
    def _key(ocp, levels) -> tuple:
        # everything a build bakes in; the start and the engine are parameters
        p = ocp.params
        return (levels, p.spin_rate_nd, p.plane_normal, tuple(ocp.target_position_nd),
                tuple(ocp.target_uvw_nd), ocp.sin_alpha_min, ocp.mass_min_nd,
                ocp.tf_bounds_nd, ocp.scaling.time_s)

    def _build(self, ocp, levels: tuple) -> dict:
        key = self._key(ocp, levels)
        if key in self._cache:
            return self._cache[key]
        ca = _casadi()
        nodes = self.nodes(len(levels))
        par = ca.SX.sym("p", 9)  # x0 (7), thrust, exhaust velocity
        xin, thrust, ve = par[:7], par[7], par[8]
        w, lbw, ubw, g, lbg, ubg = [], [], [], [], [], []
        slo, shi = ocp.state_bounds()
        start = xin
        layout = []
        i_dur = []
        for N, gam in zip(nodes, levels, strict=True):
            tau, wq = legendre_gauss(N)
            D = gauss_differentiation_matrix(N)
            X = ca.SX.sym("X", 7, N + 1)
            U = ca.SX.sym("U", 3, N)
            dt = ca.SX.sym("dt")
            F = ca.horzcat(*[ocp.rhs_engine(X[:, k + 1], ca.vertcat(U[:, k], gam), thrust, ve)
                             for k in range(N)])
            g += [ca.vec(ca.mtimes(X, ca.DM(D.T)) - dt / 2 * F), X[:, 0] - start]
            lbg += [0.0] * (7 * N + 7)
            ubg += [0.0] * (7 * N + 7)
            g.append(ca.sum1(U * U).T)
            lbg += [1.0] * N
            ubg += [1.0] * N
            start = X[:, 0] + dt / 2 * ca.mtimes(F, ca.DM(wq))
            layout.append((N, len(lbw)))
            w += [ca.vec(X), ca.vec(U), dt]
            i_dur.append(len(lbw) + 7 * (N + 1) + 3 * N)
            # the duration's lower bound is set at each solve (min_arc_s)
            lbw += list(np.tile(slo, N + 1)) + [ocp.sin_alpha_min, -1.0, -1.0] * N + [0.0]
            ubw += list(np.tile(shi, N + 1)) + [1.0, 1.0, 1.0] * N + [ocp.tf_bounds_nd[1]]
        xf = start
        term = ocp.terminal_residual(xf)
        n_term = int(term.shape[0])
        g += [term, xf]
        lbg += [0.0] * n_term + list(slo)
        ubg += [0.0] * n_term + list(shi)
        z = ca.vertcat(*w)
        gv = ca.vertcat(*g)
        opts = ipopt_options(verbose=self.verbose, tol=self.tol, max_iter=self.max_iter)
        solver = ca.nlpsol("phased_gpm", "ipopt", {"x": z, "p": par, "f": ocp.objective(xf, 0.0),
                                                   "g": gv}, opts)
        xs = ca.SX.sym("xs", 7)
        jt = ca.Function("term_jac", [xs], [ca.jacobian(ocp.terminal_residual(xs), xs)])
        built = dict(solver=solver, lbw=np.asarray(lbw, float), ubw=np.asarray(ubw, float),
                     lbg=np.asarray(lbg, float), ubg=np.asarray(ubg, float), layout=layout,
                     nodes=nodes, n_term=n_term, n_g=int(gv.shape[0]), duration_index=i_dur,
                     xf=ca.Function("xf", [z, par], [xf]), term_jac=jt)
        self._cache[key] = built
        return built

    # ---- guesses ---------------------------------------------------------------------------
    def cold_guess(self, ocp, levels: tuple, x0: np.ndarray, thrust_nd: float,
                   exhaust_velocity_nd: float) -> PhasedGuess:
        """Straight-line start: positions along the great circle from the start to the target
        with the altitude linear in time, velocity decreasing linearly to zero, braking along
        the track; arcs before the last 8 s (full) or 24 s (minimum throttle), the last the
        rocket-equation burn that cancels the initial speed, tf = (1 − exp(−|V0|/c))·c·m0/F
        ([000] eq. (23)). (The optimum from [001]'s start: 7.4, 23.6 and 531.9 s.)"""
        s = ocp.scaling
        v0 = float(np.linalg.norm(x0[3:6]))
        c, T = exhaust_velocity_nd, thrust_nd
        t_last = (1.0 - math.exp(-v0 / c)) * c * x0[6] / T
        durs = [float(s.time_nd(8.0 if g >= 1.0 else 24.0)) for g in levels[:-1]] + [t_last]
        tf = sum(durs)
        p0 = x0[:3]
        r0 = float(np.linalg.norm(p0))
        pf = ocp.target_position_nd
        rf = float(np.linalg.norm(pf))
        e0, ef = p0 / r0, pf / rf
        ang = math.acos(float(np.clip(e0 @ ef, -1.0, 1.0)))
        states, dirs = [], []
        t0 = 0.0
        m = float(x0[6])
        for N, d, g in zip(self.nodes(len(levels)), durs, levels, strict=True):
            tau, _ = legendre_gauss(N)
            ts = t0 + d * (np.concatenate([[-1.0], tau]) + 1.0) / 2.0
            fr = ts / tf
            if ang > 1e-9:
                pos_dir = (np.sin((1 - fr) * ang)[:, None] * e0
                           + np.sin(fr * ang)[:, None] * ef) / math.sin(ang)
            else:
                pos_dir = np.tile(e0, (len(fr), 1))
            pos = pos_dir * (r0 + fr * (rf - r0))[:, None]
            vel = (1.0 - fr)[:, None] * x0[3:6]
            mass = m - T / c * g * (ts - t0)
            states.append(np.column_stack([pos, vel, mass]))
            dirs.append(np.tile([0.0, -1.0, 0.0], (N, 1)))
            m = float(mass[-1]) - T / c * g * (d - (ts[-1] - t0))
            t0 += d
        return PhasedGuess(np.asarray(durs), states, dirs)

    # ---- solve -----------------------------------------------------------------------------
    def solve(self, ocp, structure, *, guess: PhasedGuess | None = None,
              initial_state: np.ndarray | None = None, thrust_nd: float | None = None,
              exhaust_velocity_nd: float | None = None,
              min_arc_s: float | None = None) -> PhasedSolution:
        """Solve the collocation of ``ocp`` with the arc ``structure`` (throttle levels,
        ``None`` = the minimum throttle).

        Parameters
        ----------
        ocp : TouchdownOCP
        structure : tuple
        guess : PhasedGuess, optional
            On this solver's nodes for the structure; default :meth:`cold_guess`.
        initial_state : ndarray, shape (7,), optional
            Normalised start (default the problem's).
        thrust_nd, exhaust_velocity_nd : float, optional
            The engine (default the problem's nominal one).
        min_arc_s : float, optional
            Lower bound of every arc's duration (s); default the solver's ``min_arc_s``.

        Returns
        -------
        PhasedSolution
            ``success`` False (never an exception) when IPOPT fails or the verdict fails. IPOPT
            stopped at its iteration limit is resumed once from its last iterate.

        Raises
        ------
        ValueError
            A malformed initial state or guess.
        """
        t_start = time.perf_counter()
        levels = ocp.levels(structure)
        b = self._build(ocp, levels)
        x0 = np.asarray(ocp.initial_state if initial_state is None else initial_state, float)
        if x0.shape != (7,) or not np.all(np.isfinite(x0)):
            raise ValueError(f"initial_state must be 7 finite normalised values, got {x0!r}")
        T = ocp.params.thrust_nd if thrust_nd is None else float(thrust_nd)
        c = ocp.params.exhaust_velocity_nd if exhaust_velocity_nd is None \
            else float(exhaust_velocity_nd)
        if guess is None:
            guess = self.cold_guess(ocp, levels, x0, T, c)
        z0 = self._pack(b, guess)
        par = np.concatenate([x0, [T, c]])
        s = ocp.scaling
        t_min = float(s.time_nd(self.min_arc_s if min_arc_s is None else float(min_arc_s)))
        i_dur = np.asarray(b["duration_index"])
        lbw = b["lbw"].copy()
        lbw[i_dur] = t_min
        z0 = np.clip(z0, lbw, b["ubw"])
        sol = b["solver"](x0=z0, p=par, lbx=lbw, ubx=b["ubw"], lbg=b["lbg"], ubg=b["ubg"])
        st = b["solver"].stats()
        last = np.asarray(sol["x"]).ravel()
        if st["return_status"] == "Maximum_Iterations_Exceeded" and np.all(np.isfinite(last)):
            # resumed once from the last iterate, a good start: on the `standard` cases whose
            # collocation stopped there (thrust −4.2 % and −2.6 %) the restart converged at once
            sol = b["solver"](x0=last, p=par, lbx=lbw, ubx=b["ubw"], lbg=b["lbg"],
                              ubg=b["ubg"])
            st = b["solver"].stats()
        z = np.asarray(sol["x"]).ravel()
        lam_g = np.asarray(sol["lam_g"]).ravel()
        lam_x = np.asarray(sol["lam_x"]).ravel()
        states, dirs, durs = self._unpack(b, z)
        xf = np.asarray(b["xf"](z, par)).ravel()
        nu = lam_g[b["n_g"] - 7 - b["n_term"]:b["n_g"] - 7]
        lam = np.asarray(b["term_jac"](xf)).T @ nu
        lam[6] = -1.0  # ∂(−m_f)/∂m_f; the mass is free at touchdown
        errors = ocp.terminal_errors(xf)
        node_states = np.vstack([np.vstack(states), xf[None]])
        verdict, why = ocp.success_from(errors, ocp.path_quantities(node_states))
        converged = bool(st["success"])
        fuel = float((x0[6] - xf[6]) * s.mass_kg)
        # at the bound: its multiplier pushes (IPOPT's is negative at an active lower bound),
        # or the duration sits within 1e-4 of it
        at_min = (lam_x[i_dur] < -1e-9) | (durs <= t_min * (1.0 + 1e-4))
        n_f, n_it = nlp_counts(b["solver"])
        history = [(x0[6] + v) * s.mass_kg for v in st.get("iterations", {}).get("obj", [])]
        return PhasedSolution(
            x=z, fuel_kg=fuel, tf_s=float(durs.sum() * s.time_s), terminal_errors=errors,
            history=np.asarray(history or [fuel]), n_fevals=n_f, n_iter=n_it,
            wall_s=time.perf_counter() - t_start, success=converged and bool(verdict),
            message=f"IPOPT: {st['return_status']}; {why}", fun=-float(xf[6]),
            feasible=bool(verdict), algorithm=repr(self), problem=type(ocp).__name__,
            levels=levels, durations_nd=durs, tau=[legendre_gauss(N)[0] for N in b["nodes"]],
            states=states, directions=dirs, final_state=xf, costate_tf=lam, at_min=at_min)

    def _pack(self, b: dict, guess: PhasedGuess) -> np.ndarray:
        nodes = b["nodes"]
        if len(guess.states) != len(nodes) or len(guess.directions) != len(nodes) \
                or len(guess.durations_nd) != len(nodes):
            raise ValueError(f"the guess has {len(guess.states)} phases; the structure has "
                             f"{len(nodes)}")
        parts = []
        for N, X, U, d in zip(nodes, guess.states, guess.directions, guess.durations_nd,
                              strict=True):
            X = np.asarray(X, float)
            U = np.asarray(U, float)
            if X.shape != (N + 1, 7) or U.shape != (N, 3):
                raise ValueError(f"guess phase shapes {X.shape}, {U.shape}; expected "
                                 f"({N + 1}, 7), ({N}, 3)")
            parts += [X.ravel(), U.ravel(), [float(d)]]
        z = np.concatenate(parts)
        if not np.all(np.isfinite(z)):
            raise ValueError("the guess must be finite")
        return z

    def _unpack(self, b: dict, z: np.ndarray):
        states, dirs, durs = [], [], []
        i = 0
        for N in b["nodes"]:
            states.append(z[i:i + 7 * (N + 1)].reshape(N + 1, 7))
            i += 7 * (N + 1)
            dirs.append(z[i:i + 3 * N].reshape(N, 3))
            i += 3 * N
            durs.append(z[i])
            i += 1
        return states, dirs, np.asarray(durs)


def solve_structure(solver: PhasedGaussPseudospectral, ocp, structure, *,
                    guess: PhasedGuess | None = None, initial_state=None, thrust_nd=None,
                    exhaust_velocity_nd=None) -> PhasedSolution:
    """Solve with ``structure`` and find the arcs that exist (see the module docstring): the
    solver's floor first; arcs found at it freed down to :data:`MIN_ARC_FLOOR_S`; arcs at that
    floor removed (equal neighbours merged), solving again from the solution without them.
    Returns the last solution (its ``levels`` give the structure found)."""
    kw = dict(initial_state=initial_state, thrust_nd=thrust_nd,
              exhaust_velocity_nd=exhaust_velocity_nd)
    structure = tuple(structure)
    sol = solver.solve(ocp, structure, guess=guess, **kw)
    if not (sol.success and sol.at_min.any()):
        return sol
    sol = solver.solve(ocp, structure, guess=sol.guess(), min_arc_s=MIN_ARC_FLOOR_S, **kw)
    while sol.success and sol.at_min.any() and len(structure) > 1:
        keep = [i for i, drop in enumerate(sol.at_min) if not drop]
        merged: list[int] = []
        for i in keep:  # equal neighbours become one arc
            if not merged or structure[i] != structure[merged[-1]]:
                merged.append(i)
        if not merged or len(merged) == len(structure):
            break
        reduced = tuple(structure[i] for i in merged)
        g = sol.guess()
        nodes = solver.nodes(len(reduced))
        if tuple(len(g.directions[i]) for i in merged) == nodes:
            warm = PhasedGuess(g.durations_nd[merged], [g.states[i] for i in merged],
                               [g.directions[i] for i in merged])
        else:
            warm = None
        structure = reduced
        sol = solver.solve(ocp, structure, guess=warm, min_arc_s=MIN_ARC_FLOOR_S, **kw)
    return sol


def replay(ocp, sol: PhasedSolution, *, initial_state=None, thrust_nd: float | None = None,
           exhaust_velocity_nd: float | None = None, rtol: float = 1e-12,
           atol: float = 1e-14) -> dict:
    """Replay a collocation's control with the reference integrator (DOP853,
    :func:`lunar_env.integrators.integrate_reference` on the shared model), phase by phase:
    the direction from each phase's Lagrange interpolant (:meth:`PhasedSolution.direction_at`,
    as the model's angles α, β), the phase's throttle held.

    Returns
    -------
    dict
        ``terminal_errors`` (the problem's, SI), ``fuel_kg`` (from the replayed final mass),
        ``final_state`` (7,), ``success`` and ``message`` (the problem's verdict on the replay:
        terminal tolerances, above the surface before touchdown, propellant budget).
    """
    import dataclasses

    from lunar_env.integrators import MOON3D, integrate_reference

    p = ocp.params
    params = dataclasses.replace(
        p, thrust_nd=p.thrust_nd if thrust_nd is None else float(thrust_nd),
        exhaust_velocity_nd=p.exhaust_velocity_nd if exhaust_velocity_nd is None
        else float(exhaust_velocity_nd))
    y = np.asarray(ocp.initial_state if initial_state is None else initial_state, float)
    x0 = y.copy()
    edges = np.concatenate([[0.0], np.cumsum(sol.durations_nd)])
    states = [y[None]]
    for k, gam in enumerate(sol.levels):
        def control(t, k=k, gam=gam):
            # the phase's own interpolant, also where DOP853 probes the interval's ends
            tt = min(max(t, edges[k]), edges[k + 1])
            tau = 2.0 * (tt - edges[k]) / sol.durations_nd[k] - 1.0
            e = lagrange_interpolate(sol.tau[k], sol.directions[k], np.array([tau]))[0]
            ang = ocp.angles_of((e / np.linalg.norm(e))[None])[0]
            return np.array([ang[0], ang[1], gam])

        r = integrate_reference(MOON3D, y, (edges[k], edges[k + 1]), control, params,
                                rtol=rtol, atol=atol)
        y = r.y[:, -1]
        states.append(r.y[:, 1:].T)
    traj = np.vstack(states)
    errors = ocp.terminal_errors(y)
    ok, why = ocp.success_from(errors, ocp.path_quantities(traj))
    return {"terminal_errors": errors, "fuel_kg": float((x0[6] - y[6]) * ocp.scaling.mass_kg),
            "final_state": y.copy(), "success": bool(ok), "message": why}
