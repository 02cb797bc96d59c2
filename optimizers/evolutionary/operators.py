"""GA operators shared by the evolutionary algorithms of the papers.

Every operator is a pure function of arrays and an explicit ``numpy.random.Generator``, so the
algorithms ([000] ASAGA, [003] FGA, [004] EA, [002] GAIA/AGA) share one tested implementation.
Shapes: a population is ``(n, dim)``; bounds ``lb``, ``ub`` are ``(dim,)``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["arithmetic_crossover", "bound_directed_mutation", "annealing_neighbour",
           "roulette", "adaptive_rate", "uniform_population", "linear_crossover",
           "nonuniform_mutation", "niche_clearing"]


def uniform_population(lb: np.ndarray, ub: np.ndarray, n: int, rng: np.random.Generator
                       ) -> np.ndarray:
    """``n`` vectors drawn uniformly in the box [lb, ub], shape (n, dim)."""
    return lb + (ub - lb) * rng.random((int(n), lb.size))


def arithmetic_crossover(A: np.ndarray, B: np.ndarray, r: np.ndarray, lb: np.ndarray,
                         ub: np.ndarray, rng: np.random.Generator, n_recross_max: int = 10
                         ) -> tuple[np.ndarray, np.ndarray, int]:
    """Arithmetic crossover of pairs with re-crossing, [000] Zhu & Xu 2007 eq. (12)–(13).

    ``A' = (1 − α) A + β B``, ``B' = (1 − β) B + α A`` with one pair of scalars α, β ~ U(0, r_i)
    per pair and attempt. A pair whose children leave the bounds is re-crossed (new α, β), at
    most ``n_recross_max`` times; the last attempt is then clipped (eq. 13).

    Parameters
    ----------
    A, B : ndarray, shape (n_pairs, dim)
    r : ndarray, shape (n_pairs,)
        Crossover coefficients (≤ 1).

    Returns
    -------
    A', B' : ndarray, shape (n_pairs, dim)
    n_clipped : int
        Pairs that were still out of bounds after ``n_recross_max`` re-crossings.
    """
    # all attempts drawn at once; each pair keeps its first attempt whose two children are
    # inside the bounds (the same law as re-crossing one attempt at a time)
    n_try = int(n_recross_max) + 1
    alpha = rng.uniform(0.0, 1.0, (n_try, A.shape[0]))[..., None] * r[None, :, None]
    beta = rng.uniform(0.0, 1.0, (n_try, A.shape[0]))[..., None] * r[None, :, None]
    a = (1.0 - alpha) * A[None] + beta * B[None]
    b = (1.0 - beta) * B[None] + alpha * A[None]
    ok = (((a >= lb) & (a <= ub)).all(axis=2) & ((b >= lb) & (b <= ub)).all(axis=2))
    first = np.where(ok.any(axis=0), ok.argmax(axis=0), n_try - 1)
    cols = np.arange(A.shape[0])
    n_clipped = int((~ok.any(axis=0)).sum())
    return np.clip(a[first, cols], lb, ub), np.clip(b[first, cols], lb, ub), n_clipped


def bound_directed_mutation(C: np.ndarray, pm: np.ndarray, k: np.ndarray, lb: np.ndarray,
                            ub: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Per-parameter mutation toward a random bound, [000] eq. (14).

    Each parameter of row i mutates with probability ``pm[i]``: ``C + k γ (ub − C)`` or
    ``C − k γ (C − lb)`` with a fair coin and γ ~ U(0, 1).
    """
    hit = rng.random(C.shape) < pm[:, None]
    coin = rng.integers(0, 2, size=C.shape).astype(bool)
    gamma = rng.random(C.shape)
    up = C + k[:, None] * gamma * (ub - C)
    down = C - k[:, None] * gamma * (C - lb)
    out = np.where(hit, np.where(coin, down, up), C)
    return np.clip(out, lb, ub)  # only guards round-off: k ≤ 1 keeps eq. (14) inside


def annealing_neighbour(Y: np.ndarray, delta: float, lb: np.ndarray, ub: np.ndarray,
                        rng: np.random.Generator) -> np.ndarray:
    """Simulated-annealing move of [000] eq. (20): every parameter toward a random bound by
    ``δ ξ`` of the distance, ξ ~ U(0, 1)."""
    coin = rng.integers(0, 2, size=Y.shape).astype(bool)
    xi = rng.random(Y.shape)
    out = np.where(coin, Y - (Y - lb) * delta * xi, Y + (ub - Y) * delta * xi)
    return np.clip(out, lb, ub)


