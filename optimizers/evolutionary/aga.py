"""AGA: the adaptive genetic algorithm [002] compares GAIA with.

[002] names its baseline only "adaptive genetic algorithm (AGA)" and gives neither its
operators nor its settings (its table 1 is not legible). This is the standard real-coded
adaptive GA of the Chinese trajectory-optimisation literature of the time: Srinivas & Patnaik's
adaptive crossover and mutation probabilities in Ren & San's improved form (Pc1 = 0.9,
Pc2 = 0.6, Pm1 = 0.1, Pm2 = 0.001: Pc = Pc1 − (Pc1 − Pc2)(f' − f_avg)/(f_max − f_avg) for
f' ≥ f_avg, Pc1 below; the same for Pm), with the shared operators of [000] (arithmetic
crossover eq. (12)–(13), bound-directed mutation eq. (14) with the coefficient schedules of
[000] eq. (16), (18)), roulette selection on the affinity shifted to be positive, and
elitism (the best individual replaces the worst child). The affinity is GAIA's: the same
annealed penalty (:func:`optimizers.evolutionary.gaia.annealed_penalty_weight`), population 100
and 100 generations, so the two differ only in the search operators.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..common.penalties import penalised_fitness
from . import operators as ops
from .base import EvolutionaryAlgorithm
from .gaia import PENALTY_READINGS, annealed_penalty_weight

__all__ = ["AGA"]


class AGA(EvolutionaryAlgorithm):
    """Adaptive real-coded GA (the baseline of [002]).

    Parameters
    ----------
    n_pop : int
        Population (100, as GAIA in [002]); even.
    n_generations : int
        Generations (100).
    pc1, pc2, pm1, pm2 : float
        Crossover and mutation probabilities at and above the mean (Ren & San: 0.9, 0.6, 0.1,
        0.001); Pc falls from pc1 at f_avg to pc2 at f_max, Pm from pm1 to pm2.
    beta, t_lambda, penalty_reading
        The penalty schedule of [002] eq. (4) (as :class:`~.gaia.GAIA`).
    """

    name = "AGA"

    def __init__(self, n_pop: int = 100, n_generations: int = 100, pc1: float = 0.9,
                 pc2: float = 0.6, pm1: float = 0.1, pm2: float = 0.001, beta: float = 0.005,
                 t_lambda: float = 0.1, penalty_reading: str = "rising", verbose: int = 0,
                 progress_bar: bool = False) -> None:
        super().__init__(verbose=verbose, progress_bar=progress_bar)
        for nm, v in dict(n_pop=n_pop, n_generations=n_generations).items():
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 1:
                raise ValueError(f"{nm} = {v!r} must be a positive integer")
        if n_pop < 2 or n_pop % 2:
            raise ValueError(f"n_pop = {n_pop} must be an even number >= 2 (pairs are crossed)")
        for nm, v in dict(pc1=pc1, pc2=pc2, pm1=pm1, pm2=pm2, beta=beta).items():
            if not (np.isfinite(v) and 0 <= v <= 1):
                raise ValueError(f"{nm} = {v!r} must lie in [0, 1]")
        if pc2 > pc1 or pm2 > pm1:
            raise ValueError(f"need pc2 <= pc1 and pm2 <= pm1; got {pc1}, {pc2}, {pm1}, {pm2}")
        if penalty_reading not in PENALTY_READINGS:
            raise ValueError(f"penalty_reading = {penalty_reading!r}; allowed: "
                             f"{PENALTY_READINGS}")
        if not (np.isfinite(t_lambda) and t_lambda > 0):
            raise ValueError(f"t_lambda = {t_lambda!r} must be > 0")
        self.n_pop, self.n_generations = int(n_pop), int(n_generations)
        self.pc1, self.pc2, self.pm1, self.pm2 = map(float, (pc1, pc2, pm1, pm2))
        self.beta, self.t_lambda = float(beta), float(t_lambda)
        self.penalty_reading = penalty_reading

    def settings(self) -> dict[str, Any]:
        keys = ("n_pop", "n_generations", "pc1", "pc2", "pm1", "pm2", "beta", "t_lambda",
                "penalty_reading")
        return {k: getattr(self, k) for k in keys}

    def __repr__(self) -> str:
        return (f"AGA(n_pop={self.n_pop}, n_generations={self.n_generations}, pc=({self.pc1}, "
                f"{self.pc2}), pm=({self.pm1}, {self.pm2}))")

    def affinity(self, problem, F, generation):
        """The penalised fitness of [002] eq. (3) with the annealed weights of eq. (4)."""
        w = annealed_penalty_weight(generation, self.n_generations, beta=self.beta,
                                    t_lambda=self.t_lambda, reading=self.penalty_reading)
        return penalised_fitness(problem, F, w)

    def _initial_state(self, problem, lb, ub, rng, x0):
        X = self._initial_population(lb, ub, rng, x0, self.n_pop)
        return {"X": X, "F": problem.batch_fitness(X),
                "history": {"objective": [], "fitness": [], "mean_fitness": []}}

    def _best(self, problem, state, generation):
        return int(np.argmax(self.affinity(problem, state["F"], generation)))

    def _progress(self, problem, state, generation):
        h = state["history"]
        return f"best affinity {h['fitness'][-1]:.7f}, objective {h['objective'][-1]:.7g}"

    def _result_extra(self, problem, state, best):
        g = max(state["generation"], 1)
        return {"fitness": float(self.affinity(problem, state["F"][best:best + 1], g)[0])}

    def _generation(self, problem, state, g, lb, ub, rng):
        X, F, hist = state["X"], state["F"], state["history"]
        n = self.n_pop
        f = self.affinity(problem, F, g)
        finite = np.isfinite(f)
        fs = np.where(finite, f, f[finite].min() if finite.any() else 0.0)
        ib = int(np.argmax(fs))
        x_best, F_best = X[ib].copy(), F[ib].copy()
        f_max, f_avg = float(fs[ib]), float(fs.mean())
        sel = ops.roulette(fs - fs.min() + 1e-12 * max(1.0, abs(f_max)), n, rng)
        sel = sel[rng.permutation(n)]
        ia, ibb = sel[0::2], sel[1::2]
        A, B = X[ia].copy(), X[ibb].copy()
        frac = g / self.n_generations
        pc, r = ops.adaptive_rate(np.maximum(fs[ia], fs[ibb]), f_max, f_avg, self.pc1,
                                  self.pc1 - self.pc2, 0.5 - 0.25 * frac, 0.5)
        cross = rng.random(ia.size) < pc
        if np.any(cross):
            a, b, _ = ops.arithmetic_crossover(A[cross], B[cross], r[cross], lb, ub, rng)
            A[cross], B[cross] = a, b
        children = np.concatenate([A, B])
        f_par = np.concatenate([fs[ia], fs[ibb]])
        pm, k = ops.adaptive_rate(f_par, f_max, f_avg, self.pm1, self.pm1 - self.pm2,
                                  0.5 - 0.4 * frac, 0.5)
        children = ops.bound_directed_mutation(children, pm, k, lb, ub, rng)
        Fc = problem.batch_fitness(children)
        fc = self.affinity(problem, Fc, g)
        worst = int(np.argmin(np.where(np.isfinite(fc), fc, -np.inf)))
        children[worst], Fc[worst] = x_best, F_best
        state["X"], state["F"] = children, Fc
        fn = self.affinity(problem, Fc, g)
        j = int(np.argmax(fn))
        hist["fitness"].append(float(fn[j]))
        hist["mean_fitness"].append(float(np.mean(fn[np.isfinite(fn)])))
        hist["objective"].append(float(Fc[j, 0]))
        fuel, _ = problem.fuel_tf(children[j], Fc[j])
        if np.isfinite(fuel):
            hist.setdefault("fuel_kg", []).append(float(fuel))
        for key, v in problem.terminal_errors(children[j], Fc[j]).items():
            hist.setdefault(key, []).append(float(v))
