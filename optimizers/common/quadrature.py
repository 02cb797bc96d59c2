"""Legendre–Gauss quadrature and Lagrange differentiation matrices (pseudospectral methods).

Used by :mod:`optimizers.transcription.gpm` ([001] eq. (14)–(15)) and the direct-shooting node
layout (:func:`optimizers.transcription.direct_shooting.gauss_segment_fractions`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["legendre_gauss", "lagrange_derivative_matrix", "gauss_differentiation_matrix",
           "lagrange_interpolate"]


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


def lagrange_interpolate(nodes: np.ndarray, values: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The Lagrange polynomial through ``values`` (N, d) at distinct ``nodes`` (N,), evaluated at
    ``x`` (n,) (barycentric formula, Berrut & Trefethen 2004); exact at the nodes.

    Returns
    -------
    ndarray, shape (n, d)
    """
    nodes = np.asarray(nodes, dtype=float)
    values = np.asarray(values, dtype=float)
    x = np.atleast_1d(np.asarray(x, dtype=float))
    diff = nodes[:, None] - nodes[None, :]
    np.fill_diagonal(diff, 1.0)
    w = 1.0 / np.prod(diff, axis=1)
    d = x[:, None] - nodes[None, :]
    exact = d == 0.0
    d[exact] = 1.0
    c = w[None, :] / d
    out = (c @ values) / c.sum(axis=1)[:, None]
    hit = exact.any(axis=1)
    if hit.any():
        out[hit] = values[np.argmax(exact[hit], axis=1)]
    return out
