"""The touchdown family's optimum (``LunarPinpointLanding-v3``): the certified minimum-propellant
landing from each drawn state, cached on disk, and the campaigns' omniscient reference.

Each case is solved by **two independent methods** that must agree:

1. *direct*: Legendre–Gauss collocation with one phase per throttle arc
   (:mod:`optimizers.transcription.phased_gpm`), its arc structure found by removing arcs that
   do not exist (max–min–max for [001]'s start);
2. *indirect*: Pontryagin multi-arc shooting on that structure
   (:mod:`optimizers.indirect.touchdown`), started from the collocation's durations and its
   costate at touchdown (the terminal multipliers), with the minimum principle checked along
   the extremal (the switching function's sign on every arc, the elevation bound inactive).
   Where that extremal breaks the minimum principle and the collocation removed an arc, the
   full structure is shot again with the removed arc reinstated short: an extremal may hold
   an arc of a fraction of a second that the collocation cannot resolve;

and each is replayed by the reference integrator (DOP853) to the terminal conditions (within
:attr:`~optimizers.problems.touchdown.TouchdownOCP.tolerances`). A case is certified
(``success``) when both converged, both replays land, and their propellant agrees within
:data:`AGREEMENT_REL` (relative). Measured on [001]'s start: 277.575281348 kg by both, relative
difference 2e-14; replays within 3e-7 m and 3e-10 m/s of the target.

- **Cache** (:func:`touchdown_optima`): ``<cache_dir>/<key>.npz`` (written to a temporary file
  and renamed), ``key`` = SHA-256 of the cache format, the solver settings, the scenario's repr
  (its fingerprint) and the start's bytes; only missing cases are solved.
- **Batches**: the cases are chained by nearest neighbour and warm-started from the previous
  case's collocation; with workers or an executor the chain's chunks are keyed tasks
  (:func:`optimizers.common.executor.run_chunks`).
- **Family** (:class:`TouchdownOptimumFamily`): ``per_case_optimum`` through the cache and
  ``plant_optimum_fuel`` (each case's true engine from its true start; every case warm-started
  from the same nominal solution, so a case's reference does not depend on its batch).
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from lunar_env.scenarios import TouchdownScenario

from ..common.warm_chain import solve_along_chain
from ..indirect.touchdown import ARC_STEPS, TouchdownShooting
from ..indirect.touchdown import replay as replay_extremal
from ..problems.touchdown import MAX_MIN_MAX, TouchdownOCP
from ..transcription.batch import nearest_neighbour_order, pinpoint_states, scenario_fingerprint
from ..transcription.phased_gpm import (
    MIN_ARC_FLOOR_S,
    MIN_ARC_S,
    PhasedGaussPseudospectral,
    PhasedGuess,
    PhasedSolution,
    solve_structure,
)
from ..transcription.phased_gpm import replay as replay_collocation
from . import OptimumFamily, PerCaseOptimum, PlantOptimumFuel
from .cache import cache_key, cache_root, cached_optima

__all__ = ["TouchdownOptimum", "TouchdownOptimumFamily", "solve_touchdown_case",
           "solve_touchdown_many", "touchdown_optima", "touchdown_ocp", "default_cache_dir",
           "AGREEMENT_REL", "CACHE_FORMAT", "SOLVER_SETTINGS", "CERTIFIED"]

#: The largest relative propellant difference of the two methods for a certified case.
AGREEMENT_REL = 1e-6
#: bumped whenever the stored content or the solver pipeline changes (invalidates the cache)
CACHE_FORMAT = 3
#: the settings of both methods (part of the cache key)
SOLVER_SETTINGS = {"structure": [1.0, "min", 1.0], "n_nodes_last": 30, "n_nodes_other": 10,
                   "min_arc_s": MIN_ARC_S, "min_arc_floor_s": MIN_ARC_FLOOR_S,
                   "arc_steps": list(ARC_STEPS), "agreement_rel": AGREEMENT_REL}
#: the method label of a certified optimum
CERTIFIED = ("certified: phased LG collocation + Pontryagin multi-arc shooting "
             "(optimizers.optimum.touchdown)")

_GPM: PhasedGaussPseudospectral | None = None
_SHOOTING: TouchdownShooting | None = None
_OCPS: OrderedDict[str, TouchdownOCP] = OrderedDict()


def _solvers() -> tuple[PhasedGaussPseudospectral, TouchdownShooting]:
    """The process's two solvers (each keeps its built NLPs and shooting functions)."""
    global _GPM, _SHOOTING
    if _GPM is None:
        _GPM = PhasedGaussPseudospectral(n_nodes_last=SOLVER_SETTINGS["n_nodes_last"],
                                         n_nodes_other=SOLVER_SETTINGS["n_nodes_other"],
                                         min_arc_s=SOLVER_SETTINGS["min_arc_s"])
        _SHOOTING = TouchdownShooting(tuple(SOLVER_SETTINGS["arc_steps"]))
    return _GPM, _SHOOTING


