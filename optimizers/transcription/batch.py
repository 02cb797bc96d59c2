"""Many pinpoint optima: per-case minimum-fuel solutions of the 3D pinpoint landing ([001]) from
a batch of initial states, warm-started along a chain.

The per-case optimum is [001]'s serial strategy (:class:`optimizers.transcription.serial.
SerialSolver`: GPM, then direct shooting, ~0.5 s per case) started from the very normalised
state given, on the landing env's problem (:func:`env_ocp`): [001]'s, with the path kept above
the 2 km gate sphere at every shooting node, because ``LunarPinpointLanding-v*`` ends an episode
wherever the lander crosses that sphere (for about one dispersed start in six, [001]'s
unconstrained optimum dips a few metres under 2 km mid-flight and would be scored as a 1 km/s
crash; measured cost of the constraint there: < 0.01 kg), plus a smooth clearance
(:data:`GATE_CLEARANCE`) so the path does not graze the gate between nodes either.

- **Warm start**: :func:`solve_many` solves the cases in nearest-neighbour order; each case first
  tries direct shooting alone from the previous converged case's node controls (the dispersion
  is small, so the neighbour's optimum is an excellent guess), and falls back to the full serial
  strategy (GPM from the nominal guess, then shooting) when that does not converge.
- **Parallel**: ``n_workers > 1`` or an ``executor`` splits the chain into contiguous chunks,
  solved as keyed tasks (:func:`optimizers.common.executor.run_chunks`; each worker builds its
  NLPs once).
- **Problems built once**: :func:`env_ocp` and :func:`replan_ocp` keep one problem per scenario
  *fingerprint* (:func:`scenario_fingerprint`, a hash of the frozen scenario's repr): equal
  scenarios share it, and a scenario never receives another's problem (an ``id()`` key could,
  once the first scenario is garbage-collected and its id reused).
- **Storage** is the caller's: ``store(key, optimum)`` runs as soon as each case is solved, in
  the process that solved it (e.g. the on-disk cache of :mod:`optimizers.optimum.pinpoint`).

:class:`PinpointOptimum` holds a solution as the shooting's node controls (piecewise linear in
time, exactly the law the optimiser optimised) and the replayed states at the nodes, enough for
open-loop replays, start-state curricula and re-planning warm starts without re-solving.
"""

from __future__ import annotations

import dataclasses
import hashlib
import time
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lunar_env.scenarios import PinpointScenario

from ..common.warm_chain import solve_along_chain
from ..problems.pinpoint import PinpointOCP
from .serial import ControlGuess, get_solver, random_guess

__all__ = ["PinpointOptimum", "pinpoint_states", "solve_many", "solve_case", "replan",
           "env_ocp", "replan_ocp",
           "scenario_fingerprint", "nearest_neighbour_order", "SOLVER_OPTIONS",
           "GATE_CLEARANCE", "N_RANDOM_RETRIES"]

#: options of the serial solver used for the per-case optimum (those of [001]: N = 6, K = 5)
SOLVER_OPTIONS: dict[str, Any] = {"n_gauss": 6, "k_per_interval": 5, "n_rk4_per_segment": 1}
#: clearance above the gate sphere away from the target (:class:`PinpointOCP` floor_margin_*):
#: 100 m beyond ~5 km from the target, vanishing at it. Without it, an optimum that grazes the
#: gate mid-flight (1 dispersed case in 6) touches it between shooting nodes and the env ends
#: the episode there (measured on case 1 of seed 2026: a 956 m/s crash at 293 s open loop at
#: 0.25 s holds; with the clearance 2.2 m/s, 1.6 m miss, for +0.0008 kg of optimal fuel)
GATE_CLEARANCE = {"floor_margin_m": 100.0, "floor_margin_range_m": 5000.0}
#: random initial guesses tried after the warm start and the nominal guess failed
N_RANDOM_RETRIES = 2


