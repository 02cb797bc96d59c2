"""Lambert's problem, batched and compiled: Izzo's 2015 algorithm (Householder iterations).

Given two positions r1, r2 (m), a time of flight tof (s) and the gravitational parameter μ
(m³/s²), find the Keplerian arcs from r1 to r2 in time tof and their end velocities v1, v2.
This is two-body physics, so it lives beside :mod:`lunar_env.dynamics`; paper [004] (Wang et
al. 2001) builds its free-time two-impulse transfers on it.

Algorithm: D. Izzo, "Revisiting Lambert's problem", Celest. Mech. Dyn. Astr. 121 (2015) 1–15.
The time of flight is written in Izzo's variable x (−1 < x < 1 ellipses, x = 1 parabola,
x > 1 hyperbolas) with λ = ±sqrt(1 − c/s) carrying the geometry, and solved by third-order
Householder iterations from Izzo's initial guesses; T(x) uses the Battin hypergeometric series
near the parabola (|x − 1| < 0.01), Lagrange's expression up to |x − 1| < 0.2 and Lancaster's
elsewhere. Multi-revolution solutions: for N revolutions two arcs exist when tof exceeds the
N-revolution minimum time (found with Halley's method on dT/dx = 0).

Solutions of one problem, in this fixed layout (the same as pykep's ``lambert_problem``)
-----------------------------------------------------------------------------------------

======================  =====================  =========================================
index                   revolutions N          branch
======================  =====================  =========================================
0                       0                      the single-revolution arc
2N − 1                  N ≥ 1                  "left" branch  (x < x_Tmin: the one with the
                                               larger x-negative semi-major axis side)
2N                      N ≥ 1                  "right" branch (x > x_Tmin)
======================  =====================  =========================================

Both branches of N revolutions have the same time of flight; their x differ: the left branch
(x < x_Tmin) is the lower-energy ("low path") solution for long tof, the right branch the
other one (``LambertSolutions.branch`` gives ``-1``/``+1``, 0 for N = 0). An index whose N
exceeds the problem's own maximum has ``valid = False`` and NaN velocities.

Direction: ``prograde=True`` makes the arc's angular momentum point along +ẑ of
r1 × r2 when that has a positive z component (the transfer angle is then the short way when
r1 × r2 points to +z and the long way otherwise), as in pykep (``cw=False``);
``prograde=False`` is the clockwise arc (pykep's ``cw=True``). For a planar problem in the
x-y plane: prograde = counter-clockwise seen from +z.

Degenerate input raises ``ValueError`` naming the problem index and value: r1 and r2 collinear
(0° or 180° apart: the transfer plane is undefined), tof ≤ 0, μ ≤ 0, a zero position, NaN or
infinite entries.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numba import njit, prange

__all__ = ["LambertSolutions", "LambertFlatSolutions", "solve_lambert", "solve_lambert_flat",
           "COLLINEAR_SIN_TOL", "max_revolutions",
           "planar_polar_state", "propagate_planar_coast"]

# |r̂1 × r̂2| below this: r1 and r2 are taken as collinear (the plane of the arc is undefined;
# near it the cross product, hence the plane, is dominated by round-off).
COLLINEAR_SIN_TOL = 1e-10

_BATTIN = 0.01      # |x − 1| below this: Battin's hypergeometric series
_LAGRANGE = 0.2     # |x − 1| below this (and above _BATTIN): Lagrange's expression
_TOL_SINGLE = 1e-5  # Householder stop on |Δx| (Izzo 2015): the last step is third order, so x
# is then converged to round-off (tested against pykep to 1e-13 relative)
_TOL_MULTI = 1e-8
_MAX_ITER = 15
_PI = math.pi
# LLVM may contract a*b+c into FMAs, reassociate and use reciprocals; NaN and inf keep their
# IEEE meaning (no "nnan"/"ninf"): the non-convergence checks rely on math.isfinite.
_FM = {"contract", "arcp", "reassoc", "nsz"}

STATUS_OK = 0
STATUS_NOT_CONVERGED = 1


@njit(cache=True, fastmath=_FM)
def _hypergeometric(z, tol):
    s = 1.0
    cj = 1.0
    err = 1.0
    j = 0
    while err > tol and j < 1000:
        cj1 = cj * (3.0 + j) * (1.0 + j) / (2.5 + j) * z / (j + 1.0)
        s += cj1
        err = abs(cj1)
        cj = cj1
        j += 1
    return s


@njit(cache=True, fastmath=_FM)
def _x2tof_lagrange(x, n, lam):
    a = 1.0 / (1.0 - x * x)
    if a > 0.0:  # ellipse
        alfa = 2.0 * math.acos(x)
        beta = 2.0 * math.asin(math.sqrt(lam * lam / a))
        if lam < 0.0:
            beta = -beta
        return a * math.sqrt(a) * ((alfa - math.sin(alfa)) - (beta - math.sin(beta))
                                   + 2.0 * _PI * n) / 2.0
    alfa = 2.0 * math.acosh(x)
    beta = 2.0 * math.asinh(math.sqrt(-lam * lam / a))
    if lam < 0.0:
        beta = -beta
    return -a * math.sqrt(-a) * ((beta - math.sinh(beta)) - (alfa - math.sinh(alfa))) / 2.0


@njit(cache=True, fastmath=_FM)
def _x2tof(x, n, lam):
    """Non-dimensional time of flight T(x) for N = n revolutions (Izzo 2015, eq. 18–20)."""
    dist = abs(x - 1.0)
    if _BATTIN <= dist < _LAGRANGE:
        return _x2tof_lagrange(x, n, lam)
    k = lam * lam
    e = x * x - 1.0
    rho = abs(e)
    z = math.sqrt(1.0 + k * e)
    if dist < _BATTIN:
        eta = z - lam * x
        s1 = 0.5 * (1.0 - lam - x * eta)
        q = 4.0 / 3.0 * _hypergeometric(s1, 1e-11)
        return (eta ** 3 * q + 4.0 * lam * eta) / 2.0 + n * _PI / rho ** 1.5
    y = math.sqrt(rho)
    g = x * z - lam * e
    if e < 0.0:
        d = n * _PI + math.acos(min(1.0, max(-1.0, g)))
    else:
        f = y * (z - lam * x)
        d = math.log(f + g)
    return (x - lam * z - d / y) / e


@njit(cache=True, fastmath=_FM)
def _dtdx(x, t, lam):
    """First three derivatives of T(x) at (x, T(x)) (Izzo 2015, eq. 22)."""
    l2 = lam * lam
    l3 = l2 * lam
    umx2 = 1.0 - x * x
    y = math.sqrt(1.0 - l2 * umx2)
    y2 = y * y
    y3 = y2 * y
    d1 = (3.0 * t * x - 2.0 + 2.0 * l3 * x / y) / umx2
    d2 = (3.0 * t + 5.0 * x * d1 + 2.0 * (1.0 - l2) * l3 / y3) / umx2
    d3 = (7.0 * x * d2 + 8.0 * d1 - 6.0 * (1.0 - l2) * l2 * l3 * x / y3 / y2) / umx2
    return d1, d2, d3


@njit(cache=True, fastmath=_FM)
def _householder(t_target, x0, n, lam, tol, max_iter):
    """Solve T(x) = t_target from x0; returns (x, iterations, converged)."""
    x = x0
    it = 0
    err = 1.0
    while err > tol and it < max_iter:
        t = _x2tof(x, n, lam)
        d1, d2, d3 = _dtdx(x, t, lam)
        delta = t - t_target
        d1sq = d1 * d1
        xnew = x - delta * (d1sq - delta * d2 / 2.0) / (
            d1 * (d1sq - delta * d2) + d3 * delta * delta / 6.0)
        err = abs(x - xnew)
        x = xnew
        it += 1
        if not math.isfinite(x):
            return x, it, False
    return x, it, err <= tol


@njit(cache=True, fastmath=_FM)
def _max_revs(t, lam):
    """Largest N for which T exceeds the N-revolution minimum time (Halley on dT/dx = 0)."""
    n_max = int(math.floor(t / _PI))
    t00 = math.acos(lam) + lam * math.sqrt(1.0 - lam * lam)
    t0 = t00 + n_max * _PI
    if n_max > 0 and t < t0:
        x_old = 0.0
        x_new = 0.0
        t_min = t0
        it = 0
        while True:
            d1, d2, d3 = _dtdx(x_old, t_min, lam)
            if d1 != 0.0:
                x_new = x_old - d1 * d2 / (d2 * d2 - d1 * d3 / 2.0)
            err = abs(x_old - x_new)
            if err < 1e-13 or it > 12:
                break
            t_min = _x2tof(x_new, n_max, lam)
            x_old = x_new
            it += 1
        if t_min > t:
            n_max -= 1
    return n_max


@njit(cache=True, fastmath=_FM)
def _geometry(r1, r2, tof, mu, clockwise):
    """Izzo's non-dimensional geometry: (λ, T, r1n, r2n, c, s, ir1, ir2, it1, it2)."""
    r1n = math.sqrt(r1[0] ** 2 + r1[1] ** 2 + r1[2] ** 2)
    r2n = math.sqrt(r2[0] ** 2 + r2[1] ** 2 + r2[2] ** 2)
    cx, cy, cz = r2[0] - r1[0], r2[1] - r1[1], r2[2] - r1[2]
    c = math.sqrt(cx * cx + cy * cy + cz * cz)
    s = (c + r1n + r2n) / 2.0
    ir1 = (r1[0] / r1n, r1[1] / r1n, r1[2] / r1n)
    ir2 = (r2[0] / r2n, r2[1] / r2n, r2[2] / r2n)
    hx = ir1[1] * ir2[2] - ir1[2] * ir2[1]
    hy = ir1[2] * ir2[0] - ir1[0] * ir2[2]
    hz = ir1[0] * ir2[1] - ir1[1] * ir2[0]
    hn = math.sqrt(hx * hx + hy * hy + hz * hz)
    hx, hy, hz = hx / hn, hy / hn, hz / hn
    lam = math.sqrt(max(0.0, 1.0 - c / s))
    if hz < 0.0:  # the counter-clockwise (prograde) arc goes the long way (angle > π)
        lam = -lam
        t1 = (ir1[1] * hz - ir1[2] * hy, ir1[2] * hx - ir1[0] * hz, ir1[0] * hy - ir1[1] * hx)
        t2 = (ir2[1] * hz - ir2[2] * hy, ir2[2] * hx - ir2[0] * hz, ir2[0] * hy - ir2[1] * hx)
    else:
        t1 = (hy * ir1[2] - hz * ir1[1], hz * ir1[0] - hx * ir1[2], hx * ir1[1] - hy * ir1[0])
        t2 = (hy * ir2[2] - hz * ir2[1], hz * ir2[0] - hx * ir2[2], hx * ir2[1] - hy * ir2[0])
    sgn = 1.0
    if clockwise:
        lam = -lam
        sgn = -1.0
    n1 = math.sqrt(t1[0] ** 2 + t1[1] ** 2 + t1[2] ** 2)
    n2 = math.sqrt(t2[0] ** 2 + t2[1] ** 2 + t2[2] ** 2)
    it1 = (sgn * t1[0] / n1, sgn * t1[1] / n1, sgn * t1[2] / n1)
    it2 = (sgn * t2[0] / n2, sgn * t2[1] / n2, sgn * t2[2] / n2)
    t = math.sqrt(2.0 * mu / s ** 3) * tof
    return lam, t, r1n, r2n, c, s, ir1, ir2, it1, it2


