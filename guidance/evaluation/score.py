"""The landing envs' benchmark score: the return normalised between a random policy and the
per-case optimum (D4RL-style, Fu et al. 2020, with an exact expert).

For case ``i`` with episode return ``R_i`` (the sum of the env's rewards, unshaped and
undiscounted), the return ``R_rand,i`` of a uniform-random action law flown on the same case
and the return ``R_opt,i`` of the replay of the case's minimum-fuel optimum::

    score_i = 100 · (R_i − R_rand,i) / (R_opt,i − R_rand,i)

0 is the random policy (:class:`guidance.laws.random.RandomLaw`), 100 the per-case
optimum. D4RL normalises with one expert return per
env (a trained policy's); here the expert is each case's certified optimum, so the reference is
exact and differs per case. The reported score is the mean of ``score_i`` over the cases where
both references are finite and the optimum's return exceeds the random one. It does not replace
the success rate and the fuel gap: a policy can score near 100 and still crash now and then.

>>> import numpy as np
>>> normalised_score(np.array([5.0, 10.0]), np.array([0.0, 0.0]), np.array([10.0, 10.0]))
Score(per_case=array([ 50., 100.]), mean=75.0, n_cases=2)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from guidance.laws.random import RANDOM_SEED, RandomLaw

__all__ = ["RandomLaw", "Score", "normalised_score", "RANDOM_SEED"]


@dataclass
class Score:
    """Normalised score: ``per_case`` (n,) with NaN where a reference is missing or
    degenerate, ``mean`` over the ``n_cases`` scored cases (NaN if none)."""

    per_case: np.ndarray
    mean: float
    n_cases: int


def normalised_score(returns, random_returns, optimum_returns) -> Score:
    """100 · (return − random) / (optimum − random), per case and averaged.

    Parameters
    ----------
    returns, random_returns, optimum_returns : array_like, shape (n,)
        Per-case episode returns of the policy, of the uniform-random law and of the optimum,
        on the same cases. NaN marks a missing reference (e.g. an optimum that did not
        converge).

    Returns
    -------
    Score
        Cases where a reference is NaN, or the optimum's return does not exceed the random
        one, are NaN in ``per_case`` and left out of ``mean``.

    Raises
    ------
    ValueError
        The three arrays are not one-dimensional of the same length.
    """
    r = np.asarray(returns, dtype=np.float64)
    lo = np.asarray(random_returns, dtype=np.float64)
    hi = np.asarray(optimum_returns, dtype=np.float64)
    if not (r.ndim == lo.ndim == hi.ndim == 1 and r.shape == lo.shape == hi.shape):
        raise ValueError(f"returns {r.shape}, random_returns {lo.shape} and optimum_returns "
                         f"{hi.shape} must be one-dimensional arrays of the same length")
    ok = np.isfinite(r) & np.isfinite(lo) & np.isfinite(hi) & (hi > lo)
    per_case = np.full(r.shape, np.nan)
    per_case[ok] = 100.0 * (r[ok] - lo[ok]) / (hi[ok] - lo[ok])
    n = int(ok.sum())
    return Score(per_case=per_case, mean=float(np.mean(per_case[ok])) if n else float("nan"),
                 n_cases=n)