def roulette(weights: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Indices of ``n`` roulette-wheel draws with probabilities ∝ ``weights`` (uniform when the
    weights are all zero or not finite)."""
    w = np.asarray(weights, dtype=float)
    total = w.sum()
    if not np.isfinite(total) or total <= 0:
        return rng.integers(0, w.size, size=n)
    return rng.choice(w.size, size=n, p=w / total)


def _ratio(num, den):
    den = np.asarray(den, dtype=float)
    safe = np.where(den > 0, den, 1.0)
    return np.where(den > 0, num / safe, 1.0)


def adaptive_rate(f_ind: np.ndarray, f_max: float, f_avg: float, p1: float, p2: float,
                  c1: float, c2: float) -> tuple[np.ndarray, np.ndarray]:
    """Adaptive probability and coefficient of Srinivas & Patnaik's adaptive GA, as [000]
    eq. (15)–(18) write them (fitness maximised).

    ``p = p1 − p2 (f − f_avg)/(f_max − f_avg)`` and ``c = c1 + c2 (f_max − f)/(f_max − f_avg)``
    for ``f ≥ f_avg``; ``p = p1``, ``c = c1 + c2`` below the average. When f_max = f_avg the
    ratios are taken as for f = f_max (p = p1 − p2, c = c1).

    Returns
    -------
    p, c : ndarray, shape of ``f_ind``
    """
    f_ind = np.asarray(f_ind, dtype=float)
    above = f_ind >= f_avg
    with np.errstate(invalid="ignore"):  # −inf fitness (infeasible rows) gives NaN ratios
        up = np.clip(_ratio(f_ind - f_avg, f_max - f_avg), 0.0, 1.0)
        down = np.clip(_ratio(f_max - f_ind, f_max - f_avg), 0.0, 1.0)
        down = np.where(f_max - f_avg > 0, down, 0.0)
    return np.where(above, p1 - p2 * up, p1), np.where(above, c1 + c2 * down, c1 + c2)


def linear_crossover(A: np.ndarray, B: np.ndarray, rng: np.random.Generator
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Linear (whole arithmetic) crossover, [004] Wang et al. 2001 §2.2:
    ``Z' = α Z + (1 − α) Y``, ``Y' = α Y + (1 − α) Z`` with one α ~ U(0, 1) per pair,
    independent between pairs. Children are convex combinations (inside any box holding the
    parents). Shapes: (n_pairs, dim) in and out.
    """
    alpha = rng.random((A.shape[0], 1))
    return alpha * A + (1.0 - alpha) * B, alpha * B + (1.0 - alpha) * A


def nonuniform_mutation(Z: np.ndarray, generation: int, n_generations: int, b: float,
                        lb: np.ndarray, ub: np.ndarray, rng: np.random.Generator
                        ) -> np.ndarray:
    """Michalewicz's non-uniform mutation, [004] §2.2: with a fair coin per entry,
    ``Z + Δ(t, ub − Z)`` or ``Z − Δ(t, Z − lb)``, ``Δ(t, y) = y (1 − r^((1 − t/T)^b))`` with
    r ~ U(0, 1), t the generation and T the last one. The step shrinks to 0 as t → T; it never
    leaves [lb, ub]. Every entry of every row mutates (callers pick the rows).
    """
    frac = min(max(generation / n_generations, 0.0), 1.0)
    r = rng.random(Z.shape)
    step = 1.0 - r ** ((1.0 - frac) ** b)
    up = rng.integers(0, 2, size=Z.shape).astype(bool)
    out = np.where(up, Z + step * (ub - Z), Z - step * (Z - lb))
    return np.clip(out, lb, ub)  # guards round-off only


def niche_clearing(X: np.ndarray, cost: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Niche penalty (clearing with capacity 1): scanning from the best, an individual closer
    than ``radius`` (per coordinate, scaled: max_k |x_k − y_k| / radius_k < 1) to an already
    kept better one is marked. Returns a bool mask, True for the penalised (similar, worse)
    individuals. Non-finite costs are always penalised.
    """
    order = np.argsort(cost, kind="stable")
    Xo = X[order]
    # near[i, j]: individuals i and j (in cost order) are within one niche radius
    near = (np.abs(Xo[:, None, :] - Xo[None, :, :]) / radius).max(axis=2) < 1.0
    pen = ~np.isfinite(cost[order])
    for i in range(len(order)):
        if not pen[i]:  # a niche leader: every worse individual in its niche is penalised
            pen[i + 1:] |= near[i, i + 1:]
    penalised = np.empty_like(pen)
    penalised[order] = pen
    return penalised