def touchdown_ocp(scenario: TouchdownScenario) -> TouchdownOCP:
    """The problem of a scenario, built once per scenario fingerprint (the 16 most recent)."""
    key = scenario_fingerprint(scenario)
    if key not in _OCPS:
        _OCPS[key] = TouchdownOCP(scenario)
    _OCPS.move_to_end(key)
    while len(_OCPS) > 16:
        _OCPS.popitem(last=False)
    return _OCPS[key]


@lru_cache(maxsize=64)
def _legendre_gauss_cached(n: int) -> tuple[np.ndarray, np.ndarray]:
    from ..common.quadrature import legendre_gauss

    x, w = legendre_gauss(n)
    x.setflags(write=False)
    w.setflags(write=False)
    return x, w


def _legendre_gauss(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Legendre–Gauss points and weights of ``n`` nodes, computed once per ``n`` (a replay
    evaluates the law at every env step: the eigenvalue solve cost most of it)."""
    return _legendre_gauss_cached(n)


@dataclass
class TouchdownOptimum:
    """The certified minimum-propellant landing of one case (SI times).

    Attributes
    ----------
    success : bool
        Both methods converged, both DOP853 replays land, and their propellant agrees within
        :data:`AGREEMENT_REL`.
    fuel_kg, tf_s : float
        The collocation's propellant (kg) and final time (s) (NaN when not certified).
    fuel_indirect_kg : float
        The Pontryagin extremal's propellant (kg).
    fuel_rel_diff : float
        |direct − indirect| / indirect.
    levels : ndarray, shape (n_arcs,)
        Throttle of each arc.
    durations_s : ndarray, shape (n_arcs,)
        The collocation's arc durations (s).
    nodes : ndarray of int, shape (n_arcs,)
        LG points of each phase.
    directions : ndarray, shape (Σ nodes, 3)
        Orbital-frame thrust directions at the LG points, phase after phase.
    states_nd : ndarray, shape (Σ (nodes + 1), 7)
        Normalised states at each phase's start and LG points (a warm start).
    costate_0 : ndarray, shape (7,)
        The extremal's costate at the start (the extremal may hold an arc shorter than the
        collocation resolves, reinstated by the shooting: its structure is then
        :data:`~optimizers.problems.touchdown.MAX_MIN_MAX` while ``levels`` lack that arc).
    replay_errors : ndarray, shape (4,)
        DOP853 replays' position (m) and velocity (m/s) errors at touchdown: direct, then
        indirect.
    message : str
    solve_s : float
        Wall time of the solve (s); a result read from the cache keeps its stored time.
    """

    success: bool
    fuel_kg: float
    tf_s: float
    fuel_indirect_kg: float = math.nan
    fuel_rel_diff: float = math.nan
    levels: np.ndarray = field(default_factory=lambda: np.zeros(0))
    durations_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    directions: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    states_nd: np.ndarray = field(default_factory=lambda: np.zeros((0, 7)))
    costate_0: np.ndarray = field(default_factory=lambda: np.full(7, np.nan))
    replay_errors: np.ndarray = field(default_factory=lambda: np.full(4, np.nan))
    message: str = ""
    solve_s: float = math.nan

    # -- the control law ------------------------------------------------------------------------
    def _phase_arrays(self) -> tuple[list, list]:
        cut = np.cumsum(self.nodes)[:-1]
        dirs = np.split(self.directions, cut)
        cut_s = np.cumsum(self.nodes + 1)[:-1]
        return dirs, np.split(self.states_nd, cut_s)

    def controls_at(self, t_s, scenario: TouchdownScenario) -> np.ndarray:
        """(α, β, throttle) (rad, rad, fraction) of the law at times ``t_s`` (n,) (s since the
        start), held after touchdown; the collocation's control (each phase's Lagrange
        interpolant through its LG points).

        Raises
        ------
        ValueError
            For a case that is not certified (it has no law).
        """
        if not self.success:
            raise ValueError(f"no optimal control for an uncertified case ({self.message})")
        from ..common.quadrature import lagrange_interpolate

        t = np.clip(np.atleast_1d(np.asarray(t_s, dtype=float)), 0.0, self.tf_s)
        edges = np.concatenate([[0.0], np.cumsum(self.durations_s)])
        k = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, len(self.levels) - 1)
        dirs, _ = self._phase_arrays()
        e = np.empty((len(t), 3))
        for p, n in enumerate(self.nodes):
            sel = k == p
            if sel.any():
                tau = 2.0 * (t[sel] - edges[p]) / self.durations_s[p] - 1.0
                e[sel] = lagrange_interpolate(_legendre_gauss(int(n))[0], dirs[p], tau)
        e /= np.linalg.norm(e, axis=1)[:, None]
        ang = TouchdownOCP.angles_of(e)
        return np.column_stack([ang, self.levels[k]])

    def mean_controls(self, t0_s: float, dt_s: float, scenario: TouchdownScenario,
                      n_gauss: int = 4) -> np.ndarray:
        """(α, β, throttle), shape (3,): the law averaged over [t0, t0 + dt] (s) for an env step
        that holds one action: the mean thrust vector (throttle × direction), its direction
        and its length as the throttle. The step is split at the arcs' switches and each part
        integrated by ``n_gauss``-point Gauss–Legendre quadrature, so the step's propellant is
        the law's exactly and its impulse to the direction's curvature. (Sampling across a
        switch instead shifts it by up to half a sample: with 16 samples a step, 2 g of
        propellant and 1 cm/s at 10 s, 6 m at touchdown, measured.)"""
        t1_s = t0_s + dt_s
        edges = np.concatenate([[0.0], np.cumsum(self.durations_s)])
        cuts = np.concatenate([[t0_s], edges[(edges > t0_s) & (edges < t1_s)], [t1_s]])
        x, w = _legendre_gauss(int(n_gauss))
        ts, ws = [], []
        for a, b in zip(cuts[:-1], cuts[1:], strict=True):
            ts.append(a + (x + 1.0) * (b - a) / 2.0)
            ws.append(w * (b - a) / 2.0)
        ts, ws = np.concatenate(ts), np.concatenate(ws) / dt_s
        u = self.controls_at(ts, scenario)
        ca = np.cos(u[:, 0])
        vec = ((ws * u[:, 2])[:, None] * np.stack([np.sin(u[:, 0]), ca * np.cos(u[:, 1]),
                                                   ca * np.sin(u[:, 1])], axis=1)).sum(axis=0)
        thr = float(np.linalg.norm(vec))
        ang = TouchdownOCP.angles_of((vec / thr)[None])[0]
        return np.array([ang[0], ang[1], thr])

    def guess(self, scenario: TouchdownScenario) -> PhasedGuess:
        """The collocation as a warm start (same nodes)."""
        dirs, states = self._phase_arrays()
        return PhasedGuess(np.asarray(self.durations_s) / scenario.scaling().time_s,
                           [s.copy() for s in states], [d.copy() for d in dirs])

    # -- storage --------------------------------------------------------------------------------
    def to_arrays(self) -> dict[str, np.ndarray]:
        """The fields as arrays (``numpy.savez``-ready; :meth:`from_arrays` reads them)."""
        return {"success": np.array(self.success), "fuel_kg": np.array(self.fuel_kg),
                "tf_s": np.array(self.tf_s), "fuel_indirect_kg": np.array(self.fuel_indirect_kg),
                "fuel_rel_diff": np.array(self.fuel_rel_diff), "levels": self.levels,
                "durations_s": self.durations_s, "nodes": self.nodes,
                "directions": self.directions, "states_nd": self.states_nd,
                "costate_0": self.costate_0, "replay_errors": self.replay_errors,
                "message": np.array(self.message), "solve_s": np.array(self.solve_s)}

    @classmethod
    def from_arrays(cls, d) -> TouchdownOptimum:
        """The optimum stored by :meth:`to_arrays`."""
        return cls(bool(d["success"]), float(d["fuel_kg"]), float(d["tf_s"]),
                   float(d["fuel_indirect_kg"]), float(d["fuel_rel_diff"]),
                   np.asarray(d["levels"], float), np.asarray(d["durations_s"], float),
                   np.asarray(d["nodes"], np.int64), np.asarray(d["directions"], float),
                   np.asarray(d["states_nd"], float), np.asarray(d["costate_0"], float),
                   np.asarray(d["replay_errors"], float), str(d["message"]),
                   float(d["solve_s"]))


# ----------------------------------------------------------------------------- one case


def _failure(message: str, wall_s: float, **kw) -> TouchdownOptimum:
    return TouchdownOptimum(False, math.nan, math.nan, message=message, solve_s=wall_s, **kw)


def solve_touchdown_case(scenario: TouchdownScenario, x0_nd, warm: TouchdownOptimum | None = None,
                         *, thrust_scale: float = 1.0, isp_scale: float = 1.0
                         ) -> TouchdownOptimum:
    """The certified optimum from the normalised start ``x0_nd`` (7,) (see the module
    docstring), optionally with a true engine (thrust and Isp scales of the nominal one).

    ``warm``: a neighbouring case's optimum: the collocation starts from it when it has the
    full max–min–max structure; the cold start that finds the structure
    (:func:`~optimizers.transcription.phased_gpm.solve_structure`) follows when there is none,
    or when the warm solution is not certified.

    Returns
    -------
    TouchdownOptimum
        ``success`` False (never an exception) when a method fails or they disagree; the
        message says which.

    Raises
    ------
    ValueError
        ``x0_nd`` is not 7 finite numbers, or a scale is not finite and > 0.
    """
    x0 = np.asarray(x0_nd, dtype=np.float64).reshape(-1)
    if x0.shape != (7,) or not np.all(np.isfinite(x0)):
        raise ValueError(f"initial state {x0_nd!r} must be 7 finite normalised numbers")
    for name, v in (("thrust_scale", thrust_scale), ("isp_scale", isp_scale)):
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} = {v!r} must be finite and > 0")
    t_start = time.perf_counter()
    ocp = touchdown_ocp(scenario)
    gpm, shooting = _solvers()
    engine = {"thrust_nd": ocp.params.thrust_nd * thrust_scale,
              "exhaust_velocity_nd": ocp.params.exhaust_velocity_nd * isp_scale}
    full = ocp.levels(MAX_MIN_MAX)
    attempts = []
    if warm is not None and warm.success and tuple(warm.levels) == full:
        # a neighbour's collocation on the full structure; a neighbour whose structure lost an
        # arc is no guess for this case's (its arc may exist here)
        attempts.append(lambda: gpm.solve(ocp, MAX_MIN_MAX, guess=warm.guess(scenario),
                                          initial_state=x0, **engine))
    attempts.append(lambda: solve_structure(gpm, ocp, MAX_MIN_MAX, initial_state=x0, **engine))
    out = None
    for attempt in attempts:
        try:
            direct = attempt()
        except ValueError:  # a stored warm start of other nodes: the next attempt starts cold
            continue
        if not direct.success or direct.at_min.any():
            out = _failure(f"collocation: {direct.message}" if not direct.success else
                           "collocation: an arc at its minimum duration",
                           time.perf_counter() - t_start)
            continue
        out = _certify(ocp, shooting, direct, x0, engine, t_start)
        if out.success:
            return out
    return out


def _certify(ocp, shooting, direct: PhasedSolution, x0: np.ndarray, engine: dict,
             t_start: float) -> TouchdownOptimum:
    """The Pontryagin extremal from the collocation, both DOP853 replays and the verdict."""
    s = ocp.scaling
    kw = dict(levels=np.asarray(direct.levels, float),
              durations_s=direct.durations_nd * s.time_s,
              nodes=np.asarray([len(t) for t in direct.tau], np.int64),
              directions=np.vstack(direct.directions), states_nd=np.vstack(direct.states))
    rep_d = replay_collocation(ocp, direct, initial_state=x0, **engine)
    ext = shooting.solve(ocp, direct.levels, guess_durations_nd=direct.durations_nd,
                         guess_final_mass_nd=direct.final_state[6],
                         guess_costate_tf=direct.costate_tf, initial_state=x0, **engine)
    if not ext.success and not ext.switching_ok:
        # the collocation removes an arc it finds at its duration floor (MIN_ARC_FLOOR_S), yet
        # the extremal may hold it for a fraction of a second (a first full-thrust arc of
        # 0.03–0.2 s on 2 % of `standard` cases): the minimum principle then fails at the
        # removed arc's end, and the full structure with that arc reinstated short converges
        ext = _with_removed_arcs(ocp, shooting, ext, x0, engine) or ext
    rep_i = replay_extremal(ocp, ext, shooting, initial_state=x0) if ext.success else None
    errs = np.array([rep_d["terminal_errors"]["position_m"],
                     rep_d["terminal_errors"]["velocity_m_s"],
                     rep_i["terminal_errors"]["position_m"] if rep_i else np.nan,
                     rep_i["terminal_errors"]["velocity_m_s"] if rep_i else np.nan])
    rel = abs(direct.fuel_kg - ext.fuel_kg) / ext.fuel_kg if ext.success else math.nan
    wall = time.perf_counter() - t_start
    why = []
    if not rep_d["success"]:
        why.append(f"the collocation's DOP853 replay: {rep_d['message']}")
    if not ext.success:
        why.append(f"Pontryagin: {ext.message}")
    elif not rep_i["success"]:
        why.append(f"the extremal's DOP853 replay: {rep_i['message']}")
    if ext.success and not rel <= AGREEMENT_REL:
        why.append(f"the methods differ by {rel:.2e} of the propellant (> {AGREEMENT_REL:g})")
    common = dict(fuel_indirect_kg=float(ext.fuel_kg), fuel_rel_diff=float(rel),
                  costate_0=np.asarray(ext.costate_0, float), replay_errors=errs, **kw)
    if why:
        return _failure("; ".join(why), wall, **common)
    # the extremal's arcs: the collocation's, or those with a reinstated short arc
    arcs = ", ".join(f"{g:g} for {d:.2f} s" for g, d in zip(
        ext.levels, ext.durations_nd * s.time_s, strict=True))
    return TouchdownOptimum(True, float(direct.fuel_kg), float(direct.tf_s),
                            message=f"certified: throttle {arcs}; methods agree to {rel:.1e}",
                            solve_s=wall, **common)


def _embeddings(reduced: tuple, full: tuple) -> list[list[int]]:
    """Every way ``reduced`` (throttle levels) is ``full`` with arcs removed: the index in
    ``full`` of each reduced arc, earliest first."""
    out: list[list[int]] = []

    def place(i: int, start: int, acc: list[int]) -> None:
        if i == len(reduced):
            out.append(acc)
            return
        for j in range(start, len(full)):
            if full[j] == reduced[i]:
                place(i + 1, j + 1, [*acc, j])

    place(0, 0, [])
    return out


#: duration of a reinstated arc in the shooting's guess, as a fraction of its neighbour's (the
#: converged duration does not depend on it: 1e-5 to 1e-2 reach the same extremal)
REINSTATED_FRACTION = 1e-3


def _with_removed_arcs(ocp, shooting, ext, x0: np.ndarray, engine: dict):
    """The extremal of the full structure (:data:`MAX_MIN_MAX`) from ``ext``, an extremal of
    a structure with arcs removed, each removed arc reinstated at
    :data:`REINSTATED_FRACTION` of a neighbour's duration; the first placement that satisfies
    the minimum principle, else None."""
    full = ocp.levels(MAX_MIN_MAX)
    reduced = tuple(ext.levels)
    if len(reduced) >= len(full) or not np.all(np.isfinite(ext.durations_nd)):
        return None
    for placed in _embeddings(reduced, full):
        durations = np.zeros(len(full))
        durations[placed] = ext.durations_nd
        for j in range(len(full)):
            if j not in placed:
                near = min(placed, key=lambda i, j=j: abs(i - j))
                durations[j] = REINSTATED_FRACTION * durations[near]
                durations[near] -= durations[j]
        out = shooting.solve(ocp, MAX_MIN_MAX, guess_durations_nd=durations,
                             guess_final_mass_nd=ext.x[6], guess_costate_tf=ext.costate_tf,
                             initial_state=x0, **engine)
        if out.success:
            return out
    return None


# ----------------------------------------------------------------------------- many cases


def solve_touchdown_many(scenario: TouchdownScenario, states_nd, *, n_workers: int = 1,
                         executor=None, progress: bool = True, store=None,
                         store_keys=None) -> list[TouchdownOptimum]:
    """Certified optima of normalised starts ``states_nd`` (n, 7), in input order, solved along
    a nearest-neighbour chain (each warm-started from the previous certified case); with
    ``n_workers > 1`` or an ``executor`` the chain's chunks run as keyed tasks. ``store(key,
    optimum)`` runs in the solving process as each case is solved (a module-level function).

    Raises
    ------
    ValueError
        ``states_nd`` not of shape (n, 7), ``n_workers < 1``, or ``store`` without one key per
        row.
    """
    return solve_along_chain(f"touchdown-{scenario.name}", solve_touchdown_case, scenario,
                             pinpoint_states(states_nd), nearest_neighbour_order,
                             n_workers=n_workers, executor=executor, progress=progress,
                             desc=f"touchdown optimum {scenario.name}", store=store,
                             store_keys=store_keys)


# ----------------------------------------------------------------------------- cache


def default_cache_dir() -> Path:
    """``$LUNAR_CACHE_DIR/touchdown_optimum`` (default ``~/.cache/lunar-descent-guidance``)."""
    return cache_root("touchdown_optimum")


def _cache_key(scenario, x0_nd: np.ndarray) -> str:
    return cache_key({"format": CACHE_FORMAT, "settings": SOLVER_SETTINGS}, scenario, x0_nd)


def touchdown_optima(scenario: TouchdownScenario, states_nd, *, workers: int = 1,
                     cache_dir: str | Path | None = None, use_cache: bool = True,
                     progress: bool = True, executor=None) -> list[TouchdownOptimum]:
    """Certified optima of normalised starts ``states_nd`` (n, 7), in input order: read from
    the cache where stored, solved (:func:`solve_touchdown_many`) and stored otherwise.

    Parameters
    ----------
    scenario : TouchdownScenario
    states_nd : array_like, shape (n, 7)
    workers : int
        Local processes (1: this process).
    cache_dir : path, optional
        Default :func:`default_cache_dir`.
    use_cache : bool
        False: solve everything and write nothing.
    progress : bool
    executor : optimizers.common.executor.Executor, optional
        Runs the chunks (the workers write the cache: on several machines it must be shared).

    Raises
    ------
    ValueError
        ``states_nd`` is not of shape (n, 7), or ``workers < 1``.
    """
    states = pinpoint_states(states_nd)
    if int(workers) < 1:
        raise ValueError(f"workers = {workers!r} must be >= 1")
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    paths = [cache / f"{_cache_key(scenario, x)}.npz" if use_cache else None for x in states]
    return cached_optima(states, paths, TouchdownOptimum,
                         lambda rows, **kw: solve_touchdown_many(
                             scenario, rows, n_workers=workers, executor=executor,
                             progress=progress, **kw))


class TouchdownOptimumFamily(OptimumFamily):
    """The touchdown optimum (``scenario.family == "pinpoint_touchdown"``)."""

    def per_case_optimum(self, scenario, states_nd: np.ndarray, *, progress: bool = True,
                         workers: int = 1, executor=None) -> PerCaseOptimum:
        """The certified optimum from each drawn state (cached on disk)."""
        if progress:
            print(f"Per-case optimum of {len(states_nd)} states (collocation + Pontryagin, "
                  "cached)...", flush=True)
        t0 = time.perf_counter()
        sols = touchdown_optima(scenario, states_nd, workers=workers, progress=progress,
                                executor=executor)
        return PerCaseOptimum.from_solutions(sols, CERTIFIED, time.perf_counter() - t0)

    def plant_optimum_fuel(self, scenario, states_nd: np.ndarray, thrust_scale: np.ndarray,
                           isp_scale: np.ndarray, *, progress: bool = False
                           ) -> PlantOptimumFuel:
        """The certified optimum of each case with its true engine from its true start (both
        methods, the engine a parameter of the built problems), NaN where not certified. Every
        case starts from the nominal engine's optimum from the nominal start (one solve), so a
        case's reference does not depend on the other cases."""
        states = pinpoint_states(states_nd)
        x_nom = touchdown_ocp(scenario).x0_nd
        nominal = solve_touchdown_case(scenario, x_nom)
        fuel = np.full(len(states), np.nan)
        solver = [""] * len(states)
        it = range(len(states))
        if progress:
            from tqdm.auto import tqdm

            it = tqdm(it, desc="omniscient optimum (collocation + Pontryagin)", unit="case")
        for k in it:
            opt = solve_touchdown_case(scenario, states[k], nominal,
                                       thrust_scale=float(thrust_scale[k]),
                                       isp_scale=float(isp_scale[k]))
            if opt.success:
                fuel[k] = opt.fuel_kg
                solver[k] = CERTIFIED
        return PlantOptimumFuel(fuel, tuple(solver))

    def replan_ocp(self, scenario):
        """The touchdown problem (:class:`~optimizers.problems.touchdown.TouchdownOCP`) of the
        scenario; a re-plan passes the current state as the solvers' ``initial_state``."""
        return touchdown_ocp(scenario)
