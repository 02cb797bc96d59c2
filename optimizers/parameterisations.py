"""Control parameterisations: decision variables with a physical meaning -> control laws.

:class:`NodePolynomial` is the "improved function approximation" of [000] Zhu & Xu 2007, §3
(also used by [002] with other sizes): the control at ``n_nodes`` equally spaced times
``t_i = t0 + i (tf − t0) / (n_nodes − 1)`` ([000] eq. 9, n = n_nodes − 1 segments) are the
decision variables, and a polynomial of degree ``degree`` is fitted through them by least
squares ([000] eq. 10, a cubic through 10 node angles). The fitted polynomial, not the node
values, drives the integration.

Vectorisation. In the normalised time s = (t − t0)/(tf − t0) ∈ [0, 1] the node abscissae are the
same for every candidate, so the least-squares fit is one constant matrix: coefficients in s are
``node_values @ P.T`` with ``P = pinv(V)``, ``V[i, k] = s_i**k``, for the whole population at
once. Coefficients in time follow from ``c_k = a_k / (tf − t0)**k``.
"""

from __future__ import annotations

import numpy as np

from lunar_env.integrators import PiecewisePolynomial

__all__ = ["NodePolynomial", "piecewise_linear_control"]


class NodePolynomial:
    """Node values at equally spaced times plus a least-squares polynomial fit.

    Parameters
    ----------
    n_nodes : int
        Number of nodes (``n + 1`` in [000] eq. 9; 10 in [000], 10 in [002]).
    degree : int
        Polynomial degree (3 in [000] eq. 10; 5 in [002], whose "N = 6 power terms"). Must
        satisfy ``degree + 1 <= n_nodes``; with equality the fit interpolates the nodes.

    Raises
    ------
    ValueError
        If ``n_nodes < 2``, ``degree < 0`` or ``degree + 1 > n_nodes``.

    Examples
    --------
    >>> import numpy as np
    >>> p = NodePolynomial(n_nodes=10, degree=3)
    >>> s = p.node_fractions
    >>> coefs = p.fit(np.array([1 + 2 * s - s**3]))     # a cubic is reproduced exactly
    >>> np.allclose(coefs, [[1, 2, 0, -1]])
    True
    """

    def __init__(self, n_nodes: int = 10, degree: int = 3) -> None:
        n_nodes = int(n_nodes)
        degree = int(degree)
        if n_nodes < 2:
            raise ValueError(f"n_nodes = {n_nodes} must be >= 2")
        if degree < 0:
            raise ValueError(f"degree = {degree} must be >= 0")
        if degree + 1 > n_nodes:
            raise ValueError(f"degree = {degree} needs at least degree + 1 = {degree + 1} nodes; "
                             f"got n_nodes = {n_nodes}")
        self.n_nodes = n_nodes
        self.degree = degree
        self.node_fractions = np.linspace(0.0, 1.0, n_nodes)
        vander = self.node_fractions[:, None] ** np.arange(degree + 1)[None, :]
        # (degree+1, n_nodes): maps node values to least-squares coefficients in s
        self._projection = np.linalg.pinv(vander)
        self._powers = np.arange(degree + 1)[None, :]

    @property
    def order(self) -> int:
        """Number of polynomial coefficients, ``degree + 1``."""
        return self.degree + 1

    def __repr__(self) -> str:
        return f"NodePolynomial(n_nodes={self.n_nodes}, degree={self.degree})"

    def node_times(self, t0, tf) -> np.ndarray:
        """Node times ``t_i`` ([000] eq. 9) for each candidate.

        Parameters
        ----------
        t0, tf : float or ndarray, shape (batch,)

        Returns
        -------
        ndarray, shape (batch, n_nodes) (same time unit as the input)
        """
        t0 = np.atleast_1d(np.asarray(t0, dtype=np.float64))
        tf = np.atleast_1d(np.asarray(tf, dtype=np.float64))
        return t0[:, None] + (tf - t0)[:, None] * self.node_fractions[None, :]

    def fit(self, node_values: np.ndarray) -> np.ndarray:
        """Least-squares coefficients in the normalised time s = (t − t0)/(tf − t0).

        Parameters
        ----------
        node_values : ndarray, shape (batch, n_nodes)

        Returns
        -------
        ndarray, shape (batch, degree + 1)
            Ascending powers of s.
        """
        v = np.asarray(node_values, dtype=np.float64)
        if v.ndim == 1:
            v = v[None, :]
        if v.shape[-1] != self.n_nodes:
            raise ValueError(f"node_values has {v.shape[-1]} columns; this parameterisation "
                             f"has n_nodes = {self.n_nodes}")
        return v @ self._projection.T

    def time_coefficients(self, node_values: np.ndarray, t0, tf) -> np.ndarray:
        """Ascending-power coefficients in τ = t − t0, shape (batch, degree + 1).

        ``t0`` and ``tf`` (float or shape (batch,)) are in the time unit of the result (the
        integrators use normalised time).
        """
        a = self.fit(node_values)
        span = np.asarray(tf, dtype=np.float64) - np.asarray(t0, dtype=np.float64)
        if not np.all(span > 0):
            raise ValueError("tf must be > t0 for every candidate")
        span = np.broadcast_to(span, a.shape[:1])
        return a / span[:, None] ** self._powers

    def evaluate(self, node_values: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Fitted polynomial at normalised times ``s`` (shape (n_s,)); returns (batch, n_s)."""
        a = self.fit(node_values)
        s = np.asarray(s, dtype=np.float64)
        return a @ (s[None, :] ** np.arange(self.order)[:, None])

    def control(self, node_values: np.ndarray, t0, tf, *, throttle: float | np.ndarray = 1.0
                ) -> PiecewisePolynomial:
        """Control law for :func:`lunar_env.integrators.integrate`: the fitted polynomial on
        channel 0 and a constant throttle on the last channel (planar model: φ, throttle).

        Parameters
        ----------
        node_values : ndarray, shape (batch, n_nodes)
            Control values at the nodes (rad for a thrust angle).
        t0, tf : float or ndarray, shape (batch,)
            Start and final time (normalised for the integrators).
        throttle : float or ndarray, shape (batch,)
            Constant throttle in [0, 1] ([000]: the engine is always on, 1).

        Returns
        -------
        PiecewisePolynomial
            One segment [t0, tf] per candidate, order ``degree + 1``.
        """
        breaks, coefs = self.control_arrays(node_values, t0, tf, throttle=throttle)
        return PiecewisePolynomial(breaks, coefs)

    def control_arrays(self, node_values: np.ndarray, t0, tf, *,
                       throttle: float | np.ndarray = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """``(breaks, coefs)`` of :meth:`control` as C-contiguous arrays, shapes (batch, 2) and
        (batch, 1, 2, degree + 1), for :func:`lunar_env.integrators.integrate_prepared`."""
        c = self.time_coefficients(node_values, t0, tf)
        batch = c.shape[0]
        coefs = np.zeros((batch, 1, 2, self.order))
        coefs[:, 0, 0, :] = c
        coefs[:, 0, 1, 0] = throttle
        breaks = np.empty((batch, 2))
        breaks[:, 0] = t0
        breaks[:, 1] = tf
        return breaks, coefs


def piecewise_linear_control(breaks_nd: np.ndarray, control_nodes_rad: np.ndarray,
                             throttle: float = 1.0) -> PiecewisePolynomial:
    """Controls linear between nodes plus a constant throttle, as a batch-1
    PiecewisePolynomial ([001] eq. (18): the direct-shooting control law).

    Parameters
    ----------
    breaks_nd : ndarray, shape (n_nodes,)
    control_nodes_rad : ndarray, shape (n_nodes, 2)
    """
    b = np.asarray(breaks_nd, dtype=float)
    u = np.asarray(control_nodes_rad, dtype=float)
    if b.ndim != 1 or u.shape != (len(b), 2):
        raise ValueError(f"breaks shape {b.shape} and control nodes shape {u.shape} do not "
                         "match; expected (n,) and (n, 2)")
    h = np.diff(b)
    if np.any(h <= 0):
        raise ValueError("control node times must be strictly increasing")
    n_seg = len(b) - 1
    coefs = np.zeros((1, n_seg, 3, 2))
    coefs[0, :, :2, 0] = u[:-1]
    coefs[0, :, :2, 1] = (u[1:] - u[:-1]) / h[:, None]
    coefs[0, :, 2, 0] = throttle
    return PiecewisePolynomial(b[None, :], coefs)