@dataclass
class PinpointOptimum:
    """Minimum-fuel solution of one case (SI times, radians).

    Attributes
    ----------
    success : bool
        The solver converged and the problem's verdict on the replayed trajectory holds.
    fuel_kg, tf_s : float
        Optimal propellant (kg) and final time (s) (NaN when the solve failed).
    t_nodes_s : ndarray, shape (n,)
        Shooting node times (s), 0 … tf.
    controls_rad : ndarray, shape (n, 2)
        (α, β) (rad) at the nodes, linear in between.
    states_nd : ndarray, shape (n, 7)
        Normalised states at the nodes (compiled-RK4 replay of the law).
    message : str
    solve_s : float
        Wall time of the solve (s); a result read back from storage keeps its stored time.
    """

    success: bool
    fuel_kg: float
    tf_s: float
    t_nodes_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    controls_rad: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    states_nd: np.ndarray = field(default_factory=lambda: np.zeros((0, 7)))
    message: str = ""
    solve_s: float = float("nan")

    def angles_at(self, t_s) -> np.ndarray:
        """(α, β) (rad) at times ``t_s`` (s) (any shape -> shape + (2,)); held after tf and
        before 0.

        Raises
        ------
        ValueError
            For a failed solve (it has no control law).
        """
        if not self.success:
            raise ValueError(f"no optimal control for a failed case ({self.message})")
        t = np.clip(np.asarray(t_s, dtype=np.float64), self.t_nodes_s[0], self.t_nodes_s[-1])
        a = np.interp(t, self.t_nodes_s, self.controls_rad[:, 0])
        b = np.interp(t, self.t_nodes_s, self.controls_rad[:, 1])
        return np.stack([a, b], axis=-1)

    def mean_angles(self, t0_s: float, dt_s: float, n_sub: int = 8) -> np.ndarray:
        """(α, β) (rad), shape (2,): the law averaged over [t0, t0 + dt] (s) at ``n_sub``
        midpoints: the best constant action for an env step that holds it (second order, as
        :func:`optimizers.reproduce.peng2012.replay_in_env`)."""
        ts = t0_s + (np.arange(n_sub) + 0.5) / n_sub * dt_s
        return self.angles_at(ts).mean(axis=0)

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The fields as arrays (``numpy.savez``-ready; :meth:`from_arrays` reads them back)."""
        return {"success": np.array(self.success), "fuel_kg": np.array(self.fuel_kg),
                "tf_s": np.array(self.tf_s), "t_nodes_s": self.t_nodes_s,
                "controls_rad": self.controls_rad, "states_nd": self.states_nd,
                "message": np.array(self.message), "solve_s": np.array(self.solve_s)}

    @classmethod
    def from_arrays(cls, d) -> PinpointOptimum:
        """The optimum stored by :meth:`to_arrays` (a mapping of the same keys)."""
        return cls(bool(d["success"]), float(d["fuel_kg"]), float(d["tf_s"]),
                   np.asarray(d["t_nodes_s"], float), np.asarray(d["controls_rad"], float),
                   np.asarray(d["states_nd"], float), str(d["message"]), float(d["solve_s"]))


# ----------------------------------------------------------------------------- problems

#: problems built once per (kind, scenario fingerprint), the most recently used
#: :data:`MAX_CACHED_OCPS` kept (a process solving many plants would otherwise keep them all,
#: and with them their solvers' scenarios)
_OCPS: OrderedDict[tuple[str, str], PinpointOCP] = OrderedDict()
MAX_CACHED_OCPS = 16


def _cached_ocp(key: tuple[str, str], build: Callable[[], PinpointOCP]) -> PinpointOCP:
    if key not in _OCPS:
        _OCPS[key] = build()
    _OCPS.move_to_end(key)
    while len(_OCPS) > MAX_CACHED_OCPS:
        _OCPS.popitem(last=False)
    return _OCPS[key]


def scenario_fingerprint(scenario: PinpointScenario) -> str:
    """A stable hash (hex, 16 characters) of a frozen scenario: SHA-256 of its repr, which lists
    every field (floats exactly). Equal scenarios have the same fingerprint, in every process."""
    return hashlib.sha256(repr(scenario).encode()).hexdigest()[:16]


def env_ocp(scenario: PinpointScenario) -> PinpointOCP:
    """The landing env's optimal-control problem: [001]'s, with the path kept above the 2 km
    gate sphere (the env ends an episode wherever the lander crosses it; [001]'s optimum may dip
    below 2 km mid-flight for dispersed starts, which the env scores as a crash) and
    :data:`GATE_CLEARANCE`. Built once per scenario fingerprint (kept while among the
    :data:`MAX_CACHED_OCPS` most recently used)."""
    return _cached_ocp(("env", scenario_fingerprint(scenario)),
                       lambda: PinpointOCP(scenario, min_altitude_m=scenario.target.altitude_m,
                                           **GATE_CLEARANCE))


def replan_ocp(scenario: PinpointScenario) -> PinpointOCP:
    """The env's problem from a mid-flight state: :func:`env_ocp` with the final-time lower
    bound relaxed to 1 s ([001]'s 300 s bound is about the whole descent, not the time to go).
    Built once per scenario fingerprint, as :func:`env_ocp`."""
    def build() -> PinpointOCP:
        sc = dataclasses.replace(scenario, tf_bounds_s=(1.0, scenario.tf_bounds_s[1]))
        return PinpointOCP(sc, min_altitude_m=scenario.target.altitude_m, **GATE_CLEARANCE)

    return _cached_ocp(("replan", scenario_fingerprint(scenario)), build)


# ----------------------------------------------------------------------------- one case


def _from_result(result, solver, x0_nd: np.ndarray, wall_s: float) -> PinpointOptimum:
    s = solver.ocp.scaling
    ssol = result.extra.get("shooting_solution")
    if ssol is None or not result.success:
        return PinpointOptimum(False, float("nan"), float("nan"), message=result.message,
                               solve_s=wall_s)
    t_rep, x_rep = ssol.replay(solver.ocp, initial_state=x0_nd)
    m = int(ssol.n_rk4_per_segment)
    return PinpointOptimum(True, float(result.fuel_kg), float(result.tf_s),
                           np.asarray(ssol.t_nodes_nd) * s.time_s,
                           np.asarray(ssol.controls, float), np.asarray(x_rep[::m], float),
                           result.message, wall_s)


def solve_case(scenario: PinpointScenario, x0_nd: np.ndarray,
               warm: PinpointOptimum | None = None) -> PinpointOptimum:
    """Minimum-fuel optimum of :func:`env_ocp` from the normalised initial state ``x0_nd``.

    Direct shooting from ``warm``'s node controls first (when given and successful), the full
    serial strategy (GPM + shooting from the nominal guess) if that fails, then
    :data:`N_RANDOM_RETRIES` random guesses seeded by the state's bytes.

    Parameters
    ----------
    scenario : PinpointScenario
    x0_nd : ndarray, shape (7,)
        Normalised Moon-fixed state (position, velocity, mass) in the scenario's scaling.
    warm : PinpointOptimum, optional
        A neighbouring case's optimum.

    Returns
    -------
    PinpointOptimum
        ``success`` False when every attempt failed (non-convergence is a value).

    Raises
    ------
    ValueError
        ``x0_nd`` is not finite.
    """
    solver = get_solver(env_ocp(scenario), **SOLVER_OPTIONS)
    x0 = np.asarray(x0_nd, dtype=np.float64).reshape(7)
    if not np.all(np.isfinite(x0)):
        raise ValueError(f"initial state {x0!r} must be finite")
    t0 = time.perf_counter()
    if warm is not None and warm.success:
        t_ref = solver.ocp.scaling.time_s
        guess = ControlGuess(warm.tf_s / t_ref, warm.t_nodes_s / t_ref, warm.controls_rad)
        res = solver.solve_shooting_only(guess, initial_state=x0)
        if res.success:
            return _from_result(res, solver, x0, time.perf_counter() - t0)
    res = solver.solve(initial_state=x0)
    if not res.success:
        # decision: a grazing gate constraint sometimes stalls the shooting from the nominal
        # guess; a few random guesses inside the bounds (seeded by the state) usually converge
        seed = int.from_bytes(hashlib.sha256(x0.tobytes()).digest()[:4], "little")
        rng = np.random.default_rng(seed)
        for _ in range(N_RANDOM_RETRIES):
            res = solver.solve(random_guess(solver.ocp, rng), initial_state=x0)
            if res.success:
                break
    return _from_result(res, solver, x0, time.perf_counter() - t0)


def replan(scenario: PinpointScenario, state_nd: np.ndarray, plan: PinpointOptimum | None,
           elapsed_s: float, fallback: bool = True, max_iter: int | None = None
           ) -> PinpointOptimum:
    """Re-solve :func:`replan_ocp` from the current state ``state_nd`` (normalised, shape (7,)),
    warm-started from ``plan`` advanced by ``elapsed_s`` (s) (its node controls shifted, the
    nodes already flown dropped); the full serial strategy from the nominal guess if the warm
    shooting fails and ``fallback`` (measured on perturbed mid-flight states: that fallback
    rarely converges there and costs 10-25 s, so dataset restarts skip it). ``max_iter`` caps
    IPOPT's iterations (default the solver's 300; a converging warm re-plan takes ~10-60, a
    failing one runs to the cap). The returned plan's times start at 0 = now."""
    opts = dict(SOLVER_OPTIONS, **({} if max_iter is None else {"max_iter": int(max_iter)}))
    solver = get_solver(replan_ocp(scenario), **opts)
    x0 = np.asarray(state_nd, dtype=np.float64).reshape(7)
    t_ref = solver.ocp.scaling.time_s
    t0 = time.perf_counter()
    if plan is not None and plan.success and plan.tf_s - elapsed_s > 1.0:
        t = plan.t_nodes_s - elapsed_s
        keep = t > 0
        t_new = np.concatenate([[0.0], t[keep]])
        u_new = np.vstack([plan.angles_at(elapsed_s)[None], plan.controls_rad[keep]])
        guess = ControlGuess((plan.tf_s - elapsed_s) / t_ref, t_new / t_ref, u_new)
        res = solver.solve_shooting_only(guess, initial_state=x0)
        if res.success or not fallback:
            return _from_result(res, solver, x0, time.perf_counter() - t0)
    res = solver.solve(initial_state=x0)
    return _from_result(res, solver, x0, time.perf_counter() - t0)


