"""Legendre–Gauss quadrature and Lagrange differentiation matrices (pseudospectral methods).

Used by :mod:`optimizers.transcription.gpm` ([001] eq. (14)–(15)) and the direct-shooting node
layout (:func:`optimizers.transcription.direct_shooting.gauss_segment_fractions`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["legendre_gauss", "lagrange_derivative_matrix", "gauss_differentiation_matrix"]


def legendre_gauss(n_nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Legendre–Gauss points (roots of P_N) and quadrature weights on [−1, 1].

    Returns
    -------
    tau : ndarray, shape (n_nodes,), increasing
    weights : ndarray, shape (n_nodes,)
        Exact for polynomials of degree ≤ 2N − 1.
    """
    n = int(n_nodes)
    if n < 1:
        raise ValueError(f"n_nodes = {n_nodes!r} must be >= 1")
    tau, w = np.polynomial.legendre.leggauss(n)
    return tau, w


def lagrange_derivative_matrix(support: np.ndarray) -> np.ndarray:
    """Derivatives of the Lagrange basis on ``support`` at the support points.

    ``M[k, i] = L_i'(s_k)`` (barycentric formulas, Berrut & Trefethen 2004).

    Parameters
    ----------
    support : ndarray, shape (m,), distinct points

    Returns
    -------
    ndarray, shape (m, m)
    """
    s = np.asarray(support, dtype=float)
    diff = s[:, None] - s[None, :]
    np.fill_diagonal(diff, 1.0)
    bary = 1.0 / np.prod(diff, axis=1)
    m = (bary[None, :] / bary[:, None]) / diff
    np.fill_diagonal(m, 0.0)
    np.fill_diagonal(m, -m.sum(axis=1))
    return m


def gauss_differentiation_matrix(n_nodes: int) -> np.ndarray:
    """The GPM differentiation matrix D ∈ R^{N×(N+1)} ([001] eq. (14)).

    ``D[k-1, i] = L_i'(τ_k)`` for the Lagrange basis L_0..L_N on (−1, τ_1..τ_N), k = 1..N:
    applied to the values of a polynomial of degree ≤ N at those N + 1 points it gives the
    exact derivative at the LG points.
    """
    tau, _ = legendre_gauss(n_nodes)
    return lagrange_derivative_matrix(np.concatenate([[-1.0], tau]))[1:, :]