@njit(cache=True, fastmath=_FM)
def _solve_one(r1, r2, tof, mu, clockwise, n_use, v1, v2, iters, ok):
    """One problem with n_use (<= its N_max) revolutions at most: fills v1, v2 (n_rows, 3),
    iters and ok (n_rows,); rows beyond 2·n_use + 1, and non-converged rows, are NaN."""
    lam, t, r1n, r2n, c, s, ir1, ir2, it1, it2 = _geometry(r1, r2, tof, mu, clockwise)
    n_rows = v1.shape[0]
    # single revolution: Izzo's initial guess (eq. 30)
    t00 = math.acos(lam) + lam * math.sqrt(1.0 - lam * lam)
    t1_par = 2.0 / 3.0 * (1.0 - lam ** 3)
    if t >= t00:
        x0 = -(t - t00) / (t - t00 + 4.0)
    elif t <= t1_par:
        x0 = t1_par * (t1_par - t) / (2.0 / 5.0 * (1.0 - lam ** 5) * t) + 1.0
    else:
        x0 = (t / t00) ** (0.69314718055994529 / math.log(t1_par / t00)) - 1.0
    gamma = math.sqrt(mu * s / 2.0)
    rho = (r1n - r2n) / c
    sigma = math.sqrt(max(0.0, 1.0 - rho * rho))
    for j in range(n_rows):
        if j > 2 * n_use:
            ok[j] = False
            iters[j] = 0
            for d in range(3):
                v1[j, d] = np.nan
                v2[j, d] = np.nan
            continue
        if j == 0:
            x, k, conv = _householder(t, x0, 0, lam, _TOL_SINGLE, _MAX_ITER)
        else:
            i = (j + 1) // 2
            if j % 2 == 1:  # left branch
                tmp = ((i * _PI + _PI) / (8.0 * t)) ** (2.0 / 3.0)
            else:           # right branch
                tmp = (8.0 * t / (i * _PI)) ** (2.0 / 3.0)
            x, k, conv = _householder(t, (tmp - 1.0) / (tmp + 1.0), i, lam, _TOL_MULTI,
                                      _MAX_ITER)
        iters[j] = k
        # velocities from x (Izzo 2015, Algorithm 1, last block)
        y = math.sqrt(1.0 - lam * lam + lam * lam * x * x)
        vr1 = gamma * ((lam * y - x) - rho * (lam * y + x)) / r1n
        vr2 = -gamma * ((lam * y - x) + rho * (lam * y + x)) / r2n
        vt = gamma * sigma * (y + lam * x)
        good = conv and math.isfinite(vr1) and math.isfinite(vr2) and math.isfinite(vt)
        ok[j] = good
        for d in range(3):
            if good:
                v1[j, d] = vr1 * ir1[d] + vt / r1n * it1[d]
                v2[j, d] = vr2 * ir2[d] + vt / r2n * it2[d]
            else:
                v1[j, d] = np.nan
                v2[j, d] = np.nan


