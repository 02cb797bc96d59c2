"""The serial strategy of [001] (Peng, Li, Shen, Tang 2012, §3): GPM, then direct shooting.

1. A coarse Gauss pseudospectral solve (N = 6 LG points) from the initial guess, itself solved
   feasible-first (phase 1: minimise the equality-constraint violation; phase 2: minimise tf
   from there) — :class:`optimizers.transcription.gpm.GaussPseudospectral`.
2. Direct shooting on (N + 1)·K segments (K = 5), the node controls initialised by a cubic
   spline through the GPM controls at the LG points — :class:`optimizers.transcription.
   direct_shooting.DirectShooting`.

Initial guesses (decisions where the paper is silent: it says only "random initial values
inside the constraint ranges"): a guess is a final time and (α, β) at the N LG points of that
time. :func:`random_guess` draws α and β uniformly inside their bounds at every node and tf
uniformly in [tf_min, min(tf_max, the longest burn the fuel budget allows)]. The GPM state guess
is the trajectory those controls produce (piecewise linear through the nodes, held at the ends,
integrated with the compiled RK4 from the initial state), so guess = controls + tf only, and the
same guess can start direct shooting alone (spline through the node controls), as in the
paper's comparison.

Everything returns :class:`optimizers.common.result.OptimResult` (non-convergence is a value).
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from lunar_env.scenarios import PinpointScenario, get_scenario

from ..common.quadrature import legendre_gauss
from ..common.result import ControlLaw, OptimResult, Trajectory
from ..parameterisations import piecewise_linear_control
from ..problems.pinpoint import PinpointOCP
from .direct_shooting import DirectShooting, ShootingSolution, gauss_segment_fractions
from .gpm import GaussPseudospectral, GPMGuess, GPMSolution

__all__ = [
    "ControlGuess", "nominal_guess", "random_guess", "guess_to_gpm", "solve_serial",
    "solve_shooting_only", "dense_collocation_check", "SerialSolver", "get_solver",
]


@dataclass
class ControlGuess:
    """An initial guess: final time and node controls.

    Attributes
    ----------
    tf_nd : float
    t_nd : ndarray, shape (n,)
        Node times inside [0, tf].
    controls : ndarray, shape (n, 2)
        (α, β) in rad at the nodes.
    """

    tf_nd: float
    t_nd: np.ndarray
    controls: np.ndarray

    def __post_init__(self) -> None:
        self.t_nd = np.asarray(self.t_nd, float)
        self.controls = np.asarray(self.controls, float)
        if not (np.isfinite(self.tf_nd) and self.tf_nd > 0):
            raise ValueError(f"ControlGuess.tf_nd = {self.tf_nd!r} must be finite and > 0")
        if self.controls.shape != (len(self.t_nd), 2):
            raise ValueError(f"ControlGuess.controls shape {self.controls.shape} does not "
                             f"match t_nd shape {self.t_nd.shape}; expected (n, 2)")


def _as_ocp(problem) -> PinpointOCP:
    if isinstance(problem, PinpointOCP):
        return problem
    if isinstance(problem, str):
        problem = get_scenario(problem)
    if isinstance(problem, PinpointScenario):
        return PinpointOCP(problem)
    raise TypeError(f"expected a PinpointOCP, a PinpointScenario or a scenario name, got "
                    f"{type(problem).__name__}")


def _lg_times(tf_nd: float, n_gauss: int) -> np.ndarray:
    tau, _ = legendre_gauss(n_gauss)
    return tf_nd * (tau + 1.0) / 2.0


def nominal_guess(ocp: PinpointOCP, n_gauss: int = 6) -> ControlGuess:
    """The deterministic guess: brake along the track (α = 0, β = 180°) for the rocket-equation
    burn time that cancels the initial speed, tf = (1 − exp(−|V0|/c))·c·m0/F ([000] eq. (23))."""
    c = ocp.params.exhaust_velocity_nd
    v0 = float(np.linalg.norm(ocp.x0_nd[3:6]))
    tf = (1.0 - math.exp(-v0 / c)) * c * ocp.x0_nd[6] / ocp.params.thrust_nd
    tf = float(np.clip(tf, *ocp.tf_bounds_nd))
    t = _lg_times(tf, n_gauss)
    beta = float(np.clip(math.pi, *ocp.beta_bounds_rad))
    alpha = float(np.clip(0.0, *ocp.alpha_bounds_rad))
    return ControlGuess(tf, t, np.tile([alpha, beta], (n_gauss, 1)))


def random_guess(ocp: PinpointOCP, rng: np.random.Generator, n_gauss: int = 6) -> ControlGuess:
    """A random guess inside the bounds (see the module docstring)."""
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    lo, hi = ocp.tf_bounds_nd
    hi = min(hi, ocp.tf_upper_by_fuel_nd())
    tf = float(rng.uniform(lo, hi))
    u = rng.uniform(ocp.control_lower, ocp.control_upper, size=(n_gauss, 2))
    return ControlGuess(tf, _lg_times(tf, n_gauss), u)


def _held_nodes(guess: ControlGuess) -> tuple[np.ndarray, np.ndarray]:
    """Node times/controls extended to [0, tf] by holding the end values."""
    t = guess.t_nd
    u = guess.controls
    if t[0] > 0:
        t = np.concatenate([[0.0], t])
        u = np.vstack([u[:1], u])
    if t[-1] < guess.tf_nd:
        t = np.concatenate([t, [guess.tf_nd]])
        u = np.vstack([u, u[-1:]])
    return t, u


def guess_to_gpm(ocp: PinpointOCP, guess: ControlGuess, *, n_steps: int = 200,
                 initial_state: np.ndarray | None = None) -> GPMGuess:
    """States for a control guess: integrate it (compiled RK4, piecewise linear, held ends)."""
    from lunar_env.integrators import MOON3D, integrate

    t, u = _held_nodes(guess)
    pp = piecewise_linear_control(t, u)
    x0 = ocp.x0_nd if initial_state is None else np.asarray(initial_state, float)
    prop = integrate(MOON3D, x0[None, :], t0_nd=0.0, dt_nd=guess.tf_nd / n_steps,
                     n_steps=n_steps, control=pp, params=ocp.params, record=True)
    tt = prop.times[0]
    return GPMGuess(guess.tf_nd, tt, prop.states[0], pp(tt[None, :])[0, :, :2])


def spline_node_controls(ocp: PinpointOCP, t_src: np.ndarray, u_src: np.ndarray,
                         t_dst: np.ndarray) -> np.ndarray:
    """Cubic spline (not-a-knot) through (t_src, u_src), evaluated at t_dst, clipped to the
    control bounds ([001] §3 (2): "the node controls between Gauss points by spline
    interpolation"). Falls back to linear interpolation for fewer than 4 points."""
    if len(t_src) >= 4:
        u = CubicSpline(t_src, u_src, axis=0)(t_dst)
    else:
        u = np.stack([np.interp(t_dst, t_src, u_src[:, j]) for j in range(u_src.shape[1])], 1)
    return np.clip(u, ocp.control_lower, ocp.control_upper)


class SerialSolver:
    """GPM (feasible first) → direct shooting, with the NLPs built once and reused.

    Parameters
    ----------
    problem : PinpointOCP, PinpointScenario or scenario name
    n_gauss : int
        N of the GPM initial-guess generator ([001]: 6).
    k_per_interval : int
        K shooting segments between adjacent Gauss points ([001]: 5).
    n_rk4_per_segment : int
        RK4 steps per shooting segment (not stated in [001]). With 1 the control, replayed by an
        adaptive DOP853 integrator, misses the target by ~0.4 m (the transcription's RK4
        error); 4 brings that to ~2 mm (what an open-loop replay in the environment needs to
        reach the 2 km gate at < 0.5 m/s).
    form : {"single", "lifted"}
        "single" is the paper's direct shooting (controls and tf only). "lifted" keeps the node
        states as variables with continuity constraints: the same discretised problem and
        optimum, a sparse NLP (cheaper exact Hessians, used for the finer RK4 grids).
    tol : float
        IPOPT tolerance (normalised).
    max_iter : int
        IPOPT iteration limit per NLP.
    """

    def __init__(self, problem="peng2012", *, n_gauss: int = 6, k_per_interval: int = 5,
                 n_rk4_per_segment: int = 1, form: str = "single", tol: float = 1e-10,
                 max_iter: int = 300, verbose: bool = False) -> None:
        self.ocp = _as_ocp(problem)
        self.n_gauss = int(n_gauss)
        self.gpm = GaussPseudospectral(self.n_gauss, tol=tol, max_iter=max_iter,
                                       verbose=verbose)
        self.shooting = DirectShooting(gauss_segment_fractions(self.n_gauss, k_per_interval),
                                       n_rk4_per_segment=n_rk4_per_segment, tol=tol,
                                       max_iter=max_iter, verbose=verbose, form=form)

    def build(self) -> float:
        """Build (or fetch) both NLPs; returns the seconds spent."""
        t0 = time.perf_counter()
        self.gpm._build(self.ocp)
        self.shooting._build(self.ocp)
        # load (or compile) the numba RK4 kernel used for guesses and replays
        guess_to_gpm(self.ocp, nominal_guess(self.ocp, self.n_gauss), n_steps=2)
        return time.perf_counter() - t0

    def solve(self, guess: ControlGuess | None = None, *,
              initial_state: np.ndarray | None = None) -> OptimResult:
        """Run the serial strategy from ``guess`` (default :func:`nominal_guess`)."""
        ocp = self.ocp
        guess = nominal_guess(ocp, self.n_gauss) if guess is None else guess
        t_start = time.perf_counter()
        g = guess_to_gpm(ocp, guess, initial_state=initial_state)
        gsol = self.gpm.solve(ocp, g, initial_state=initial_state)
        t_nodes = gsol.tf_nd * self.shooting.fractions
        u0 = spline_node_controls(ocp, gsol.t_lg_nd, gsol.controls, t_nodes)
        ssol = self.shooting.solve(ocp, gsol.tf_nd, u0, initial_state=initial_state)
        wall = time.perf_counter() - t_start
        return _result(ocp, ssol, gsol, wall, initial_state=initial_state)

    def solve_shooting_only(self, guess: ControlGuess, *,
                            initial_state: np.ndarray | None = None) -> OptimResult:
        """Direct shooting alone from the same guess (spline through its node controls)."""
        ocp = self.ocp
        t_start = time.perf_counter()
        t_nodes = guess.tf_nd * self.shooting.fractions
        u0 = spline_node_controls(ocp, guess.t_nd, guess.controls, t_nodes)
        ssol = self.shooting.solve(ocp, guess.tf_nd, u0, initial_state=initial_state)
        return _result(ocp, ssol, None, time.perf_counter() - t_start,
                       initial_state=initial_state)


def _result(ocp: PinpointOCP, ssol: ShootingSolution, gsol: GPMSolution | None, wall_s: float,
            *, initial_state=None) -> OptimResult:
    s = ocp.scaling
    t_rep, x_rep = ssol.replay(ocp, initial_state=initial_state)
    m = ssol.n_rk4_per_segment
    replay_diff = float(np.max(np.abs(x_rep[::m] - ssol.states)))
    errors = ocp.terminal_errors(x_rep[-1])
    pp = ssol.control_law()
    u_rep = pp(t_rep[None, :])[0]
    traj = Trajectory(t_s=t_rep * s.time_s, states=ocp.describe_states(x_rep),
                      controls={"alpha_rad": u_rep[:, 0], "beta_rad": u_rep[:, 1],
                                "throttle": u_rep[:, 2]})
    extra = {
        "shooting": {
            "t_nodes_s": ssol.t_nodes_nd * s.time_s, "alpha_rad": ssol.controls[:, 0],
            "beta_rad": ssol.controls[:, 1], "iterations": ssol.iterations,
            "wall_s": ssol.wall_s, "status": ssol.message, "success": ssol.success,
            "n_segments": len(ssol.t_nodes_nd) - 1,
            "n_rk4_per_segment": ssol.n_rk4_per_segment,
        },
        "shooting_solution": ssol,
        "replay_max_abs_diff_nd": replay_diff,
    }
    n_iter = ssol.n_iter
    n_fevals = ssol.n_fevals
    history = list(ssol.history)
    # the problem's verdict on the replayed trajectory: terminal conditions, above the surface
    # everywhere, fuel budget (a converged NLP through the Moon is no landing)
    verdict, why = ocp.success_from(errors, ocp.path_quantities(x_rep))
    success = bool(ssol.success) and bool(verdict)
    message = f"shooting: {ssol.message.split(';')[0]}; replay: {why}"
    if gsol is not None:
        extra["gpm"] = {
            "t_s": gsol.t_lg_nd * s.time_s, "alpha_rad": gsol.controls[:, 0],
            "beta_rad": gsol.controls[:, 1], "tf_s": gsol.tf_nd * s.time_s,
            "fuel_kg": ocp.fuel_kg(gsol.tf_nd), "success": gsol.success,
            "status": gsol.message, "phases": gsol.phases, "wall_s": gsol.wall_s,
        }
        extra["gpm_solution"] = gsol
        n_iter += gsol.n_iter
        n_fevals += gsol.n_fevals
        history = list(gsol.history) + history
        message = f"gpm: {gsol.message.split(';')[0]}; {message}"
    fuel = ocp.fuel_kg(ssol.tf_nd)
    return OptimResult(
        x=ssol.x, fuel_kg=fuel, tf_s=ssol.tf_nd * s.time_s, terminal_errors=errors,
        history=np.asarray(history), n_fevals=int(n_fevals), n_iter=int(n_iter),
        wall_s=float(wall_s), success=success, message=message, trajectory=traj, extra=extra,
        fun=fuel, feasible=bool(verdict), algorithm="GPM (feasible first) + direct shooting"
        if gsol is not None else "direct shooting", problem=repr(ocp),
        control=ControlLaw(pp, s.time_s))


#: the most recently used solvers, at most :data:`MAX_CACHED_SOLVERS` (oldest evicted first)
_SOLVERS: OrderedDict[tuple, SerialSolver] = OrderedDict()
#: why a bound: a built pinpoint solver holds ~300 MB of CasADi NLPs, and a process that
#: solves many plants (each plant is its own scenario, e.g. a campaign's true engines) kept
#: every one: 52 plants grew a process to 14-17 GB
MAX_CACHED_SOLVERS = 4


def get_solver(problem="peng2012", **kwargs) -> SerialSolver:
    """The process-wide :class:`SerialSolver` for ``problem`` and options (built once, kept
    while it is among the :data:`MAX_CACHED_SOLVERS` most recently used)."""
    return _solver(problem, **kwargs)


def _solver(problem, **kwargs) -> SerialSolver:
    if isinstance(problem, str):
        problem = get_scenario(problem)
    sc = problem.scenario if isinstance(problem, PinpointOCP) else problem
    key = (id(sc), getattr(problem, "min_altitude_m", 0.0), getattr(problem, "floor_margin_m",
                                                                     0.0),
           getattr(problem, "floor_margin_range_m", 0.0), tuple(sorted(kwargs.items())))
    if key not in _SOLVERS or _SOLVERS[key].ocp.scenario is not sc:
        _SOLVERS[key] = SerialSolver(problem, **kwargs)
    _SOLVERS.move_to_end(key)
    while len(_SOLVERS) > MAX_CACHED_SOLVERS:
        _SOLVERS.popitem(last=False)
    return _SOLVERS[key]


def solve_serial(scenario="peng2012", guess: ControlGuess | None = None, *,
                 initial_state: np.ndarray | None = None, **kwargs) -> OptimResult:
    """[001]'s serial strategy: GPM (N = 6, feasible first), then direct shooting.

    Parameters
    ----------
    scenario : PinpointScenario, PinpointOCP or scenario name
    guess : ControlGuess, optional
        Default :func:`nominal_guess`; :func:`random_guess` draws one inside the bounds.
    initial_state : ndarray, shape (7,), optional
        Normalised Moon-fixed start (default the scenario's); the NLPs are reused.
    **kwargs
        :class:`SerialSolver` options (``n_gauss``, ``k_per_interval``,
        ``n_rk4_per_segment``, ``tol``, ``max_iter``). The solver with these options is built
        once per process and reused.

    Returns
    -------
    OptimResult
        ``tf_s``, ``fuel_kg``; ``terminal_errors`` from replaying the control with
        :func:`lunar_env.integrators.integrate`; ``success`` the NLPs converged and the
        problem's verdict on that replay (terminal conditions, never below the surface, fuel
        budget); ``extra["gpm"]`` (the GPM stage) and ``extra["shooting"]``; ``n_fevals``
        IPOPT objective evaluations and ``n_iter`` IPOPT iterations of all NLPs; ``history``
        the fuel (kg) per iteration; ``control`` the (α, β, throttle) law on SI time.
    """
    return _solver(scenario, **kwargs).solve(guess, initial_state=initial_state)


def solve_shooting_only(scenario="peng2012", guess: ControlGuess | None = None, *,
                        initial_state: np.ndarray | None = None, **kwargs) -> OptimResult:
    """Direct shooting alone from ``guess`` (the paper's comparison, which never converged)."""
    solver = _solver(scenario, **kwargs)
    guess = nominal_guess(solver.ocp, solver.n_gauss) if guess is None else guess
    return solver.solve_shooting_only(guess, initial_state=initial_state)


def dense_collocation_check(result: OptimResult, problem="peng2012", *,
                            n_nodes_list: tuple[int, ...] = (20, 40), tol: float = 1e-10,
                            initial_state: np.ndarray | None = None) -> dict:
    """Converged-optimum check: LG collocation with many nodes from the serial solution.

    A single-interval GPM with ``n_nodes`` LG points converges spectrally to the true optimum of
    the continuous problem (for a smooth solution), independently of the shooting
    transcription's control parameterisation and RK4 steps. Returns, per N, tf (s), fuel (kg),
    the IPOPT status, and the gap of the serial result to the densest converged one; the
    densest converged :class:`~optimizers.transcription.gpm.GPMSolution` is
    ``out["reference_result"]`` (for :func:`optimizers.certification.certify`).
    """
    ocp = _as_ocp(problem)
    s = ocp.scaling
    ssol: ShootingSolution = result.extra["shooting_solution"]
    t_rep, x_rep = ssol.replay(ocp, initial_state=initial_state)
    u = ssol.control_law()(t_rep[None, :])[0, :, :2]
    guess = GPMGuess(ssol.tf_nd, t_rep, x_rep, u)
    out = {"runs": []}
    best_sol = None
    for n in n_nodes_list:
        gpm = GaussPseudospectral(int(n), feasible_first=False, tol=tol, max_iter=1000)
        t0 = time.perf_counter()
        sol = gpm.solve(ocp, guess, initial_state=initial_state)
        out["runs"].append({"n_nodes": int(n), "tf_s": sol.tf_nd * s.time_s,
                            "fuel_kg": ocp.fuel_kg(sol.tf_nd), "success": sol.success,
                            "status": sol.message, "wall_s": time.perf_counter() - t0})
        if sol.success:
            best_sol = sol
    ok = [r for r in out["runs"] if r["success"]]
    if ok:
        best = ok[-1]
        out["reference_tf_s"] = best["tf_s"]
        out["reference_fuel_kg"] = best["fuel_kg"]
        out["serial_minus_reference_tf_s"] = result.tf_s - best["tf_s"]
        out["serial_minus_reference_fuel_kg"] = result.fuel_kg - best["fuel_kg"]
        out["reference_result"] = best_sol
    return out


def certified_optimum(ocp: PinpointOCP, *, n_nodes: int = 40, tol: float = 1e-10) -> OptimResult:
    """The pinpoint problem's certified optimum: the serial strategy from the nominal guess,
    then a dense single-interval LG collocation (``n_nodes`` points) from its solution.

    Returns the dense GPM's :class:`~optimizers.transcription.gpm.GPMSolution` (fuel, tf and
    the problem's verdict), with the serial result in ``extra["serial"]``.
    """
    serial = _solver(ocp).solve(initial_state=ocp.initial_state)
    ssol: ShootingSolution = serial.extra["shooting_solution"]
    t_rep, x_rep = ssol.replay(ocp)
    u = ssol.control_law()(t_rep[None, :])[0, :, :2]
    gpm = GaussPseudospectral(int(n_nodes), feasible_first=False, tol=tol, max_iter=1000)
    dense = gpm.solve(ocp, GPMGuess(ssol.tf_nd, t_rep, x_rep, u))
    dense.algorithm = f"dense LG collocation (N = {int(n_nodes)}) from the serial solution"
    dense.extra["serial"] = serial
    return dense
