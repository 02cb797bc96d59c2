"""ASAGA: adaptive simulated-annealing genetic algorithm ([000] Zhu & Xu 2007, §4).

The adaptive GA of [000] §4.1 with a simulated-annealing local search of the best children
embedded in every generation (§4.2–4.3), for box-bounded problems with a dynamic-penalty
fitness (eq. 11). See :class:`ASAGA` for the algorithm, its settings and every decision taken
where the paper is silent.
"""

from __future__ import annotations

import math
import os
import pickle
import time
from dataclasses import dataclass, field

import numpy as np

from .common.problem import Problem, PygmoProblem
from .common.result import OptimResult

__all__ = ["ASAGA", "ASAGAState", "paper_penalty_weights"]


def paper_penalty_weights(generation: int, n_generations: int) -> tuple[float, float]:
    """σ1, σ2 of [000] eq. (11): σ2 = max(1, 10^(2T/Tmax − 1)), σ1 = 5 σ2.

    σ2 grows from 1 (T ≤ Tmax/2) to 10 (T = Tmax), so the terminal constraints tighten.
    """
    sigma_radius = max(1.0, 10.0 ** (2.0 * generation / n_generations - 1.0))
    return 5.0 * sigma_radius, sigma_radius


@dataclass
class ASAGAState:
    """Everything needed to continue a run after generation ``generation`` (a checkpoint).

    Attributes
    ----------
    generation : int
        Last completed generation (0 before the first).
    X : ndarray, shape (n_pop, dim)
        Population (decision vectors).
    F : ndarray, shape (n_pop, n_f)
        Its raw fitness rows ``[obj, *ceq, *cin]`` (the penalty is recomputed from them each
        generation because its weights change).
    rng_state : dict
        ``numpy.random.Generator.bit_generator.state``.
    history : dict of str -> list
    n_fevals : int
    wall_s : float
        Wall time spent so far.
    """

    generation: int
    X: np.ndarray
    F: np.ndarray
    rng_state: dict
    history: dict = field(default_factory=dict)
    n_fevals: int = 0
    wall_s: float = 0.0