@njit(cache=True, fastmath=_FM)
def _nmax_batch(r1, r2, tof, mu, clockwise, n_max):
    for b in range(r1.shape[0]):
        lam, t = _geometry(r1[b], r2[b], tof[b], mu[b], clockwise[b])[:2]
        n_max[b] = _max_revs(t, lam)


@njit(cache=True, fastmath=_FM)
def _batch_serial(r1, r2, tof, mu, clockwise, n_use, v1, v2, iters, ok):
    for b in range(r1.shape[0]):
        _solve_one(r1[b], r2[b], tof[b], mu[b], clockwise[b], n_use[b], v1[b], v2[b], iters[b],
                   ok[b])


@njit(cache=True, parallel=True, fastmath=_FM)
def _batch_parallel(r1, r2, tof, mu, clockwise, n_use, v1, v2, iters, ok):
    for b in prange(r1.shape[0]):
        _solve_one(r1[b], r2[b], tof[b], mu[b], clockwise[b], n_use[b], v1[b], v2[b], iters[b],
                   ok[b])


@njit(cache=True, fastmath=_FM)
def _flat_serial(r1, r2, tof, mu, clockwise, n_use, offsets, v1, v2, iters, ok):
    for b in range(r1.shape[0]):
        lo, hi = offsets[b], offsets[b + 1]
        _solve_one(r1[b], r2[b], tof[b], mu[b], clockwise[b], n_use[b], v1[lo:hi], v2[lo:hi],
                   iters[lo:hi], ok[lo:hi])


