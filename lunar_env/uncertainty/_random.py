"""The counter-based generator of the navigation noise (private to :mod:`lunar_env.uncertainty`).

A draw is a pure function of (noise key, decision index, component): splitmix64 hashes give
uniforms, Acklam's rational approximation of the normal quantile turns them into standard
normals, truncated at ±:data:`TRUNCATION_SIGMA`. Nothing here depends on the batch a lander
flies in, so case k's noise is the same whatever the batch size, the chunking or the arrays a
caller reads. :mod:`lunar_env.uncertainty.navigation` is the public face of this module.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba.extending import register_jitable

__all__ = ["TRUNCATION_SIGMA", "NUMPY_ERROR_MODEL", "splitmix64", "normal_quantile",
           "standard_normals"]

#: every error draw is a standard normal truncated at this many σ
TRUNCATION_SIGMA = 4.5

#: The compiled noise runs with NumPy's error model: under the default (Python's) every
#: division tests its divisor for zero and may raise, a branch that keeps LLVM from vectorising
#: the loops (measured: the hash and central-quantile passes run 4-8x faster without it). No
#: divisor here can be zero (the quantile's denominators are > 0.3 on their branches, the units
#: are positive), so the results are the same to the bit.
NUMPY_ERROR_MODEL = {"error_model": "numpy"}

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S32 = np.uint64(32)
_LOW32 = np.uint64(0xFFFFFFFF)
_TWO32_INV = 1.0 / 4294967296.0


@numba.njit(cache=True)
def splitmix64(x):  # pragma: no cover  (compiled)
    """Steele, Lea & Flood's splitmix64 finaliser of the uint64 ``x`` (a bijective hash)."""
    z = x + _GOLDEN
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    return z ^ (z >> _S31)


# Acklam's rational approximation of the normal quantile (relative error < 1.2e-9): the
# central 95 % of draws cost a dozen flops and no transcendental function, which is what keeps
# per-decision noise for thousands of landers cheap next to the integration.
_A = (-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
      1.383577518672690e+02, -3.066479806614716e+01, 2.506628277459239e+00)
_B = (-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
      6.680131188771972e+01, -1.328068155288572e+01)
_C = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
      -2.549732539343734e+00, 4.374664141464968e+00, 2.938163982698783e+00)
_D = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
      3.754408661907416e+00)
_P_LOW = 0.02425


@register_jitable(**NUMPY_ERROR_MODEL)
def _is_tail(p):
    """p lies in a tail of Acklam's algorithm (:func:`_normal_tail`, else
    :func:`_normal_central`)."""
    return p < _P_LOW or p > 1.0 - _P_LOW


@register_jitable(**NUMPY_ERROR_MODEL)
def _normal_central(p):
    """Φ⁻¹(p) for p in [_P_LOW, 1 - _P_LOW] (Acklam's central rational function)."""
    q = p - 0.5
    r = q * q
    return (((((_A[0] * r + _A[1]) * r + _A[2]) * r + _A[3]) * r + _A[4]) * r + _A[5]) * q \
        / (((((_B[0] * r + _B[1]) * r + _B[2]) * r + _B[3]) * r + _B[4]) * r + 1.0)


@register_jitable(**NUMPY_ERROR_MODEL)
def _normal_tail(p):
    """Φ⁻¹(p) for p in (0, _P_LOW) or (1 - _P_LOW, 1) (Acklam's tails)."""
    q = math.sqrt(-2.0 * math.log(p if p < 0.5 else 1.0 - p))
    x = ((((( _C[0] * q + _C[1]) * q + _C[2]) * q + _C[3]) * q + _C[4]) * q + _C[5]) \
        / ((((_D[0] * q + _D[1]) * q + _D[2]) * q + _D[3]) * q + 1.0)
    return x if p < 0.5 else -x


@register_jitable(**NUMPY_ERROR_MODEL)
def normal_quantile(p):
    """Φ⁻¹(p) for p in (0, 1) (Acklam's algorithm)."""
    return _normal_tail(p) if _is_tail(p) else _normal_central(p)


@register_jitable(**NUMPY_ERROR_MODEL)
def _truncate(z):
    """A standard normal truncated at ±TRUNCATION_SIGMA."""
    return min(max(z, -TRUNCATION_SIGMA), TRUNCATION_SIGMA)


@register_jitable(**NUMPY_ERROR_MODEL)
def standard_normals(keys, counters, z):
    """The navigation noise's standard normals into ``z`` (m, n), component-major (component
    j of lander i at ``z[j, i]``), for noise keys ``keys`` (n,) uint64 at decision indices
    ``counters`` (n,) int64.

    Two normals per 64-bit hash: lander i's hash for components (j, j + 1) (j even) is
    splitmix64(base_i + j + 1) with base_i = splitmix64(key_i ^ splitmix64(counter_i)); each
    32-bit half (high for j, low for j + 1) is a uniform (k + ½)/2³² in (0, 1), mapped through
    the normal quantile (:func:`normal_quantile`) and truncated at ±TRUNCATION_SIGMA.

    Computed in passes over the whole batch, not per lander, so that LLVM vectorises them: the
    hashes and uniforms, then the central rational function for every draw, then the ~5 % of
    draws in a tail (whose logarithm, if-converted into the vectorised pass, would be paid by
    every draw). Each draw goes through exactly the arithmetic of :func:`normal_quantile`.
    """
    m, n = z.shape
    base = np.empty(n, dtype=np.uint64)
    for i in range(n):
        base[i] = splitmix64(keys[i] ^ splitmix64(np.uint64(counters[i])))
    for j in range(0, m, 2):
        zj = z[j]
        inc = np.uint64(j + 1)
        if j + 1 < m:
            zk = z[j + 1]
            for i in range(n):
                h = splitmix64(base[i] + inc)
                zj[i] = (np.float64(h >> _S32) + 0.5) * _TWO32_INV
                zk[i] = (np.float64(h & _LOW32) + 0.5) * _TWO32_INV
        else:
            for i in range(n):
                zj[i] = (np.float64(splitmix64(base[i] + inc) >> _S32) + 0.5) * _TWO32_INV
    u = z.reshape(-1)
    # the tails are found before the central pass overwrites the uniforms
    tails = np.empty(u.shape[0], dtype=np.int64)
    n_tail = 0
    for k in range(u.shape[0]):
        if _is_tail(u[k]):
            tails[n_tail] = k
            n_tail += 1
    p_tail = np.empty(n_tail)
    for t in range(n_tail):
        p_tail[t] = u[tails[t]]
    for k in range(u.shape[0]):
        u[k] = _truncate(_normal_central(u[k]))
    for t in range(n_tail):
        u[tails[t]] = _truncate(_normal_tail(p_tail[t]))