class ASAGA:
    """Adaptive simulated-annealing genetic algorithm (ASAGA).

    Paper: Zhu J., Xu S. "Optimization of lunar soft landing trajectory based on adaptive
    simulated annealing genetic algorithm", Acta Aeronautica et Astronautica Sinica 28(4),
    806–812, 2007 ([000]). One generation T = 1 … Tmax (§4.3):

    1. Penalised fitness f of every individual (eq. 11 via ``problem.penalty_fitness``, weights
       σ1 = 5σ2, σ2 = max(1, 10^(2T/Tmax − 1))); record the best individual.
    2. Stretch ``f' = exp[−(f_max − f)/T_i]`` (eq. 22) with the temperature
       ``T_i = T0 κ^(T−1)`` (eq. 19); roulette selection of ``n_pop`` individuals on f'; random
       pairs; crossover (eq. 12) with probability Pc (eq. 15) and coefficient r (eq. 16), children
       outside the bounds re-crossed up to ``n_recross_max`` times, then clipped (eq. 13);
       per-parameter mutation (eq. 14) with probability Pm (eq. 17) and coefficient k (eq. 18).
    3. Evaluate the children; the best ``n_anneal`` are each annealed: every parameter is
       perturbed (eq. 20, δ = 0.5·[1 − (T−1)/Tmax]) and the move accepted by the Metropolis rule
       (eq. 21); repeated while ``n_accepted < n_accept_min`` and ``n_inner < n_inner_max``.
       The annealed individuals replace the ``n_anneal`` worst children.
    4. Elitism: a randomly chosen child is replaced by the best individual recorded in 1.
    5. Cool and repeat until Tmax.

    Parameters (defaults are the paper's settings, [000] §5)
    ----------
    n_pop : int
        Population size M (20).
    n_generations : int
        Number of generations Tmax (300).
    t0 : float
        Initial annealing temperature T0 (10000).
    kappa : float
        Cooling factor κ of eq. (19) (0.97).
    n_accept_min : int
        N_min: the annealing of an individual stops after this many accepted moves (10).
    n_inner_max : int
        C_max: ... or after this many inner iterations (10).
    n_anneal : int
        n0: number of best children annealed each generation (2).
    n_recross_max : int
        R_max: re-crossings of a pair whose children leave the bounds before clipping (10).
    pc1, pc2 : float
        Crossover probability Pc1 − Pc2·… (eq. 15) (0.9, 0.2).
    r1_start, r1_slope, r2 : float
        Crossover coefficient r1 = r1_start − r1_slope·T/Tmax, r2 (eq. 16) (0.5, 0.25, 0.5).
    pm1, pm2 : float
        Mutation probability (eq. 17) (0.01, 0.005).
    k1_start, k1_slope, k2 : float
        Mutation coefficient k1 = k1_start − k1_slope·T/Tmax, k2 (eq. 18) (0.5, 0.4, 0.5).
    delta_start : float
        δ(T_i) = delta_start·[1 − (T − 1)/Tmax] of eq. (20) (0.5).
    penalty_weights : callable, optional
        ``(generation, n_generations) -> (σ_velocity, σ_radius)``; default
        :func:`paper_penalty_weights`.
    verbose : int
        0 silent; N > 0 prints a progress line every N generations.
    progress_bar : bool
        Show a tqdm progress bar.

    Examples
    --------
    >>> from optimizers.asaga import ASAGA
    >>> from optimizers.problems import PlanarLandingProblem
    >>> res = ASAGA(n_generations=5).solve(PlanarLandingProblem(), seed=0)
    >>> sorted(res.terminal_errors)
    ['radial_velocity_m_s', 'radius_m', 'speed_m_s', 'tangential_velocity_m_s']

    As a pygmo algorithm: ``pygmo.algorithm(ASAGA()).evolve(pop)`` with
    ``pop = pygmo.population(problem.to_pygmo(), size=20)``.

    Decisions where the paper is silent or ambiguous
    ------------------------------------------------
    - *Generation counter.* T runs 1 … Tmax, so T_i = T0 at the first generation (eq. 19) and
      δ = 0.5 then (its maximum, §5).
    - *Crossover* (eq. 12): one pair of scalars α, β ~ U(0, r) per pair and attempt, applied to
      the whole vectors (arithmetic crossover of the paper's ref. [11]). Note that the children
      are not convex combinations: with A = B, A' = (1 − α + β)A. A pair is re-crossed (new α, β)
      while any of its two children leaves the bounds, at most ``n_recross_max`` times; then the
      last attempt is clipped (eq. 13).
    - *Which fitness enters eq. (15)–(18).* The raw (not stretched) penalised fitness, with
      f_max and f_avg over the current population. f_c is the larger fitness of the pair. The
      paper mutates after crossover but does not evaluate in between, so f_m of a child is the
      fitness of the parent it mostly descends from (A for A', B for B'; itself if not crossed).
      When f_max = f_avg the ratios are taken as for f_c = f_max (Pc = Pc1 − Pc2, r = r1,
      Pm = Pm1 − Pm2, k = k1).
    - *Mutation* (eq. 14): each parameter of each child mutates independently with probability
      Pm, with its own coin and γ.
    - *Annealing* (eq. 20–21): each of the n0 individuals has its own counters n_a, n_c (the
      paper resets them once and then says "respectively" for each individual); the n0 run in
      parallel (one batched evaluation per inner iteration). The individual *after* annealing
      (the current SA state, not the best state visited) replaces a worst child, as written.
    - *Best individual.* The result is the best of the final population under the final
      penalty weights (the recorded elite is always in it).

    - *Units of the fitness* (``fitness_units``). Eq. (11) is written after the normalisation of
      §2, so the default evaluates it in normalised units (m(tf)/m0, velocities / sqrt(μ/r0),
      radius / r0). ``"si"`` evaluates the same expression in kg, m/s and m: the reading under
      which T0 = 10000 has the size of the early penalties.

    Measured behaviour (``python -m optimizers.reproduce zhu2007 [--fitness-units si]``, 10
    runs × 300 generations, ~12 000 evaluations each): the paper's accuracy does **not**
    reproduce. Normalised fitness: 0/10 runs converge (|dV| 0.3–3.2 m/s, final radius 2.6–20 km
    high, fuel 274.4–277.3 kg: below the optimum because they do not land). SI fitness: 0/10
    (1/10 with another random stream; |dV| 0.5–87 m/s, |dr| < 4 m, fuel up to 3 kg above the
    optimum). The same budget suffices for pygmo's CMA-ES on the same penalty (8/10 land,
    ``benchmarks/bench_optimizers.py``), so the problem is not the obstacle.
    Why, as measured (``extra["history_anneal_acceptance"]``): with the normalised fitness
    (O(1), m(tf)/m0 ≈ 0.54) T_i = 10000·0.97^(T−1) ≥ 1.1 makes the Metropolis rule accept
    97–100 % of the annealing moves (a random walk) and the stretching of eq. (22) flat
    (selection nearly uniform); with the SI fitness acceptance falls to ~0 after generation
    100 (greedy) but no operator makes moves fine enough: eq. (12) multiplies near-equal
    parents by (1 − α + β), i.e. tf by up to ±r·600 s; eq. (14) moves by k ≥ 0.1 of the
    range; eq. (20) by up to δ ≥ 0.0017 of the range in all 11 parameters at once (0.3 s of tf
    in the last generation, worth ~1 m/s of terminal speed). With 1000–3000 generations the
    SI variant reaches 0.03–0.6 m/s and |dr| < 0.5 m, at fuel 0.2–1.8 kg above the optimum.
    """

    def __init__(self, n_pop: int = 20, n_generations: int = 300, t0: float = 10000.0,
                 kappa: float = 0.97, n_accept_min: int = 10, n_inner_max: int = 10,
                 n_anneal: int = 2, n_recross_max: int = 10, pc1: float = 0.9, pc2: float = 0.2,
                 r1_start: float = 0.5, r1_slope: float = 0.25, r2: float = 0.5,
                 pm1: float = 0.01, pm2: float = 0.005, k1_start: float = 0.5,
                 k1_slope: float = 0.4, k2: float = 0.5, delta_start: float = 0.5,
                 penalty_weights=None, fitness_units: str = "normalised",
                 anneal_result: str = "current", verbose: int = 0,
                 progress_bar: bool = False) -> None:
        ints = dict(n_pop=n_pop, n_generations=n_generations, n_accept_min=n_accept_min,
                    n_inner_max=n_inner_max, n_anneal=n_anneal, n_recross_max=n_recross_max)
        for name, v in ints.items():
            if int(v) != v or v < 0:
                raise ValueError(f"{name} = {v!r} must be a non-negative integer")
        if n_pop < 2 or n_pop % 2:
            raise ValueError(f"n_pop = {n_pop} must be an even number >= 2 (pairs are crossed)")
        if n_generations < 1:
            raise ValueError(f"n_generations = {n_generations} must be >= 1")
        if n_anneal > n_pop:
            raise ValueError(f"n_anneal = {n_anneal} cannot exceed n_pop = {n_pop}")
        if not t0 > 0 or not 0 < kappa <= 1:
            raise ValueError(f"need t0 > 0 and 0 < kappa <= 1; got t0={t0!r}, kappa={kappa!r}")
        for name, v in dict(pc1=pc1, pc2=pc2, pm1=pm1, pm2=pm2).items():
            if not 0 <= v <= 1:
                raise ValueError(f"{name} = {v!r} must be a probability in [0, 1]")
        self.n_pop = int(n_pop)
        self.n_generations = int(n_generations)
        self.t0 = float(t0)
        self.kappa = float(kappa)
        self.n_accept_min = int(n_accept_min)
        self.n_inner_max = int(n_inner_max)
        self.n_anneal = int(n_anneal)
        self.n_recross_max = int(n_recross_max)
        self.pc1, self.pc2 = float(pc1), float(pc2)
        self.r1_start, self.r1_slope, self.r2 = float(r1_start), float(r1_slope), float(r2)
        self.pm1, self.pm2 = float(pm1), float(pm2)
        self.k1_start, self.k1_slope, self.k2 = float(k1_start), float(k1_slope), float(k2)
        self.delta_start = float(delta_start)
        self.penalty_weights = penalty_weights or paper_penalty_weights
        if fitness_units not in ("normalised", "si"):
            raise ValueError(f"fitness_units = {fitness_units!r}; use 'normalised' or 'si'")
        self.fitness_units = fitness_units
        if anneal_result not in ("current", "best"):
            raise ValueError(f"anneal_result = {anneal_result!r}; use 'current' or 'best'")
        self.anneal_result = anneal_result
        self.verbose = int(verbose)
        self.progress_bar = bool(progress_bar)

    def __repr__(self) -> str:
        return (f"ASAGA(n_pop={self.n_pop}, n_generations={self.n_generations}, t0={self.t0}, "
                f"kappa={self.kappa}, n_accept_min={self.n_accept_min}, "
                f"n_inner_max={self.n_inner_max}, n_anneal={self.n_anneal}, "
                f"n_recross_max={self.n_recross_max})")

    # ---- schedules ------------------------------------------------------------------------
    def temperature(self, generation: int) -> float:
        """T_i = T0 κ^(T−1), eq. (19)."""
        return self.t0 * self.kappa ** (generation - 1)

    def delta(self, generation: int) -> float:
        """Annealing step δ(T_i) = 0.5 [1 − (T−1)/Tmax] ([000] §5)."""
        return self.delta_start * (1.0 - (generation - 1) / self.n_generations)

    # ---- penalty ----------------------------------------------------------------------------
    def _fitness(self, problem, F: np.ndarray, generation: int) -> np.ndarray:
        s_v, s_r = self.penalty_weights(generation, self.n_generations)
        if hasattr(problem, "penalty_fitness"):
            return problem.penalty_fitness(F, s_v, s_r, units=self.fitness_units)
        # generic problems: −obj − σ1·‖ceq‖ − σ2·Σ max(0, cin)
        nec = problem.get_nec()
        ceq = F[:, 1:1 + nec]
        cin = np.maximum(F[:, 1 + nec:], 0.0)
        return -F[:, 0] - s_v * np.linalg.norm(ceq, axis=1) - s_r * cin.sum(axis=1)

    # ---- operators (public for testing) -----------------------------------------------------
    @staticmethod
    def _ratio(num, den):
        den = np.asarray(den, dtype=float)
        safe = np.where(den > 0, den, 1.0)
        return np.where(den > 0, num / safe, 1.0)

    def adaptive_rates(self, f_ind: np.ndarray, f_max: float, f_avg: float, generation: int,
                       kind: str) -> tuple[np.ndarray, np.ndarray]:
        """Probabilities and coefficients of eq. (15)–(18).

        ``kind="crossover"``: f_ind = f_c → (Pc, r); ``kind="mutation"``: f_ind = f_m → (Pm, k).
        """
        frac_t = generation / self.n_generations
        f_ind = np.asarray(f_ind, dtype=float)
        above = f_ind >= f_avg
        up = np.clip(self._ratio(f_ind - f_avg, f_max - f_avg), 0.0, 1.0)
        down = np.clip(self._ratio(f_max - f_ind, f_max - f_avg), 0.0, 1.0)
        down = np.where(f_max - f_avg > 0, down, 0.0)
        if kind == "crossover":
            p1, p2 = self.pc1, self.pc2
            c1, c2 = self.r1_start - self.r1_slope * frac_t, self.r2
        elif kind == "mutation":
            p1, p2 = self.pm1, self.pm2
            c1, c2 = self.k1_start - self.k1_slope * frac_t, self.k2
        else:
            raise ValueError(f"kind = {kind!r}; use 'crossover' or 'mutation'")
        prob = np.where(above, p1 - p2 * up, p1)
        coef = np.where(above, c1 + c2 * down, c1 + c2)
        return prob, coef

    def crossover(self, A: np.ndarray, B: np.ndarray, r: np.ndarray, lb: np.ndarray,
                  ub: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Eq. (12)–(13) for pairs (A[i], B[i]) with coefficients r[i]; returns (A', B').

        Re-crossing of pairs with a child out of bounds, then clipping.
        """
        # all R_max + 1 attempts drawn at once; each pair keeps its first attempt whose two
        # children are inside the bounds (same law as re-crossing one attempt at a time)
        n_try = self.n_recross_max + 1
        alpha = rng.uniform(0.0, 1.0, (n_try, A.shape[0]))[..., None] * r[None, :, None]
        beta = rng.uniform(0.0, 1.0, (n_try, A.shape[0]))[..., None] * r[None, :, None]
        a = (1.0 - alpha) * A[None] + beta * B[None]
        b = (1.0 - beta) * B[None] + alpha * A[None]
        ok = (((a >= lb) & (a <= ub)).all(axis=2) & ((b >= lb) & (b <= ub)).all(axis=2))
        first = np.where(ok.any(axis=0), ok.argmax(axis=0), n_try - 1)
        cols = np.arange(A.shape[0])
        self._n_clipped = int((~ok.any(axis=0)).sum())
        return np.clip(a[first, cols], lb, ub), np.clip(b[first, cols], lb, ub)

    def mutate(self, C: np.ndarray, pm: np.ndarray, k: np.ndarray, lb: np.ndarray,
               ub: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Eq. (14), each parameter of row i with probability pm[i] and coefficient k[i]."""
        hit = rng.random(C.shape) < pm[:, None]
        coin = rng.integers(0, 2, size=C.shape).astype(bool)
        gamma = rng.random(C.shape)
        up = C + k[:, None] * gamma * (ub - C)
        down = C - k[:, None] * gamma * (C - lb)
        out = np.where(hit, np.where(coin, down, up), C)
        return np.clip(out, lb, ub)  # only guards round-off: k ≤ 1 keeps eq. (14) inside

    def neighbour(self, Y: np.ndarray, delta: float, lb: np.ndarray, ub: np.ndarray,
                  rng: np.random.Generator) -> np.ndarray:
        """Annealing move of eq. (20): every parameter perturbed toward a random bound."""
        coin = rng.integers(0, 2, size=Y.shape).astype(bool)
        xi = rng.random(Y.shape)
        out = np.where(coin, Y - (Y - lb) * delta * xi, Y + (ub - Y) * delta * xi)
        return np.clip(out, lb, ub)

    @staticmethod
    def roulette(weights: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
        """Indices of ``n`` roulette-wheel draws with probabilities ∝ ``weights``."""
        w = np.asarray(weights, dtype=float)
        total = w.sum()
        if not np.isfinite(total) or total <= 0:
            return rng.integers(0, w.size, size=n)
        return rng.choice(w.size, size=n, p=w / total)

    # ---- main loop ------------------------------------------------------------------------
    def solve(self, problem: Problem, *, seed: int | np.random.Generator | None = None,
              x0: np.ndarray | None = None, return_trajectory: bool = False,
              checkpoint: str | os.PathLike | None = None, checkpoint_every: int = 25,
              callback=None) -> OptimResult:
        """Run ASAGA on ``problem``.

        Parameters
        ----------
        problem : Problem
            Box-bounded problem; ``penalty_fitness(F, σ_v, σ_r)`` (maximised) is used when the
            problem has it (e.g. :class:`~optimizers.problems.PlanarLandingProblem`, eq. 11),
            otherwise ``−obj − σ1‖ceq‖ − σ2 Σ max(0, cin)``.
        seed : int or numpy.random.Generator, optional
            Randomness (the run is deterministic for a given seed).
        x0 : ndarray, shape (n_pop, dim), optional
            Initial population (default: uniform in the bounds, [000] step 1).
        return_trajectory : bool
            Decode the best vector into ``result.trajectory`` (needs ``problem.decode``).
        checkpoint : path, optional
            Pickle file of an :class:`ASAGAState`. If it exists the run **resumes** from it
            (same seed stream, so an interrupted and resumed run equals an uninterrupted one);
            it is rewritten every ``checkpoint_every`` generations and at the end.
        callback : callable, optional
            ``callback(generation, state_dict) -> bool``; returning True stops the run.

        Returns
        -------
        OptimResult
            ``x``, ``fuel_kg`` and ``tf_s`` (when the problem knows them), SI
            ``terminal_errors``, ``history`` (best penalised fitness per generation), and in
            ``extra``: ``history_fuel_kg``, ``history_speed_m_s``, ``history_radius_m``,
            ``history_mean_fitness``, ``history_anneal_acceptance`` (fraction of annealing moves
            accepted), ``history_clipped_pairs`` (fraction of crossed pairs clipped after
            ``n_recross_max`` re-crossings), ``n_generations``, ``fitness`` (final penalised),
            ``F`` (raw fitness row).
        """
        t_start = time.perf_counter()
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        lb, ub = (np.asarray(b, dtype=float) for b in problem.get_bounds())
        dim = lb.size
        n_fevals0 = problem.n_fevals
        state = None
        if checkpoint is not None and os.path.exists(checkpoint):
            with open(checkpoint, "rb") as fh:
                state = pickle.load(fh)
            if state.X.shape != (self.n_pop, dim):
                raise ValueError(f"checkpoint {os.fspath(checkpoint)!r} holds a population of "
                                 f"shape {state.X.shape}; this run needs ({self.n_pop}, {dim})")
            rng.bit_generator.state = state.rng_state
        if state is None:
            if x0 is None:
                X = lb + (ub - lb) * rng.random((self.n_pop, dim))
            else:
                X = np.array(x0, dtype=float)
                if X.shape != (self.n_pop, dim):
                    raise ValueError(f"x0 has shape {X.shape}; expected ({self.n_pop}, {dim})")
                X = np.clip(X, lb, ub)
            F = problem.batch_fitness(X)
            hist = {k: [] for k in ("fitness", "fuel_kg", "speed_m_s", "radius_m",
                                    "mean_fitness", "anneal_acceptance", "clipped_pairs")}
            state = ASAGAState(0, X, F, rng.bit_generator.state, hist, 0, 0.0)
        n_fevals_prev = state.n_fevals
        wall_prev = state.wall_s
        X, F, hist = state.X, state.F, state.history

        bar = None
        if self.progress_bar:
            from tqdm.auto import tqdm
            bar = tqdm(total=self.n_generations, initial=state.generation, desc="ASAGA",
                       leave=False)
        stopped = False
        T = state.generation
        for T in range(state.generation + 1, self.n_generations + 1):
            X, F = self._generation(problem, X, F, T, lb, ub, rng, hist)
            if bar is not None:
                bar.update(1)
                bar.set_postfix(fitness=f"{hist['fitness'][-1]:.6f}")
            if self.verbose and (T % self.verbose == 0 or T == self.n_generations):
                print(f"ASAGA gen {T:4d}/{self.n_generations}: best fitness "
                      f"{hist['fitness'][-1]:.7f} fuel {hist['fuel_kg'][-1]:.4f} kg "
                      f"|dV| {hist['speed_m_s'][-1]:.3g} m/s dr {hist['radius_m'][-1]:.3g} m")
            if checkpoint is not None and (T % checkpoint_every == 0 or T == self.n_generations):
                self._save(checkpoint, T, X, F, rng, hist,
                           n_fevals_prev + problem.n_fevals - n_fevals0,
                           wall_prev + time.perf_counter() - t_start)
            if callback is not None and callback(T, {"X": X, "F": F, "history": hist}):
                stopped = True
                break
        if bar is not None:
            bar.close()

        g_final = max(T, 1)
        f = self._fitness(problem, F, g_final)
        i = int(np.argmax(f))
        x_best = X[i].copy()
        wall = wall_prev + time.perf_counter() - t_start
        n_fevals = n_fevals_prev + problem.n_fevals - n_fevals0
        err = self._errors(problem, F[i:i + 1])
        fuel = float(problem.fuel_kg_from_fitness(F[i:i + 1])[0]) if hasattr(
            problem, "fuel_kg_from_fitness") else float(F[i, 0])
        success = bool(err.get("speed_m_s", 0.0) < 0.5 and abs(err.get("radius_m", 0.0)) < 1.0)
        msg = "stopped by callback" if stopped else f"completed {g_final} generations"
        if "speed_m_s" in err:
            msg += ("; terminal conditions met (|dV| < 0.5 m/s, |dr| < 1 m)" if success
                    else "; terminal conditions NOT met (|dV| >= 0.5 m/s or |dr| >= 1 m)")
        traj = None
        if return_trajectory:
            traj = problem.decode(x_best)["trajectory"]
        extra = {f"history_{k}": np.asarray(v) for k, v in hist.items() if k != "fitness"}
        extra.update(n_generations=g_final, fitness=float(f[i]), F=F[i].copy(),
                     population=X.copy())
        return OptimResult(x=x_best, fuel_kg=fuel, tf_s=float(x_best[-1]),
                           terminal_errors=err, history=np.asarray(hist["fitness"]),
                           n_fevals=int(n_fevals), wall_s=wall, success=success, message=msg,
                           trajectory=traj, extra=extra)

    def _errors(self, problem, F_row: np.ndarray) -> dict[str, float]:
        if hasattr(problem, "velocity_scale_m_s"):
            dvr = float(F_row[0, 1] * problem.velocity_scale_m_s)
            dvt = float(F_row[0, 2] * problem.velocity_scale_m_s)
            return {"radial_velocity_m_s": dvr, "tangential_velocity_m_s": dvt,
                    "speed_m_s": math.hypot(dvr, dvt),
                    "radius_m": float(F_row[0, 3] * problem.radius_scale_m)}
        return {f"c{j}": float(v) for j, v in enumerate(F_row[0, 1:])}

    def _save(self, path, T, X, F, rng, hist, n_fevals, wall) -> None:
        st = ASAGAState(T, X.copy(), F.copy(), rng.bit_generator.state,
                        {k: list(v) for k, v in hist.items()}, int(n_fevals), float(wall))
        tmp = f"{os.fspath(path)}.tmp"
        with open(tmp, "wb") as fh:
            pickle.dump(st, fh)
        os.replace(tmp, path)

    def _generation(self, problem, X, F, T, lb, ub, rng, hist):
        """One generation (steps 2–5 of [000] §4.3); returns the next (X, F)."""
        n = self.n_pop
        temp = self.temperature(T)
        # (2) fitness under this generation's penalty, record the best, stretch, select
        f = self._fitness(problem, F, T)
        ib = int(np.argmax(f))
        x_best, F_best = X[ib].copy(), F[ib].copy()
        f_max, f_avg = float(f[ib]), float(f.mean())
        err = self._errors(problem, F[ib:ib + 1])
        hist["fitness"].append(f_max)
        hist["mean_fitness"].append(f_avg)
        hist["fuel_kg"].append(float(problem.fuel_kg_from_fitness(F[ib:ib + 1])[0])
                               if hasattr(problem, "fuel_kg_from_fitness") else float(F[ib, 0]))
        hist["speed_m_s"].append(err.get("speed_m_s", float("nan")))
        hist["radius_m"].append(err.get("radius_m", float("nan")))
        stretched = np.exp(-(f_max - f) / temp)
        sel = self.roulette(stretched, n, rng)
        sel = sel[rng.permutation(n)]
        ia, ibb = sel[0::2], sel[1::2]
        A, B = X[ia], X[ibb]
        fa, fb = f[ia], f[ibb]
        # crossover, eq. (12), (13), (15), (16)
        pc, r = self.adaptive_rates(np.maximum(fa, fb), f_max, f_avg, T, "crossover")
        cross = rng.random(ia.size) < pc
        A2, B2 = A.copy(), B.copy()
        self._n_clipped = 0
        if np.any(cross):
            a, b = self.crossover(A[cross], B[cross], r[cross], lb, ub, rng)
            A2[cross], B2[cross] = a, b
        children = np.concatenate([A2, B2])
        f_parent = np.concatenate([fa, fb])
        # mutation, eq. (14), (17), (18), per parameter
        pm, k = self.adaptive_rates(f_parent, f_max, f_avg, T, "mutation")
        children = self.mutate(children, pm, k, lb, ub, rng)
        hist["clipped_pairs"].append(self._n_clipped / max(1, int(cross.sum())))
        # (3) evaluate children, anneal the best n0, replace the n0 worst
        Fc = problem.batch_fitness(children)
        fc = self._fitness(problem, Fc, T)
        if self.n_anneal > 0:
            order = np.argsort(-fc, kind="stable")
            best_idx = order[:self.n_anneal]
            Y, FY, fY = children[best_idx].copy(), Fc[best_idx].copy(), fc[best_idx].copy()
            Yb, FYb, fYb = Y.copy(), FY.copy(), fY.copy()
            n_a = np.zeros(self.n_anneal, dtype=int)
            n_c = np.zeros(self.n_anneal, dtype=int)
            active = np.ones(self.n_anneal, dtype=bool)
            d = self.delta(T)
            n_moves = 0
            while np.any(active):
                idx = np.flatnonzero(active)
                Yn = self.neighbour(Y[idx], d, lb, ub, rng)
                Fn = problem.batch_fitness(Yn)
                fn = self._fitness(problem, Fn, T)
                with np.errstate(over="ignore"):
                    p_acc = np.where(fn >= fY[idx], 1.0, np.exp(-(fY[idx] - fn) / temp))
                acc = rng.random(idx.size) < p_acc
                n_moves += idx.size
                j = idx[acc]
                Y[j], FY[j], fY[j] = Yn[acc], Fn[acc], fn[acc]
                n_a[j] += 1
                better = j[fY[j] > fYb[j]]
                Yb[better], FYb[better], fYb[better] = Y[better], FY[better], fY[better]
                cont = (n_a[idx] < self.n_accept_min) & (n_c[idx] < self.n_inner_max)
                n_c[idx[cont]] += 1
                active[idx[~cont]] = False
            hist["anneal_acceptance"].append(int(n_a.sum()) / max(1, n_moves))
            worst = np.argsort(fc, kind="stable")[:self.n_anneal]
            if self.anneal_result == "best":
                Y, FY = Yb, FYb
            children[worst], Fc[worst] = Y, FY
        # (4) elitism: a random child becomes the recorded best
        j = int(rng.integers(0, n))
        children[j], Fc[j] = x_best, F_best
        return children, Fc

    # ---- pygmo user-defined algorithm ------------------------------------------------------
    def get_name(self) -> str:
        return "ASAGA (Zhu & Xu 2007)"

    def set_verbosity(self, level: int) -> None:
        self.verbose = int(level)

    def set_seed(self, seed: int) -> None:
        self._uda_seed = int(seed)

    def evolve(self, pop):
        """pygmo UDA entry point: ``pygmo.algorithm(ASAGA(...)).evolve(pop)``.

        The population size must equal ``n_pop``. If the population's problem wraps one of ours
        (:class:`~optimizers.common.problem.PygmoProblem`) its batched fitness and penalty are
        used; otherwise pygmo's ``fitness`` is called per individual with the generic penalty.
        """
        prob = pop.problem
        inner = prob.extract(PygmoProblem)
        problem = inner.problem if inner is not None else _PygmoAsProblem(prob)
        res = self.solve(problem, seed=getattr(self, "_uda_seed", None),
                         x0=np.asarray(pop.get_x()))
        Xf = res.extra["population"]
        Ff = problem.batch_fitness(Xf)
        for i in range(len(Xf)):
            pop.set_xf(i, Xf[i], Ff[i])
        return pop


class _PygmoAsProblem(Problem):
    """Wrap a ``pygmo.problem`` for :meth:`ASAGA.evolve` (per-individual fitness)."""

    def __init__(self, prob) -> None:
        super().__init__()
        self.prob = prob

    def get_bounds(self):
        lb, ub = self.prob.get_bounds()
        return np.asarray(lb, float), np.asarray(ub, float)

    def get_nec(self) -> int:
        return self.prob.get_nec()

    def get_nic(self) -> int:
        return self.prob.get_nic()

    def _batch_fitness(self, X):
        return np.array([self.prob.fitness(x) for x in X])