@njit(cache=True, parallel=True, fastmath=_FM)
def _flat_parallel(r1, r2, tof, mu, clockwise, n_use, offsets, v1, v2, iters, ok):
    for b in prange(r1.shape[0]):
        lo, hi = offsets[b], offsets[b + 1]
        _solve_one(r1[b], r2[b], tof[b], mu[b], clockwise[b], n_use[b], v1[lo:hi], v2[lo:hi],
                   iters[lo:hi], ok[lo:hi])


# Below this batch size the serial kernel wins (thread start-up costs more than the work).
_PARALLEL_MIN_BATCH = 2048


@dataclass(frozen=True)
class LambertSolutions:
    """All Lambert arcs of a batch of problems (layout in the module docstring).

    Attributes
    ----------
    v1_m_s, v2_m_s : ndarray, shape (batch, n_rows, 3)
        Velocity just after leaving r1 and on arrival at r2 (m/s); NaN where ``valid`` is
        False. ``n_rows = 2·n + 1`` with n = min(max_revs, the largest N_max of the batch).
    valid : ndarray of bool, shape (batch, n_rows)
        The solution exists (N ≤ min(N_max, max_revs)) and the iteration converged.
    failed : ndarray of bool, shape (batch, n_rows)
        The solution exists but the Householder iteration did not converge (never seen on the
        kep3 benchmark protocol; reported rather than hidden).
    iterations : ndarray of int, shape (batch, n_rows)
    n_max : ndarray of int, shape (batch,)
        Largest number of revolutions for which solutions exist (not capped by max_revs).
    n_revs : ndarray of int, shape (n_rows,)
        Revolutions of each solution index: 0, 1, 1, 2, 2, ...
    branch : ndarray of int, shape (n_rows,)
        0 for N = 0, −1 for the left branch (x < x_Tmin), +1 for the right branch.
    """

    v1_m_s: np.ndarray
    v2_m_s: np.ndarray
    valid: np.ndarray
    failed: np.ndarray
    iterations: np.ndarray
    n_max: np.ndarray
    n_revs: np.ndarray
    branch: np.ndarray

    @property
    def n_solutions(self) -> np.ndarray:
        """Number of valid solutions of each problem, shape (batch,)."""
        return self.valid.sum(axis=1)