# ----------------------------------------------------------------------------- many cases


def nearest_neighbour_order(states_nd: np.ndarray) -> np.ndarray:
    """Greedy nearest-neighbour chain through the rows of ``states_nd`` (n, 7), each feature
    standardised over the batch, starting at row 0.

    Returns
    -------
    ndarray of int, shape (n,)
    """
    n = len(states_nd)
    if n <= 2:
        return np.arange(n)
    feat = states_nd - states_nd.mean(axis=0)
    scale = feat.std(axis=0)
    feat = feat / np.where(scale > 0, scale, 1.0)
    left = list(range(1, n))
    order = [0]
    while left:
        d = np.sum((feat[left] - feat[order[-1]]) ** 2, axis=1)
        order.append(left.pop(int(np.argmin(d))))
    return np.asarray(order)


def pinpoint_states(states_nd) -> np.ndarray:
    """``states_nd`` as float64 rows of normalised pinpoint states, shape (n, 7).

    Raises
    ------
    ValueError
        Any other shape.
    """
    states = np.asarray(states_nd, dtype=np.float64)
    if states.ndim != 2 or states.shape[1] != 7:
        raise ValueError(f"states_nd has shape {states.shape}; expected (n, 7) normalised "
                         "pinpoint states")
    return states


def solve_many(scenario: PinpointScenario, states_nd, *, n_workers: int = 1, executor=None,
               progress: bool = True, store: Callable[[Any, PinpointOptimum], None] | None = None,
               store_keys: Sequence | None = None) -> list[PinpointOptimum]:
    """Per-case optima (:func:`solve_case`) of normalised initial states, in input order.

    The rows are chained by :func:`nearest_neighbour_order`; each is warm-started from the
    previous success in the chain.

    Parameters
    ----------
    scenario : PinpointScenario
    states_nd : array_like, shape (n, 7)
        Normalised Moon-fixed states (the env's ``state_nd``).
    n_workers : int
        1 solves in this process; more splits the chain into ``4 · n_workers`` chunks solved in
        spawned processes (at most one worker per 8 cases).
    executor : optimizers.common.executor.Executor, optional
        Runs the chunks instead (a Ray cluster, a shared local pool); the caller keeps
        ownership. Overrides ``n_workers``.
    progress : bool
        tqdm bar over the cases.
    store : callable, optional
        ``store(store_keys[i], optimum)`` for row i, called as soon as the row is solved, in the
        process that solved it: a module-level function when the rows go to workers (executors
        refuse closures).
    store_keys : sequence, optional
        One key per row (required with ``store``), e.g. a file path.

    Returns
    -------
    list of PinpointOptimum, length n, in the order of the input rows.

    Raises
    ------
    ValueError
        ``states_nd`` is not of shape (n, 7), ``n_workers < 1``, or ``store`` without one key
        per row.
    """
    return solve_along_chain(f"pinpoint-{scenario.name}", solve_case, scenario,
                             pinpoint_states(states_nd), nearest_neighbour_order,
                             n_workers=n_workers, executor=executor, progress=progress,
                             desc=f"per-case optimum {scenario.name}", store=store,
                             store_keys=store_keys)
