"""ASAGA: adaptive simulated-annealing genetic algorithm ([000] Zhu & Xu 2007, §4).

The adaptive GA of [000] §4.1 with a simulated-annealing local search of the best children
embedded in every generation (§4.2–4.3), for box-bounded problems with a dynamic-penalty
fitness (eq. 11). See :class:`ASAGA` for the algorithm, its settings and every decision taken
where the paper is silent.

This module is the template for a new evolutionary algorithm: a class docstring that cites the
paper and lists every hyperparameter with the paper's default, validated settings, the operators
taken from :mod:`.operators`, the penalty from :mod:`.penalties`, and only the generation itself
written here (:class:`~.base.EvolutionaryAlgorithm` does seeding, progress, checkpoints, the
pygmo interface and the problem's verdict).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..common.penalties import penalised_fitness
from ..common.problem import Problem
from . import operators as ops
from .base import EvolutionaryAlgorithm
from .penalties import paper_penalty_weight

__all__ = ["ASAGA"]


class ASAGA(EvolutionaryAlgorithm):
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

    The defaults are the paper's settings ([000] §5).

    Parameters
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
    penalty_weight : callable, optional
        ``(generation, n_generations) -> σ`` (a float, or one weight per penalty group of the
        problem); default :func:`~optimizers.evolutionary.penalties.paper_penalty_weight`,
        σ2 = max(1, 10^(2T/Tmax − 1)) of eq. (11). The relative factors of the groups
        (σ1 = 5σ2 for the velocity term) and their units are the problem's
        (:meth:`~optimizers.common.problem.Problem.penalty_groups`).
    anneal_result : {"current", "best"}
        Which annealed individual replaces a worst child: the SA chain's current state (as
        written, default) or the best state it visited.
    temperature_scale : {"absolute", "spread"}
        ``"absolute"`` (default, the paper): T_i = T0 κ^(T−1) in fitness units.
        ``"spread"`` (a variant, not the paper): T_i = κ^(T−1)·(f_max − f_avg), the annealing
        temperature measured in the population's current fitness spread (see below).
    verbose : int
        0 silent; N > 0 prints a progress line every N generations.
    progress_bar : bool
        Show a tqdm progress bar.

    Examples
    --------
    >>> from optimizers.evolutionary.asaga import ASAGA
    >>> from optimizers.problems import PlanarLandingProblem
    >>> res = ASAGA(n_generations=5).solve(PlanarLandingProblem(), seed=0)
    >>> sorted(res.terminal_errors)
    ['radial_velocity_m_s', 'radius_m', 'speed_m_s', 'tangential_velocity_m_s']
    >>> res.success        # decided by the problem: |dV| < 0.5 m/s and |dr| < 1 m ([000])
    False

    As a pygmo algorithm: ``pygmo.algorithm(ASAGA()).evolve(pop)`` with
    ``pop = pygmo.population(problem.to_pygmo(), size=20)``.

    Notes
    -----
    Decisions where the paper is silent or ambiguous:

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

    - *Units of the fitness.* The penalty of eq. (11) is built from the problem's penalty groups
      (:mod:`optimizers.evolutionary.penalties`): ASAGA is black-box. For [000]'s problem the
      units are the problem's ``penalty_units`` (:class:`~optimizers.problems.
      PlanarLandingProblem`): normalised by default (eq. (11) follows the normalisation of §2);
      ``"si"`` (kg, m/s, m) is the reading under which T0 = 10000 has the size of the early
      penalties.

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

    The ``temperature_scale="spread"`` variant (an explicit option; the printed algorithm stays
    the default) addresses the first cause and nothing else. Eq. (19)–(22) compare fitness
    differences with T_i, so T_i only has a meaning relative to the fitness scale, which the
    paper's T0 = 10000 does not know. The variant measures the temperature in the unit that
    eq. (15)–(18) already use, the current spread f_max − f_avg of the population:
    T_i = κ^(T−1)·(f_max − f_avg), the paper's cooling schedule with T0 read as "one spread".
    At the start a move one spread worse is accepted with probability e^−1 and the stretching
    of eq. (22) weights an individual one spread below the best by e^−1; both become greedy as
    κ^(T−1) falls to 1e-4. Measured (10 runs, 300 generations, ``python -m optimizers.reproduce
    zhu2007``): annealing acceptance falls from ~100 % to 13 % (normalised) / 4 % (SI) in the
    first third; normalised fitness 0/10 converge — the terminal speed does, 0.03–0.13 m/s,
    but the runs land 1.5–20 km off in radius (the radius term is weak in normalised units);
    SI fitness 1/10 (|dr| < 4 m, |dV| 0.2–8.4 m/s): the coarse operators (second cause) remain.
    """

    name = "ASAGA"

    def __init__(self, n_pop: int = 20, n_generations: int = 300, t0: float = 10000.0,
                 kappa: float = 0.97, n_accept_min: int = 10, n_inner_max: int = 10,
                 n_anneal: int = 2, n_recross_max: int = 10, pc1: float = 0.9, pc2: float = 0.2,
                 r1_start: float = 0.5, r1_slope: float = 0.25, r2: float = 0.5,
                 pm1: float = 0.01, pm2: float = 0.005, k1_start: float = 0.5,
                 k1_slope: float = 0.4, k2: float = 0.5, delta_start: float = 0.5,
                 penalty_weight=None, anneal_result: str = "current",
                 temperature_scale: str = "absolute", verbose: int = 0,
                 progress_bar: bool = False) -> None:
        super().__init__(verbose=verbose, progress_bar=progress_bar)
        ints = dict(n_pop=n_pop, n_generations=n_generations, n_accept_min=n_accept_min,
                    n_inner_max=n_inner_max, n_anneal=n_anneal, n_recross_max=n_recross_max)
        for name, v in ints.items():
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 0:
                raise ValueError(f"{name} = {v!r} must be a non-negative integer")
        if n_pop < 2 or n_pop % 2:
            raise ValueError(f"n_pop = {n_pop} must be an even number >= 2 (pairs are crossed)")
        if n_generations < 1:
            raise ValueError(f"n_generations = {n_generations} must be >= 1")
        if n_anneal > n_pop:
            raise ValueError(f"n_anneal = {n_anneal} cannot exceed n_pop = {n_pop}")
        reals = dict(t0=t0, kappa=kappa, pc1=pc1, pc2=pc2, r1_start=r1_start,
                     r1_slope=r1_slope, r2=r2, pm1=pm1, pm2=pm2, k1_start=k1_start,
                     k1_slope=k1_slope, k2=k2, delta_start=delta_start)
        for name, v in reals.items():
            if not np.isfinite(v):
                raise ValueError(f"{name} = {v!r} must be a finite number")
        if not t0 > 0 or not 0 < kappa <= 1:
            raise ValueError(f"need t0 > 0 and 0 < kappa <= 1; got t0={t0!r}, kappa={kappa!r}")
        for name, v in dict(pc1=pc1, pc2=pc2, pm1=pm1, pm2=pm2, delta_start=delta_start,
                            r1_start=r1_start, r2=r2, k1_start=k1_start, k2=k2).items():
            if not 0 <= v <= 1:
                raise ValueError(f"{name} = {v!r} must lie in [0, 1]")
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
        self.penalty_weight = penalty_weight or paper_penalty_weight
        if anneal_result not in ("current", "best"):
            raise ValueError(f"anneal_result = {anneal_result!r}; use 'current' or 'best'")
        self.anneal_result = anneal_result
        if temperature_scale not in ("absolute", "spread"):
            raise ValueError(f"temperature_scale = {temperature_scale!r}; use 'absolute' (the "
                             "paper's, default) or 'spread'")
        self.temperature_scale = temperature_scale

    def settings(self) -> dict[str, Any]:
        keys = ("n_pop", "n_generations", "t0", "kappa", "n_accept_min", "n_inner_max",
                "n_anneal", "n_recross_max", "pc1", "pc2", "r1_start", "r1_slope", "r2", "pm1",
                "pm2", "k1_start", "k1_slope", "k2", "delta_start", "anneal_result",
                "temperature_scale")
        out = {k: getattr(self, k) for k in keys}
        out["penalty_weight"] = getattr(self.penalty_weight, "__qualname__",
                                        repr(self.penalty_weight))
        return out

    def __repr__(self) -> str:
        return (f"ASAGA(n_pop={self.n_pop}, n_generations={self.n_generations}, t0={self.t0}, "
                f"kappa={self.kappa}, n_accept_min={self.n_accept_min}, "
                f"n_inner_max={self.n_inner_max}, n_anneal={self.n_anneal}, "
                f"n_recross_max={self.n_recross_max})")

    # ---- schedules ------------------------------------------------------------------------
    def temperature(self, generation: int, spread: float | None = None) -> float:
        """T_i = T0 κ^(T−1), eq. (19); with ``temperature_scale="spread"``, κ^(T−1)·spread,
        ``spread = f_max − f_avg`` of the current population (see the class docstring)."""
        if self.temperature_scale == "spread" and spread is not None:
            return self.kappa ** (generation - 1) * max(float(spread), 1e-300)
        return self.t0 * self.kappa ** (generation - 1)

    def delta(self, generation: int) -> float:
        """Annealing step δ(T_i) = 0.5 [1 − (T−1)/Tmax] ([000] §5)."""
        return self.delta_start * (1.0 - (generation - 1) / self.n_generations)

    def fitness(self, problem: Problem, F: np.ndarray, generation: int) -> np.ndarray:
        """Penalised fitness (maximised) of fitness rows ``F`` at ``generation``, eq. (11)."""
        return penalised_fitness(problem, F, self.penalty_weight(generation, self.n_generations))

    # ---- operators (the shared ones of :mod:`.operators`, with this paper's settings) -------
    def adaptive_rates(self, f_ind: np.ndarray, f_max: float, f_avg: float, generation: int,
                       kind: str) -> tuple[np.ndarray, np.ndarray]:
        """Probabilities and coefficients of eq. (15)–(18).

        ``kind="crossover"``: f_ind = f_c → (Pc, r); ``kind="mutation"``: f_ind = f_m → (Pm, k).
        """
        frac_t = generation / self.n_generations
        if kind == "crossover":
            return ops.adaptive_rate(f_ind, f_max, f_avg, self.pc1, self.pc2,
                                     self.r1_start - self.r1_slope * frac_t, self.r2)
        if kind == "mutation":
            return ops.adaptive_rate(f_ind, f_max, f_avg, self.pm1, self.pm2,
                                     self.k1_start - self.k1_slope * frac_t, self.k2)
        raise ValueError(f"kind = {kind!r}; use 'crossover' or 'mutation'")

    def crossover(self, A, B, r, lb, ub, rng) -> tuple[np.ndarray, np.ndarray]:
        """Eq. (12)–(13) (:func:`.operators.arithmetic_crossover` with R_max re-crossings)."""
        a, b, self._n_clipped = ops.arithmetic_crossover(A, B, r, lb, ub, rng,
                                                         self.n_recross_max)
        return a, b

    mutate = staticmethod(ops.bound_directed_mutation)
    neighbour = staticmethod(ops.annealing_neighbour)
    roulette = staticmethod(ops.roulette)

    # ---- the generation -------------------------------------------------------------------
    def _initial_state(self, problem, lb, ub, rng, x0):
        X = self._initial_population(lb, ub, rng, x0, self.n_pop)
        hist = {k: [] for k in ("objective", "fitness", "mean_fitness", "anneal_acceptance",
                                "clipped_pairs")}
        return {"X": X, "F": problem.batch_fitness(X), "history": hist}

    def _best(self, problem, state, generation):
        return int(np.argmax(self.fitness(problem, state["F"], generation)))

    def _progress(self, problem, state, generation):
        h = state["history"]
        errs = ", ".join(f"{k[:-len('_m_s')] if k.endswith('_m_s') else k} "
                         f"{h[k][-1]:.3g}" for k in h if k not in (
                             "objective", "fitness", "mean_fitness", "anneal_acceptance",
                             "clipped_pairs"))
        return (f"best fitness {h['fitness'][-1]:.7f}, objective {h['objective'][-1]:.6g}"
                + (f", {errs}" if errs else ""))

    def _result_extra(self, problem, state, best):
        return {"fitness": float(self.fitness(problem, state["F"][best:best + 1],
                                              max(state["generation"], 1))[0])}

    def _record(self, problem, state, x_best, F_best, f_max, f_avg):
        hist = state["history"]
        hist["fitness"].append(f_max)
        hist["mean_fitness"].append(f_avg)
        hist["objective"].append(float(F_best[0]))
        fuel, _ = problem.fuel_tf(x_best, F_best)
        errors = dict(problem.terminal_errors(x_best, F_best))
        if np.isfinite(fuel):
            errors["fuel_kg"] = fuel
        for k, v in errors.items():
            hist.setdefault(k, []).append(float(v))

    def _generation(self, problem, state, T, lb, ub, rng):
        """One generation (steps 2–5 of [000] §4.3)."""
        X, F, hist = state["X"], state["F"], state["history"]
        n = self.n_pop
        # (2) fitness under this generation's penalty, record the best, stretch, select
        f = self.fitness(problem, F, T)
        if not np.any(np.isfinite(f)):
            f = np.zeros_like(f)  # no finite fitness at all: select uniformly
        ib = int(np.argmax(f))
        x_best, F_best = X[ib].copy(), F[ib].copy()
        f_max, f_avg = float(f[ib]), float(f.mean())
        fin = f[np.isfinite(f)]
        temp = self.temperature(T, float(f_max - fin.mean()))
        self._record(problem, state, x_best, F_best, f_max, f_avg)
        with np.errstate(over="ignore", invalid="ignore"):
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
        fc = self.fitness(problem, Fc, T)
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
                fn = self.fitness(problem, Fn, T)
                with np.errstate(over="ignore", invalid="ignore"):
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
        state["X"], state["F"] = children, Fc