@dataclass(frozen=True)
class LambertFlatSolutions:
    """All Lambert arcs of a batch, one row per solution (no padding): what
    :func:`solve_lambert_flat` returns. Solutions of problem b are the rows
    ``offsets[b]:offsets[b + 1]``, in the order of :class:`LambertSolutions`.

    Attributes
    ----------
    v1_m_s, v2_m_s : ndarray, shape (n_solutions, 3)
        NaN on rows whose iteration failed (``failed``).
    problem, n_revs, branch, iterations : ndarray of int, shape (n_solutions,)
    failed : ndarray of bool, shape (n_solutions,)
    offsets : ndarray of int, shape (batch + 1,)
    n_max : ndarray of int, shape (batch,)
    """

    v1_m_s: np.ndarray
    v2_m_s: np.ndarray
    problem: np.ndarray
    n_revs: np.ndarray
    branch: np.ndarray
    iterations: np.ndarray
    failed: np.ndarray
    offsets: np.ndarray
    n_max: np.ndarray


def _layout(max_revs: int) -> tuple[np.ndarray, np.ndarray]:
    n_sol = 2 * max_revs + 1
    idx = np.arange(n_sol)
    n_revs = (idx + 1) // 2
    branch = np.where(idx == 0, 0, np.where(idx % 2 == 1, -1, 1))
    return n_revs, branch


def _bad(name: str, arr: np.ndarray, mask: np.ndarray, allowed: str) -> ValueError:
    i = int(np.flatnonzero(mask)[0])
    return ValueError(f"{name}[{i}] = {arr[i]!r} is not allowed ({int(mask.sum())} problem(s) "
                      f"affected); {allowed}")


def max_revolutions(r1_m, r2_m, tof_s, mu_m3_s2, *, prograde=True) -> np.ndarray:
    """Largest number of full revolutions N for which arcs exist, shape (batch,)."""
    return solve_lambert(r1_m, r2_m, tof_s, mu_m3_s2, prograde=prograde, max_revs=0).n_max


