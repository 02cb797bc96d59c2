"""EA: the evolutionary algorithm of [004] Wang, Zhu, Dai, Ren 2001 (float coding, linear
crossover, non-uniform mutation, (λ+μ) selection, niching).

Written for the free-time two-impulse transfer and interception problems
(:class:`~optimizers.problems.two_impulse.TwoImpulseProblem`), where T is the only variable and
Lambert's problem removes every constraint, but it runs on any unconstrained box-bounded
:class:`~optimizers.common.problem.Problem`. See :class:`EA` for the algorithm and for every
decision taken where the paper is silent.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..common.problem import Problem
from . import operators as ops
from .base import EvolutionaryAlgorithm

__all__ = ["EA"]


class EA(EvolutionaryAlgorithm):
    """Evolutionary algorithm with (λ+μ) selection and niching ([004] §2).

    Paper: Wang S., Zhu K., Dai J., Ren X. "Solving orbital transformation and interception
    problems based on EA", J. National Univ. Defense Tech. 23(5), 2001 ([004]). Steps (§2.5):

    1. P = 0: ``n_parents`` (λ = N = 50) individuals uniformly in the bounds, float coded (the
       individual *is* the decision vector, §2.1); evaluate.
    2. ``n_children`` (μ = 150) children: random pairs of parents, linear crossover
       ``Z' = αZ + (1−α)Y``, ``Y' = αY + (1−α)Z`` with α ~ U(0, 1) per pair (§2.2.1); each child
       then undergoes non-uniform mutation ``Z ± Δ(t, ·)``, ``Δ(t, y) = y(1 − r^((1−t/T)^b))``
       with a fair coin for the direction (§2.2.2) with probability ``mutation_probability``.
    3. Parents and children together (λ + μ = 200) are ranked by cost with the niche penalty
       (§2.4) and the best λ kept.
    4. Stop when |f(P+1) − f(P)| < ε (f the best cost of a generation) or P = P_max (80).
    5. The answer is the best individual.

    The defaults are the paper's settings ([004] §3).

    Parameters
    ----------
    n_parents : int
        λ, the population kept by the selection; also the initial population N (50).
    n_children : int
        μ, children per generation (150; even).
    n_generations : int
        P_max (80).
    epsilon : float
        ε of the stop rule (1e-4, in the objective's units).
    n_niches : int
        Number of niches (10): the niche radius is (ub − lb)/n_niches per variable.
    b : float
        Exponent of the non-uniform mutation, in (2, 3) (2.5).
    mutation_probability : float
        Probability that a child is mutated after crossover (0.5; the paper is silent).
    stall_generations : int
        The stop rule fires after this many consecutive generations with |Δf| < ε (1: as
        printed).
    verbose, progress_bar
        As :class:`~.base.EvolutionaryAlgorithm`.

    Notes
    -----
    Decisions where the paper is silent or ambiguous:

    - *λ and μ.* The paper keeps "the best N (the initial population size)" and sets λ = 50,
      μ = 150 with N = 50; so λ is the number of survivors (parents) and μ the number of
      children per generation — the reverse of the usual (μ+λ) letters. 12 050 evaluations
      for 80 generations.
    - *Pairing.* Parents are paired uniformly at random (selection pressure comes from the
      truncation of step 3 only); α is drawn per pair.
    - *Mutation rate.* Not printed; each child is mutated with probability 0.5, so half the
      children are pure crossover children (which refine) and half explore. The mutation's
      generation counter t is the current generation P and its T is P_max.
    - *Niching* ("penalise individuals by their similarity", §2.4, the elimination niche of
      the paper's ref. [1]): clearing with capacity one. Scanning the λ + μ individuals from
      the best, one closer than the niche radius to an already kept better one is penalised;
      penalised individuals rank after all others (by their own cost). With radius
      (ub − lb)/10, at most ~10 niche leaders coexist and the rest of the population refines
      the best ones. The niche leaders are recorded in ``history_niches``.
    - *Stop rule.* As printed it compares the best cost of consecutive generations. Because
      the selection is elitist, a generation that finds nothing better stops the run; this is
      kept as the default (``stall_generations=1``) and its effect is measured by the
      reproduction (``python -m optimizers.reproduce wang2001``).
    - *Constraints.* None in [004] (Lambert removes them): a problem with constraints is
      refused.

    Examples
    --------
    >>> from optimizers.problems.two_impulse import TwoImpulseProblem
    >>> res = EA().solve(TwoImpulseProblem(0.03, "transfer"), seed=0)   # doctest: +SKIP
    >>> round(res.fun, 2), round(res.tf_s, 1)                          # doctest: +SKIP
    (53.1, 1052.9)

    As a pygmo algorithm: ``pygmo.algorithm(EA()).evolve(pop)`` with
    ``pop = pygmo.population(problem.to_pygmo(), size=50)``.
    """

    name = "EA"

    def __init__(self, n_parents: int = 50, n_children: int = 150, n_generations: int = 80,
                 epsilon: float = 1e-4, n_niches: int = 10, b: float = 2.5,
                 mutation_probability: float = 0.5, stall_generations: int = 1,
                 verbose: int = 0, progress_bar: bool = False) -> None:
        super().__init__(verbose=verbose, progress_bar=progress_bar)
        for name, v, low in (("n_parents", n_parents, 2), ("n_children", n_children, 2),
                             ("n_generations", n_generations, 1), ("n_niches", n_niches, 1),
                             ("stall_generations", stall_generations, 1)):
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < low:
                raise ValueError(f"{name} = {v!r} must be an integer >= {low}")
        if n_children % 2:
            raise ValueError(f"n_children = {n_children} must be even (pairs are crossed)")
        if not (np.isfinite(epsilon) and epsilon >= 0):
            raise ValueError(f"epsilon = {epsilon!r} must be a finite number >= 0")
        if not (np.isfinite(b) and b > 0):
            raise ValueError(f"b = {b!r} must be > 0 (the paper uses a value in (2, 3))")
        if not 0 <= mutation_probability <= 1:
            raise ValueError(f"mutation_probability = {mutation_probability!r} must lie in "
                             "[0, 1]")
        self.n_parents = int(n_parents)
        self.n_children = int(n_children)
        self.n_generations = int(n_generations)
        self.epsilon = float(epsilon)
        self.n_niches = int(n_niches)
        self.b = float(b)
        self.mutation_probability = float(mutation_probability)
        self.stall_generations = int(stall_generations)

    def settings(self) -> dict[str, Any]:
        keys = ("n_parents", "n_children", "n_generations", "epsilon", "n_niches", "b",
                "mutation_probability", "stall_generations")
        return {k: getattr(self, k) for k in keys}

    def __repr__(self) -> str:
        return "EA(" + ", ".join(f"{k}={v!r}" for k, v in self.settings().items()) + ")"

    # ---- the generation -------------------------------------------------------------------
    @staticmethod
    def _costs(F: np.ndarray) -> np.ndarray:
        c = np.asarray(F[:, 0], dtype=np.float64)
        return np.where(np.isfinite(c), c, np.inf)

    def _initial_state(self, problem: Problem, lb, ub, rng, x0):
        if problem.get_nec() or problem.get_nic():
            raise ValueError(f"EA ([004]) solves unconstrained problems; {problem.get_name()} "
                             f"has {problem.get_nec()} equality and {problem.get_nic()} "
                             "inequality constraints")
        X = self._initial_population(lb, ub, rng, x0, self.n_parents)
        F = problem.batch_fitness(X)
        c = self._costs(F)
        hist = {"objective": [], "mean_objective": [], "niches": []}
        return {"X": X, "F": F, "f_prev": float(c.min()), "stall": 0, "history": hist}

    def _generation(self, problem, state, gen, lb, ub, rng):
        X, F = state["X"], state["F"]
        n_pairs = self.n_children // 2
        ia = rng.integers(0, X.shape[0], n_pairs)
        ib = rng.integers(0, X.shape[0], n_pairs)
        a, b = ops.linear_crossover(X[ia], X[ib], rng)
        children = np.concatenate([a, b])
        hit = rng.random(children.shape[0]) < self.mutation_probability
        if np.any(hit):
            children[hit] = ops.nonuniform_mutation(children[hit], gen, self.n_generations,
                                                    self.b, lb, ub, rng)
        Fc = problem.batch_fitness(children)
        pool_X = np.concatenate([X, children])
        pool_F = np.concatenate([F, Fc])
        cost = self._costs(pool_F)
        radius = np.where(ub > lb, (ub - lb) / self.n_niches, 1.0)
        penalised = ops.niche_clearing(pool_X, cost, radius)
        order = np.lexsort((cost, penalised))[:self.n_parents]  # (λ+μ): best λ, niche-ranked
        state["X"], state["F"] = pool_X[order], pool_F[order]
        c = cost[order]
        f_best = float(c.min())
        hist = state["history"]
        hist["objective"].append(f_best)
        hist["mean_objective"].append(float(np.mean(c[np.isfinite(c)])) if np.isfinite(c).any()
                                      else float("inf"))
        hist["niches"].append(int((~penalised).sum()))
        state["stall"] = state["stall"] + 1 if abs(f_best - state["f_prev"]) < self.epsilon \
            else 0
        state["f_prev"] = f_best

    def _converged(self, state, generation):
        return state["stall"] >= self.stall_generations

    def _best(self, problem, state, generation):
        return int(np.argmin(self._costs(state["F"])))

    def _progress(self, problem, state, generation):
        h = state["history"]
        return (f"best objective {h['objective'][-1]:.7g}, mean {h['mean_objective'][-1]:.6g},"
                f" niches {h['niches'][-1]}")
