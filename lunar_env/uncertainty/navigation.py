"""Navigation errors: the per-decision noise, the terminal sensors' weight and the one
navigation-error kernel every task's navigation calls.

The navigated state is the truth plus, along (up, downrange, crossrange), a bias per episode
and white noise per decision, both scaled by the terminal sensors' weight at the true altitude
(:meth:`~lunar_env.uncertainty.UncertaintyModel.radar_weight`). The noise is counter-based:
a pure function of the episode's noise key and the decision index (:func:`navigation_noise`),
so case k's noise is the same whatever the batch it flies in.

Compiled callers (a task's fused navigation kernel, which draws the noise, computes the errors
and offsets the state in one pass over the batch) use three names of this module:

- :func:`navigation_constants` packs the model's navigation part once per task;
- :func:`standard_normals` fills the decision's standard normals for the whole batch;
- :func:`navigation_error` gives lander i's six errors; it is inlined into the caller, so the
  model's arithmetic is written once and costs no call per lander.

:meth:`~lunar_env.uncertainty.EpisodeErrors.navigation_errors` composes the same kernel from
Python; the tasks' fused kernels equal it bit for bit.
"""

from __future__ import annotations

import numba
import numpy as np
from numba.extending import register_jitable

from ._random import NUMPY_ERROR_MODEL, standard_normals

__all__ = ["standard_normals", "navigation_error", "navigation_noise"]

@numba.njit(cache=True, **NUMPY_ERROR_MODEL)
def _noise_kernel(keys, counters, out):  # pragma: no cover  (compiled)
    """:func:`standard_normals` into ``out`` (n, m), lander-major."""
    n, m = out.shape
    z = np.empty((m, n))
    standard_normals(keys, counters, z)
    for i in range(n):
        for j in range(m):
            out[i, j] = z[j, i]


def navigation_noise(keys: np.ndarray, counters: np.ndarray, n_components: int = 6
                     ) -> np.ndarray:
    """Standard normals (n, n_components), truncated at ±4.5, of episodes with noise keys
    ``keys`` (n,) uint64 at decision indices ``counters`` (n,): a pure function of (key,
    counter, component), so a lander's noise does not depend on the batch it flies in, and
    component j is the same whatever ``n_components``. The navigation errors read them
    interleaved: (position up, velocity up, position downrange, velocity downrange, position
    crossrange, velocity crossrange)."""
    out = np.empty((len(keys), int(n_components)))
    _noise_kernel(np.ascontiguousarray(keys, dtype=np.uint64),
                  np.ascontiguousarray(counters, dtype=np.int64), out)
    return out


# inlined into the compiled callers (numba IR inlining): a call to a helper compiled in
# another module is not inlined by LLVM, and pays a reference count increment and decrement per
# array argument, per lander (measured: ~130 ns per lander for the navigation errors' row)
@register_jitable(inline="always")
def _shrink(altitude_m, radar_altitude_m, lock_fraction, floor):
    """The terminal sensors' multiplier of a navigation error at ``altitude_m`` (scalars or
    arrays): 1 above the lock altitude, ``lock_fraction`` × altitude / lock altitude below it,
    never under ``floor``."""
    h = np.maximum(altitude_m / radar_altitude_m, 0.0)
    above = h > 1.0
    return above * 1.0 + (1.0 - above) * np.maximum(lock_fraction * h, floor)


@register_jitable(inline="always", **NUMPY_ERROR_MODEL)
def navigation_error(z, i, altitude_m, bias_p, bias_v, c, n_axes):
    """Lander i's navigation errors (position up, downrange, crossrange (m), velocity up,
    downrange, crossrange (m/s)) as a 6-tuple, at true altitude ``altitude_m``: (bias + σ ·
    noise) × the terminal sensors' weight.

    Parameters
    ----------
    z : ndarray, shape (2 · n_axes, n)
        The decision's standard normals as :func:`standard_normals` lays them out
        (interleaved position/velocity per axis, see :func:`navigation_noise`).
    i : int
        The lander's row.
    altitude_m : float
        Its true altitude (m).
    bias_p, bias_v : ndarray, shape (n, 3)
        The episodes' navigation biases (m, m/s).
    c : ndarray, shape (10,)
        :meth:`~lunar_env.uncertainty.UncertaintyModel.navigation_constants`.
    n_axes : int
        2 leaves the crossrange errors 0 (``z`` then needs only 4 rows); 3 for a 3D task.

    Compiled callers only (inlined into them): the per-lander step of every navigation
    kernel, so that the model is written once.
    """
    wp = _shrink(altitude_m, c[6], c[7], c[8])
    wv = _shrink(altitude_m, c[6], c[7], c[9])
    p0 = wp * (bias_p[i, 0] + z[0, i] * c[0])
    v0 = wv * (bias_v[i, 0] + z[1, i] * c[3])
    p1 = wp * (bias_p[i, 1] + z[2, i] * c[1])
    v1 = wv * (bias_v[i, 1] + z[3, i] * c[4])
    p2 = 0.0
    v2 = 0.0
    if n_axes > 2:
        p2 = wp * (bias_p[i, 2] + z[4, i] * c[2])
        v2 = wv * (bias_v[i, 2] + z[5, i] * c[5])
    return p0, p1, p2, v0, v1, v2


@numba.njit(cache=True, **NUMPY_ERROR_MODEL)
def _errors_kernel(keys, counters, altitude_m, bias_p, bias_v, c, n_axes, dpos, dvel
                   ):  # pragma: no cover  (compiled)
    z = np.empty((2 * n_axes, keys.shape[0]))
    standard_normals(keys, counters, z)
    for i in range(keys.shape[0]):
        e = navigation_error(z, i, altitude_m[i], bias_p, bias_v, c, n_axes)
        for j in range(3):
            dpos[i, j] = e[j]
            dvel[i, j] = e[3 + j]


def _errors(c: np.ndarray, keys: np.ndarray, bias_p: np.ndarray, bias_v: np.ndarray,
            counters: np.ndarray, altitude_m: np.ndarray, n_axes: int
            ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`navigation_error` of every lander, in one compiled call: (dpos, dvel) (n, 3)."""
    n = len(counters)
    dpos = np.empty((n, 3))
    dvel = np.empty((n, 3))
    _errors_kernel(np.ascontiguousarray(keys, dtype=np.uint64),
                   np.ascontiguousarray(counters, dtype=np.int64),
                   np.ascontiguousarray(altitude_m, dtype=np.float64), bias_p, bias_v, c,
                   int(n_axes), dpos, dvel)
    return dpos, dvel


def _weights(altitude_m: np.ndarray, radar_altitude_m: float, lock_fraction: float,
             position_floor: float, velocity_floor: float) -> tuple[np.ndarray, np.ndarray]:
    """The position and velocity weights of the terminal sensors at ``altitude_m`` (NumPy)."""
    h = np.asarray(altitude_m, dtype=np.float64)
    return (_shrink(h, radar_altitude_m, lock_fraction, position_floor),
            _shrink(h, radar_altitude_m, lock_fraction, velocity_floor))