def _prepare(r1_m, r2_m, tof_s, mu_m3_s2, prograde, max_revs):
    """Validate and broadcast the input of :func:`solve_lambert` (see its Raises)."""
    if isinstance(max_revs, bool) or int(max_revs) != max_revs or max_revs < 0:
        raise ValueError(f"max_revs = {max_revs!r} must be an integer >= 0")
    max_revs = int(max_revs)
    r1 = np.asarray(r1_m, dtype=np.float64)
    r2 = np.asarray(r2_m, dtype=np.float64)
    tof = np.asarray(tof_s, dtype=np.float64)
    mu = np.asarray(mu_m3_s2, dtype=np.float64)
    cw = ~np.asarray(prograde, dtype=bool)
    if r1.shape[-1:] != (3,) or r2.shape[-1:] != (3,) or r1.ndim > 2 or r2.ndim > 2:
        raise ValueError(f"r1 and r2 must have shape (3,) or (batch, 3); got {r1.shape} and "
                         f"{r2.shape}")
    for name, a in (("tof_s", tof), ("mu_m3_s2", mu), ("prograde", cw)):
        if a.ndim > 1:
            raise ValueError(f"{name} must be a scalar or shape (batch,); got shape {a.shape}")
    try:
        batch = np.broadcast_shapes(r1.shape[:-1], r2.shape[:-1], tof.shape, mu.shape, cw.shape)
    except ValueError:
        raise ValueError(f"batch shapes do not broadcast: r1 {r1.shape}, r2 {r2.shape}, "
                         f"tof {tof.shape}, mu {mu.shape}, prograde {cw.shape}") from None
    n = batch[0] if batch else 1
    # writable copies: numba compiles the kernel again for every read-only combination (a
    # broadcast view of one problem is read-only)
    r1 = np.array(np.broadcast_to(r1, (n, 3)), order="C")
    r2 = np.array(np.broadcast_to(r2, (n, 3)), order="C")
    tof = np.array(np.broadcast_to(tof, (n,)), order="C")
    mu = np.array(np.broadcast_to(mu, (n,)), order="C")
    cw = np.array(np.broadcast_to(cw, (n,)), order="C")
    if not (np.isfinite(r1).all() and np.isfinite(r2).all() and np.isfinite(tof).all()
            and np.isfinite(mu).all()):
        for name, a in (("r1_m", r1), ("r2_m", r2), ("tof_s", tof), ("mu_m3_s2", mu)):
            fin = np.isfinite(a).reshape(n, -1).all(axis=1)
            if not fin.all():
                raise _bad(name, a, ~fin, "every entry must be finite")
    if np.any(tof <= 0):
        raise _bad("tof_s", tof, tof <= 0, "the time of flight must be > 0")
    if np.any(mu <= 0):
        raise _bad("mu_m3_s2", mu, mu <= 0, "the gravitational parameter must be > 0")
    n1 = np.sqrt(np.einsum("ij,ij->i", r1, r1))
    n2 = np.sqrt(np.einsum("ij,ij->i", r2, r2))
    for name, a, nn in (("r1_m", r1, n1), ("r2_m", r2, n2)):
        if np.any(nn == 0):
            raise _bad(name, a, nn == 0, "a position must be non-zero")
    # |r̂1 × r̂2| written out: numpy's cross costs more than the solve for small batches
    cx = r1[:, 1] * r2[:, 2] - r1[:, 2] * r2[:, 1]
    cy = r1[:, 2] * r2[:, 0] - r1[:, 0] * r2[:, 2]
    cz = r1[:, 0] * r2[:, 1] - r1[:, 1] * r2[:, 0]
    sin_angle = np.sqrt(cx * cx + cy * cy + cz * cz) / (n1 * n2)
    col = sin_angle < COLLINEAR_SIN_TOL
    if np.any(col):
        i = int(np.flatnonzero(col)[0])
        cosang = float(np.dot(r1[i], r2[i]) / (n1[i] * n2[i]))
        raise ValueError(
            f"r1_m[{i}] = {r1[i].tolist()} and r2_m[{i}] = {r2[i].tolist()} are collinear "
            f"(transfer angle {math.degrees(math.acos(max(-1.0, min(1.0, cosang)))):.6g}°; "
            f"{int(col.sum())} problem(s) affected): the plane of the arc is undefined; the "
            f"angle must differ from 0° and 180° (|r̂1 × r̂2| >= {COLLINEAR_SIN_TOL:g})")
    return r1, r2, tof, mu, cw, n, max_revs


