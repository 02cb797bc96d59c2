"""GAIA and AIA: (guiding) artificial immune algorithm ([002] Peng, Xu, Guo, Wang).

The artificial immune algorithm of [002] §4 (after Sun Ning's thesis, their ref. [8]) and its
guided variant, for box-bounded problems with the annealed-penalty affinity of [002] eq. (3).
See :class:`GAIA` for the algorithm and every decision taken where the source is silent or its
formulas are not legible (the extracted text has none of the equations).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..common.penalties import penalised_fitness
from ..common.problem import Problem
from . import operators as ops
from .base import EvolutionaryAlgorithm

__all__ = ["GAIA", "AIA", "annealed_penalty_weight", "PENALTY_READINGS"]


def annealed_penalty_weight(generation: int, n_generations: int, *, beta: float = 0.005,
                            t_lambda: float = 0.1, reading: str = "rising") -> float:
    """Penalty weight σ_λ of [002] eq. (4) at ``generation`` of ``n_generations``.

    The source's curve is not legible. What the text says: the weight follows an annealing
    curve, "β is the temperature-decrease coefficient and sets the rate of change, β ∈ [0, 1];
    T_λ is the initial temperature and sets the *final* value of the weight"; the curve is
    maxed with 1 "so that early in the search the weight does not lose its constraining role
    by being too small" — so the curve itself starts *below* 1 and grows. Readings:

    - ``"rising"`` (default, this project's reading): σ = max(1, T_λ·β^(−g/g_max)). The curve
      starts at T_λ = 0.1 < 1 (so the max with 1 acts early, as the text says), the rate is
      set by β and the final value T_λ/β = 20 by T_λ and β. σ = 1 until g = 0.435 g_max.
    - ``"inverse"``: σ = max(1, 1/(T_λ·β^(g/g_max))) (the reading suggested in the project's
      digest of the paper): the weight is the inverse of the temperature T_λβ^(g/g_max),
      10 → 2000; the max with 1 never acts.
    - ``"constant"``: σ = 1 throughout (the floor alone; the control case).

    Returns
    -------
    float
    """
    frac = generation / n_generations
    if reading == "rising":
        return max(1.0, t_lambda * beta ** (-frac))
    if reading == "inverse":
        return max(1.0, 1.0 / (t_lambda * beta ** frac))
    if reading == "constant":
        return 1.0
    raise ValueError(f"reading = {reading!r}; allowed: {PENALTY_READINGS}")


PENALTY_READINGS = ("rising", "inverse", "constant")


class GAIA(EvolutionaryAlgorithm):
    """Guiding artificial immune algorithm (GAIA); ``guided=False`` gives the basic AIA.

    Paper: Peng K., Xu S., Guo L., Wang P., "Guiding artificial immune algorithm for Earth–Mars
    low-thrust transfer trajectory optimisation" ([002]). One generation g = 1 … g_max:

    1. *Affinity* f_aff of every antibody: the penalised fitness of eq. (3) with the annealed
       weights σ_λ(g) (:func:`annealed_penalty_weight`), built from the problem's penalty
       groups (:mod:`.penalties`).
    2. *Concentration* (eq. 5–6): f_den(X_I) = (1/n) Σ_i f_bff(X_I, X_i), similarity
       f_bff = 1 − d_Ii with d the normalised distance
       d = sqrt((1/L) Σ_j ((X_I,j − X_i,j)/(ub_j − lb_j))²) ∈ [0, 1].
    3. *Stimulation* (eq. 7, parameter a): f_sti = â·exp(−a·f_den), where â is the affinity
       min–max normalised over the population to [0, 1]: high affinity and low concentration
       give high stimulation.
    4. *Immune operation*: the ``n_select`` antibodies of highest stimulation are each cloned
       τ times; every variable of every clone mutates with probability P_m (eq. 8):
       X_I,j,k = X_I,j + (r − 0.5)·δ_j, r ~ U(0, 1), inside the neighbourhood δ_j =
       δ(g)·(ub_j − lb_j), δ(g) = δ0/g; GAIA adds the guide (eq. 9):
       X_I,j,k += G·(k/τ)·(X_b,j − X_I,j), k = 1 … τ. *Clonal suppression*: the antibody of
       highest affinity among the source and its clones replaces the source.
    5. *Population refresh*: the other n − n_select antibodies (lowest stimulation) are
       replaced by random ones (uniform in the bounds).

    Guide factor (eq. 10): G = 1/(1 + exp(−b·(f_b − f0))) with f_b the best affinity;
    f0 = f_b + 0.01|f_b| in the first half of the run ("1.01 f_b", G small: global search) and
    f_b − 0.01|f_b| in the second half ("0.99 f_b", G large: local search), updated only in
    generations where f_b increased ("if f_b no longer increases, f0 stays unchanged").

    The defaults are the paper's settings ([002] §5).

    Parameters
    ----------
    n_pop : int
        Population n (100).
    n_generations : int
        g_max (100).
    n_clones : int
        Clones per selected antibody τ (20).
    p_mutation : float
        P_m (0.8).
    a : float
        Stimulation parameter (2).
    b : float
        Steepness of the guide's sigmoid (150).
    guided : bool
        True: GAIA; False: the basic AIA (G = 0).
    n_select : int, optional
        Antibodies selected for cloning (default n_pop // 2; the rest are refreshed).
    delta0 : float
        Initial neighbourhood, as a fraction of each variable's range (0.2; not in the paper).
    beta, t_lambda : float
        Penalty annealing: temperature-decrease coefficient β (0.005) and initial temperature
        T_λ (0.1) of eq. (4).
    penalty_reading : {"rising", "inverse", "constant"}
        Reading of the illegible eq. (4) (:func:`annealed_penalty_weight`).
    elitist : bool
        Always select the antibody of highest affinity for cloning (True). The paper selects by
        stimulation only; with clonal suppression this makes the best affinity non-decreasing
        for fixed weights.

    Decisions where [002] is silent or illegible (equations (3)–(10) are missing from the
    source text; the prose fixes their roles): the forms of the similarity, the stimulation
    and the guided mutation above; the fraction selected for cloning and the refreshed
    fraction (one half each, as in the usual textbook AIA); the neighbourhood δ0/g (the
    paper names δ, gives no value); which antibody is the answer (the best affinity of the
    final population under the final weights).

    Measured (``python -m optimizers.reproduce peng_mars``, 10 runs, paper's settings, 105 100
    evaluations per run): every GAIA run arrives on Mars' orbit (|Δr| ≤ 1.3e6 m, |ΔV| ≤ 0.41
    m/s) with 252.85–256.82 kg of propellant, 1.31–2.90 % (mean 2.05 %) above the Pontryagin
    optimum of 249.584 kg; the best the paper's parameterisation can reach is 1.17 % above it
    (SLSQP), so GAIA's search adds 0.14–1.73 %. Without the guide (AIA) the runs also arrive but
    at 2.4–7.6 % (mean 5.2 %). The best affinity settles (within 0.1 %) at generation 23
    (median).
    """

    name = "GAIA"

    def __init__(self, n_pop: int = 100, n_generations: int = 100, n_clones: int = 20,
                 p_mutation: float = 0.8, a: float = 2.0, b: float = 150.0, guided: bool = True,
                 n_select: int | None = None, delta0: float = 0.2, beta: float = 0.005,
                 t_lambda: float = 0.1, penalty_reading: str = "rising", elitist: bool = True,
                 verbose: int = 0, progress_bar: bool = False) -> None:
        super().__init__(verbose=verbose, progress_bar=progress_bar)
        for nm, v in dict(n_pop=n_pop, n_generations=n_generations, n_clones=n_clones).items():
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 1:
                raise ValueError(f"{nm} = {v!r} must be a positive integer")
        if n_pop < 2:
            raise ValueError(f"n_pop = {n_pop} must be >= 2")
        n_select = n_pop // 2 if n_select is None else n_select
        if isinstance(n_select, bool) or not 1 <= int(n_select) <= n_pop:
            raise ValueError(f"n_select = {n_select!r} must be an integer in [1, n_pop]")
        for nm, v in dict(p_mutation=p_mutation, beta=beta).items():
            if not (np.isfinite(v) and 0 <= v <= 1):
                raise ValueError(f"{nm} = {v!r} must lie in [0, 1]")
        for nm, v in dict(a=a, b=b, delta0=delta0, t_lambda=t_lambda).items():
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{nm} = {v!r} must be a finite number >= 0")
        if penalty_reading not in PENALTY_READINGS:
            raise ValueError(f"penalty_reading = {penalty_reading!r}; allowed: "
                             f"{PENALTY_READINGS}")
        self.n_pop, self.n_generations = int(n_pop), int(n_generations)
        self.n_clones, self.n_select = int(n_clones), int(n_select)
        self.p_mutation, self.a, self.b = float(p_mutation), float(a), float(b)
        self.guided, self.elitist = bool(guided), bool(elitist)
        self.delta0, self.beta, self.t_lambda = float(delta0), float(beta), float(t_lambda)
        self.penalty_reading = penalty_reading
        if not self.guided:
            self.name = "AIA"

    def settings(self) -> dict[str, Any]:
        keys = ("n_pop", "n_generations", "n_clones", "n_select", "p_mutation", "a", "b",
                "guided", "delta0", "beta", "t_lambda", "penalty_reading", "elitist")
        return {k: getattr(self, k) for k in keys}

    def __repr__(self) -> str:
        return (f"{self.name}(n_pop={self.n_pop}, n_generations={self.n_generations}, "
                f"n_clones={self.n_clones}, p_mutation={self.p_mutation}, a={self.a}, "
                f"b={self.b}, penalty_reading={self.penalty_reading!r})")

    # ---- the paper's formulas -------------------------------------------------------------
    def penalty_weight(self, generation: int) -> float:
        """σ_λ(g), eq. (4) (the same for λ = 1, 2, 3: T_λ = 0.1 for all three in [002])."""
        return annealed_penalty_weight(generation, self.n_generations, beta=self.beta,
                                       t_lambda=self.t_lambda, reading=self.penalty_reading)

    def affinity(self, problem: Problem, F: np.ndarray, generation: int) -> np.ndarray:
        """f_aff, eq. (3): penalised fitness (maximised) of fitness rows F (n, n_f)."""
        return penalised_fitness(problem, F, self.penalty_weight(generation))

    @staticmethod
    def concentration(X: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> np.ndarray:
        """f_den, eq. (5)–(6): mean similarity 1 − normalised distance, shape (n,)."""
        span = np.where(ub > lb, ub - lb, 1.0)
        Z = (X - lb) / span
        sq = (Z * Z).sum(axis=1)
        d2 = np.maximum(sq[:, None] + sq[None, :] - 2.0 * Z @ Z.T, 0.0) / Z.shape[1]
        return (1.0 - np.sqrt(d2)).mean(axis=1)

    def stimulation(self, affinity: np.ndarray, concentration: np.ndarray) -> np.ndarray:
        """f_sti, eq. (7): â·exp(−a·f_den) with â the affinity scaled to [0, 1]."""
        f = np.where(np.isfinite(affinity), affinity, -np.inf)
        finite = np.isfinite(f)
        if not finite.any():
            scaled = np.ones_like(f)
        else:
            lo, hi = f[finite].min(), f[finite].max()
            scaled = np.where(finite, (f - lo) / (hi - lo) if hi > lo else 1.0, 0.0)
        return scaled * np.exp(-self.a * concentration)

    def guide_factor(self, f_best: float, f0: float) -> float:
        """G, eq. (10): 1/(1 + exp(−b (f_b − f0)))."""
        z = -self.b * (f_best - f0)
        return 0.0 if z > 700 else 1.0 / (1.0 + math.exp(z))

    def neighbourhood(self, generation: int) -> float:
        """δ(g) = δ0/g as a fraction of each variable's range."""
        return self.delta0 / generation

    # ---- the generation -------------------------------------------------------------------
    def _initial_state(self, problem, lb, ub, rng, x0):
        X = self._initial_population(lb, ub, rng, x0, self.n_pop)
        hist = {k: [] for k in ("objective", "fitness", "guide", "concentration", "weight")}
        return {"X": X, "F": problem.batch_fitness(X), "f0": math.nan, "f_best_prev": -math.inf,
                "history": hist}

    def _best(self, problem, state, generation):
        return int(np.argmax(self.affinity(problem, state["F"], generation)))

    def _progress(self, problem, state, generation):
        h = state["history"]
        return (f"best affinity {h['fitness'][-1]:.7f}, objective {h['objective'][-1]:.7g}, "
                f"G {h['guide'][-1]:.3f}")

    def _result_extra(self, problem, state, best):
        g = max(state["generation"], 1)
        return {"fitness": float(self.affinity(problem, state["F"][best:best + 1], g)[0])}

    def _generation(self, problem, state, g, lb, ub, rng):
        X, F, hist = state["X"], state["F"], state["history"]
        n, tau = self.n_pop, self.n_clones
        f = self.affinity(problem, F, g)
        den = self.concentration(X, lb, ub)
        sti = self.stimulation(f, den)
        order = np.argsort(-sti, kind="stable")
        sel = order[:self.n_select].copy()
        ib = int(np.argmax(f))
        if self.elitist and ib not in sel:
            sel[-1] = ib
        # guide factor with the threshold rule of [002] §4
        f_b = float(f[ib])
        if self.guided:
            if f_b > state["f_best_prev"] or not math.isfinite(state["f0"]):
                sign = 1.0 if g <= self.n_generations / 2 else -1.0
                state["f0"] = f_b + sign * 0.01 * abs(f_b)
            G = self.guide_factor(f_b, state["f0"])
        else:
            G = 0.0
        state["f_best_prev"] = max(state["f_best_prev"], f_b)
        # clone, mutate inside the neighbourhood, guide toward the best
        src = X[sel]
        clones = np.repeat(src, tau, axis=0)
        span = ub - lb
        hit = rng.random(clones.shape) < self.p_mutation
        step = (rng.random(clones.shape) - 0.5) * (self.neighbourhood(g) * span)
        clones = clones + np.where(hit, step, 0.0)
        if G > 0.0:
            k = np.tile(np.arange(1, tau + 1) / tau, sel.size)[:, None]
            clones = clones + G * k * (X[ib] - np.repeat(src, tau, axis=0))
        clones = np.clip(clones, lb, ub)
        Fc = problem.batch_fitness(clones)
        fc = self.affinity(problem, Fc, g).reshape(sel.size, tau)
        # clonal suppression: best of the source and its clones
        j = np.argmax(fc, axis=1)
        better = fc[np.arange(sel.size), j] > f[sel]
        new_X, new_F = src.copy(), F[sel].copy()
        pick = np.arange(sel.size) * tau + j
        new_X[better], new_F[better] = clones[pick[better]], Fc[pick[better]]
        # population refresh
        n_new = n - sel.size
        if n_new:
            R = ops.uniform_population(lb, ub, n_new, rng)
            new_X = np.concatenate([new_X, R])
            new_F = np.concatenate([new_F, problem.batch_fitness(R)])
        state["X"], state["F"] = new_X, new_F
        fn = self.affinity(problem, new_F, g)
        ibn = int(np.argmax(fn))
        hist["fitness"].append(float(fn[ibn]))
        hist["objective"].append(float(new_F[ibn, 0]))
        hist["guide"].append(G)
        hist["concentration"].append(float(den.mean()))
        hist["weight"].append(self.penalty_weight(g))
        fuel, _ = problem.fuel_tf(new_X[ibn], new_F[ibn])
        if np.isfinite(fuel):
            hist.setdefault("fuel_kg", []).append(float(fuel))
        for key, v in problem.terminal_errors(new_X[ibn], new_F[ibn]).items():
            hist.setdefault(key, []).append(float(v))


class AIA(GAIA):
    """The basic artificial immune algorithm of [002] §4: :class:`GAIA` without the guide."""

    name = "AIA"

    def __init__(self, **kwargs) -> None:
        kwargs.setdefault("guided", False)
        if kwargs["guided"]:
            raise ValueError("AIA is the unguided algorithm; use GAIA for guided=True")
        super().__init__(**kwargs)
