"""FGA: the float-coded genetic algorithm of [003] Wang, Li, Cui, Liu 2003, §3.

See :class:`FGA` for the algorithm, its settings (the paper's as defaults) and every decision
taken where the paper is silent. Operators come from :mod:`.operators`, the penalty from
:mod:`.penalties`; seeding, progress, checkpoints, the pygmo interface and the problem's verdict
from :class:`~.base.EvolutionaryAlgorithm`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..common.penalties import penalised_fitness
from ..common.problem import Problem
from . import operators as ops
from .base import EvolutionaryAlgorithm

__all__ = ["FGA"]


class FGA(EvolutionaryAlgorithm):
    """Float-coded genetic algorithm (FGA) of [003].

    Paper: Wang J., Li J., Cui N., Liu D. "Genetic algorithm optimization of lunar probe
    soft-landing trajectories", J. Tsinghua Univ. (Sci. & Tech.) 43(8), 1056–1059, 2003 ([003]).
    The paper's steps: (1) the n variables, each with its range, are coded as floats side by
    side in an individual; N random individuals form the initial population; (2) evaluate the
    performance index of every individual and sort; (3) select several individuals with the
    smallest index, keep them and pass them to the next generation; (4) pair individuals at
    random and cross each pair with probability Pc; (5) mutate every parameter of every
    individual with probability Pm; (6) repeat until the stop condition (10 000 generations).

    The defaults are the paper's settings ([003] §3).

    Parameters
    ----------
    n_pop : int
        Population size N (20).
    n_generations : int
        Generations T_iter (10 000).
    pc : float
        Crossover probability of a pair Pc (0.6).
    pm : float
        Mutation probability of a parameter Pm (0.05).
    n_elite : int, optional
        Individuals kept unchanged each generation, the "several" of step (3) (default
        ``n_pop // 2``).
    mutation_b : float
        Degree of non-uniformity b of the mutation (5, Michalewicz's value).
    penalty_weight : float or callable
        Weight w of the constraint terms in the sorted index (default 1.0, static), or
        ``(generation, n_generations) -> w``. The groups, factors and units are the problem's
        (:meth:`~optimizers.common.problem.Problem.penalty_groups`).
    verbose : int
        0 silent; N > 0 prints a progress line every N generations.
    progress_bar : bool
        Show a tqdm progress bar.

    Examples
    --------
    >>> from optimizers.evolutionary import FGA
    >>> from optimizers.problems import ThrustDesignProblem
    >>> res = FGA(n_generations=50).solve(ThrustDesignProblem(), seed=0)
    >>> res.n_iter, res.n_fevals
    (50, 520)

    As a pygmo algorithm: ``pygmo.algorithm(FGA()).evolve(pop)`` with a population of 20.

    Notes
    -----
    Decisions where the paper is silent:

    - *Performance index with constraints.* The paper sorts by "the performance index" and
      does not say how the 6 boundary equalities enter; the index is the penalised objective
      ``fuel + w·Σ groups`` of :func:`~optimizers.common.penalties.penalised_fitness`
      (maximised as its negative), with a static weight. For
      :class:`~optimizers.problems.ThrustDesignProblem` (kg, m/s, m) w = 1 is an exact penalty
      (its docstring gives the multipliers).
    - *Elitist selection* (step 3): truncation — the ``n_elite`` best individuals survive
      unchanged (so the best never worsens) and are the mating pool; the other
      ``n_pop − n_elite`` places are filled with their offspring (steps 4–5), so only the
      offspring are evaluated each generation.
    - *Crossover* (step 4): the pool is shuffled and paired (re-shuffled as often as needed to
      fill the offspring places); each pair is crossed with probability Pc by the whole
      arithmetic crossover of Michalewicz (the paper's float-coding reference),
      :func:`~.operators.linear_crossover` (shared with [004]'s EA); an uncrossed pair is
      copied.
    - *Mutation* (step 5): each parameter of each offspring mutates independently with
      probability Pm by Michalewicz's non-uniform mutation
      (:func:`~.operators.nonuniform_mutation`, shared with [004]), whose step shrinks from the
      whole range at generation 1 to 0 at the last (:meth:`mutate`). The elite are not mutated
      (step 3 passes them on as they are).
    - *Answer*: the best individual of the final population under the final penalty.
    """

    name = "FGA"

    def __init__(self, n_pop: int = 20, n_generations: int = 10_000, pc: float = 0.6,
                 pm: float = 0.05, n_elite: int | None = None, mutation_b: float = 5.0,
                 penalty_weight=1.0, verbose: int = 0, progress_bar: bool = False) -> None:
        super().__init__(verbose=verbose, progress_bar=progress_bar)
        n_elite = n_pop // 2 if n_elite is None else n_elite
        for name, v in dict(n_pop=n_pop, n_generations=n_generations, n_elite=n_elite).items():
            if isinstance(v, bool) or not isinstance(v, int | np.integer):
                raise ValueError(f"{name} = {v!r} must be an integer")
        if n_pop < 2:
            raise ValueError(f"n_pop = {n_pop} must be >= 2")
        if n_generations < 1:
            raise ValueError(f"n_generations = {n_generations} must be >= 1")
        if not 2 <= n_elite < n_pop:
            raise ValueError(f"n_elite = {n_elite} must satisfy 2 <= n_elite < n_pop = {n_pop} "
                             "(at least one pair of parents and one offspring place)")
        for name, v in dict(pc=pc, pm=pm).items():
            if not (np.isfinite(v) and 0.0 <= v <= 1.0):
                raise ValueError(f"{name} = {v!r} must lie in [0, 1]")
        if not (np.isfinite(mutation_b) and mutation_b >= 0):
            raise ValueError(f"mutation_b = {mutation_b!r} must be a finite number >= 0")
        if not callable(penalty_weight):
            w = np.asarray(penalty_weight, dtype=float)
            if not (np.all(np.isfinite(w)) and np.all(w >= 0)):
                raise ValueError(f"penalty_weight = {penalty_weight!r} must be finite and >= 0")
        self.n_pop = int(n_pop)
        self.n_generations = int(n_generations)
        self.pc, self.pm = float(pc), float(pm)
        self.n_elite = int(n_elite)
        self.mutation_b = float(mutation_b)
        self.penalty_weight = penalty_weight

    def settings(self) -> dict[str, Any]:
        out = {k: getattr(self, k) for k in ("n_pop", "n_generations", "pc", "pm", "n_elite",
                                             "mutation_b")}
        w = self.penalty_weight
        out["penalty_weight"] = (getattr(w, "__qualname__", repr(w)) if callable(w)
                                 else np.asarray(w, float).tolist())
        return out

    def __repr__(self) -> str:
        return (f"FGA(n_pop={self.n_pop}, n_generations={self.n_generations}, pc={self.pc}, "
                f"pm={self.pm}, n_elite={self.n_elite})")

    def weight(self, generation: int):
        """Penalty weight at ``generation``."""
        w = self.penalty_weight
        return w(generation, self.n_generations) if callable(w) else w

    def fitness(self, problem: Problem, F: np.ndarray, generation: int) -> np.ndarray:
        """Penalised fitness (maximised) of fitness rows ``F``: −(the sorted index)."""
        return penalised_fitness(problem, F, self.weight(generation))

    # ---- the generation -------------------------------------------------------------------
    def _initial_state(self, problem, lb, ub, rng, x0):
        X = self._initial_population(lb, ub, rng, x0, self.n_pop)
        return {"X": X, "F": problem.batch_fitness(X),
                "history": {"objective": [], "fitness": []}}

    def _offspring(self, pool: np.ndarray, n_children: int, progress: float, lb, ub, rng
                   ) -> np.ndarray:
        """Steps 4–5: random pairs of the pool, crossover with Pc, mutation with Pm."""
        k = pool.shape[0]
        n_pairs = -(-n_children // 2)
        reps = -(-2 * n_pairs // k)
        order = np.concatenate([rng.permutation(k) for _ in range(reps)])[:2 * n_pairs]
        A, B = pool[order[0::2]], pool[order[1::2]]
        cross = rng.random(n_pairs) < self.pc
        A2, B2 = A.copy(), B.copy()
        if np.any(cross):
            A2[cross], B2[cross] = ops.linear_crossover(A[cross], B[cross], rng)
        children = np.concatenate([A2, B2])[:n_children]
        return self.mutate(children, progress, lb, ub, rng)

    def mutate(self, C: np.ndarray, progress: float, lb, ub, rng) -> np.ndarray:
        """Step 5: each parameter mutates with probability Pm by the non-uniform mutation at
        run fraction ``progress`` ∈ [0, 1] (0: steps over the whole range; 1: no step)."""
        hit = rng.random(C.shape) < self.pm
        if not hit.any():
            return C
        moved = ops.nonuniform_mutation(C, progress, 1.0, self.mutation_b, lb, ub, rng)
        return np.where(hit, moved, C)

    def _generation(self, problem, state, g, lb, ub, rng):
        X, F = state["X"], state["F"]
        # a static weight leaves the survivors' penalised fitness unchanged: carry it
        f = state.get("f") if not callable(self.penalty_weight) else None
        if f is None or len(f) != len(F):
            f = self.fitness(problem, F, g)
        order = np.argsort(-f, kind="stable")
        elite = order[:self.n_elite]
        hist = state["history"]
        hist["fitness"].append(float(f[elite[0]]))
        hist["objective"].append(float(F[elite[0], 0]))
        children = self._offspring(X[elite], self.n_pop - self.n_elite,
                                   (g - 1) / self.n_generations, lb, ub, rng)
        Fc = problem.batch_fitness(children)
        state["X"] = np.concatenate([X[elite], children])
        state["F"] = np.concatenate([F[elite], Fc])
        if not callable(self.penalty_weight):
            state["f"] = np.concatenate([f[elite], self.fitness(problem, Fc, g)])

    def _best(self, problem, state, generation):
        return int(np.argmax(self.fitness(problem, state["F"], generation)))

    def _progress(self, problem, state, g):
        i = self._best(problem, state, g)
        err = problem.terminal_errors(state["X"][i], state["F"][i])
        errs = ", ".join(f"{k} {v:.3g}" for k, v in err.items())
        return f"objective {state['F'][i][0]:.6g}, {errs}"

    def _result_extra(self, problem, state, best):
        return {"fitness": float(self.fitness(problem, state["F"][best:best + 1],
                                              max(state["generation"], 1))[0])}