def solve_lambert(r1_m, r2_m, tof_s, mu_m3_s2, *, prograde=True, max_revs: int = 0,
                  parallel: bool | None = None) -> LambertSolutions:
    """Solve a batch of Lambert problems in one compiled call (Izzo 2015).

    Parameters
    ----------
    r1_m, r2_m : array_like, shape (3,) or (batch, 3)
        Departure and arrival positions (m, any consistent length unit).
    tof_s : float or array_like, shape (batch,)
        Time of flight (s), > 0.
    mu_m3_s2 : float or array_like, shape (batch,)
        Gravitational parameter (m³/s²), > 0.
    prograde : bool or array_like of bool, shape (batch,)
        Counter-clockwise about +z (pykep's ``cw=False``); False for clockwise arcs.
    max_revs : int
        Largest number of revolutions to return (solutions up to min(N_max, max_revs)).
    parallel : bool, optional
        Force the threaded or the serial kernel (default: threaded for large batches).

    Returns
    -------
    LambertSolutions
        Arrays broadcast to the common batch size.

    Raises
    ------
    ValueError
        Non-finite input, tof ≤ 0, μ ≤ 0, a zero position, r1 and r2 collinear (0° or 180°
        apart: the plane of the arc is undefined), max_revs < 0, or shapes that do not
        broadcast.
    """
    r1, r2, tof, mu, cw, n, max_revs = _prepare(r1_m, r2_m, tof_s, mu_m3_s2, prograde,
                                                max_revs)
    n_max = np.empty(n, dtype=np.int64)
    _nmax_batch(r1, r2, tof, mu, cw, n_max)
    n_use = np.minimum(n_max, max_revs)
    # rows for the largest N any problem of the batch has (not max_revs: most would be empty)
    n_rows = 2 * (int(n_use.max()) if n else 0) + 1
    v1 = np.empty((n, n_rows, 3))
    v2 = np.empty((n, n_rows, 3))
    iters = np.empty((n, n_rows), dtype=np.int64)
    ok = np.empty((n, n_rows), dtype=np.bool_)
    if parallel is None:  # threads pay off only when there are multi-revolution rows to solve
        parallel = (n >= _PARALLEL_MIN_BATCH and n_rows > 1
                    and numba.config.NUMBA_NUM_THREADS > 1)
    kernel = _batch_parallel if parallel else _batch_serial
    kernel(r1, r2, tof, mu, cw, n_use, v1, v2, iters, ok)
    n_revs, branch = _layout(n_rows // 2)
    exists = n_revs[None, :] <= n_use[:, None]
    return LambertSolutions(v1, v2, ok, exists & ~ok, iters, n_max, n_revs, branch)


def solve_lambert_flat(r1_m, r2_m, tof_s, mu_m3_s2, *, prograde=True, max_revs: int = 0,
                       parallel: bool | None = None) -> LambertFlatSolutions:
    """:func:`solve_lambert` with one output row per existing solution (no NaN padding).

    The same solver and the same input contract; memory and time scale with the number of
    solutions instead of batch × (2·max N + 1), which matters for multi-revolution batches
    whose problems have very different N_max (the kep3 protocol: 1 to 20).
    """
    r1, r2, tof, mu, cw, n, max_revs = _prepare(r1_m, r2_m, tof_s, mu_m3_s2, prograde,
                                                max_revs)
    n_max = np.empty(n, dtype=np.int64)
    _nmax_batch(r1, r2, tof, mu, cw, n_max)
    n_use = np.minimum(n_max, max_revs)
    offsets = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(2 * n_use + 1, out=offsets[1:])
    m = int(offsets[-1])
    v1 = np.empty((m, 3))
    v2 = np.empty((m, 3))
    iters = np.empty(m, dtype=np.int64)
    ok = np.empty(m, dtype=np.bool_)
    if parallel is None:
        parallel = (n >= _PARALLEL_MIN_BATCH and m > n
                    and numba.config.NUMBA_NUM_THREADS > 1)
    (_flat_parallel if parallel else _flat_serial)(r1, r2, tof, mu, cw, n_use, offsets, v1, v2,
                                                   iters, ok)
    problem = np.repeat(np.arange(n), 2 * n_use + 1)
    j = np.arange(m) - offsets[problem]
    return LambertFlatSolutions(v1, v2, problem, (j + 1) // 2,
                                np.where(j == 0, 0, np.where(j % 2 == 1, -1, 1)), iters, ~ok,
                                offsets, n_max)


def planar_polar_state(r_m, v_m_s) -> np.ndarray:
    """Planar Cartesian (x, y) position and velocity → the planar model's SI polar state.

    θ is measured from +y toward +x (x = r sin θ, y = r cos θ), the convention of
    :mod:`lunar_env.dynamics`; the result is ``(r, v_r, θ, ω)`` with ω = dθ/dt (rad/s).
    Shapes: (..., 2) in, (..., 4) out.
    """
    r = np.asarray(r_m, dtype=np.float64)
    v = np.asarray(v_m_s, dtype=np.float64)
    rad = np.hypot(r[..., 0], r[..., 1])
    theta = np.arctan2(r[..., 0], r[..., 1])
    er = np.stack([np.sin(theta), np.cos(theta)], axis=-1)
    et = np.stack([np.cos(theta), -np.sin(theta)], axis=-1)
    return np.stack([rad, (v * er).sum(-1), theta, (v * et).sum(-1) / rad], axis=-1)


def propagate_planar_coast(r_m, v_m_s, t_s, mu_m3_s2: float, *, n_steps: int = 2000,
                           record: bool = False):
    """Coast planar states for ``t_s`` with the project's own integrator (the planar two-body
    model of :mod:`lunar_env.dynamics`, compiled RK4 of :mod:`lunar_env.integrators`, thrust
    off): the independent check of a Lambert arc, and the sampler of arcs for plots.

    Parameters
    ----------
    r_m, v_m_s : array_like, shape (batch, 2) or (batch, 3) (z must be 0)
    t_s : float or array_like, shape (batch,)
    n_steps : int
        RK4 steps per arc.
    record : bool
        Also return the positions at every step.

    Returns
    -------
    r_end_m, v_end_m_s : ndarray, shape (batch, 2)
    path_m : ndarray, shape (batch, n_steps + 1, 2), only when ``record``
    """
    from . import integrators as integ
    from .dynamics import PlanarParams
    from .scaling import Scaling

    r = np.atleast_2d(np.asarray(r_m, dtype=np.float64))
    v = np.atleast_2d(np.asarray(v_m_s, dtype=np.float64))
    if r.shape[-1] == 3:
        if np.any(r[:, 2] != 0) or np.any(v[:, 2] != 0):
            raise ValueError("propagate_planar_coast needs planar states (z = 0, vz = 0)")
        r, v = r[:, :2], v[:, :2]
    polar = planar_polar_state(r, v)
    sc = Scaling(length_m=float(np.max(polar[:, 0])), mu_m3_s2=float(mu_m3_s2), mass_kg=1.0)
    n = polar.shape[0]
    y0 = np.column_stack([polar[:, 0] / sc.length_m, polar[:, 1] / sc.velocity_m_s,
                          polar[:, 2], polar[:, 3] * sc.time_s, np.ones(n)])
    tf = np.broadcast_to(np.asarray(t_s, dtype=np.float64) / sc.time_s, (n,))
    law = integ.PiecewisePolynomial.constant(np.zeros((n, 2)), np.zeros(n), tf)
    prop = integ.integrate(integ.PLANAR, y0, t0_nd=0.0, dt_nd=tf / n_steps,
                           n_steps=int(n_steps), control=law,
                           params=PlanarParams(0.0, 1.0), record=record)

    def to_xy(y):
        rr = y[..., 0] * sc.length_m
        th = y[..., 2]
        vr = y[..., 1] * sc.velocity_m_s
        vt = rr * y[..., 3] / sc.time_s
        pos = np.stack([rr * np.sin(th), rr * np.cos(th)], axis=-1)
        vel = np.stack([vr * np.sin(th) + vt * np.cos(th), vr * np.cos(th) - vt * np.sin(th)],
                       axis=-1)
        return pos, vel

    r_end, v_end = to_xy(prop.y_end)
    if record:
        return r_end, v_end, to_xy(prop.states)[0]
    return r_end, v_end
