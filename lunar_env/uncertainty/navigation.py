"""Navigation errors: the per-decision noise, the hand-over to the terminal sensors and the one
navigation-error kernel every task's navigation calls.

The navigated state is the truth plus, along (up, downrange, crossrange), an error that depends
on the true altitude h. Above the terminal sensors' acquisition altitude it is the inertial
solution's: a bias per episode and white noise per decision. Below, it is the terminal sensors'
own (drawn independently of the inertial solution's): a per-episode error and a per-decision
noise that are fractions of the altitude (a range sensor's error is a fraction of its range),
plus a floor per episode; and the velocimeter's bias and noise. Over a hand-over band just below
acquisition the two blend linearly (:func:`blend_weight`), as a navigation filter converges on
a new measurement type. The noise is counter-based: a pure function of the episode's noise key
and the decision index (:func:`navigation_noise`; the terminal sensors' from a key of their own,
:data:`TERMINAL_SALT`), so case k's noise is the same whatever the batch it flies in.

Compiled callers (a task's fused navigation kernel, which draws the noise, computes the errors
and offsets the state in one pass over the batch) use four names of this module:

- :func:`standard_normals` fills the decision's standard normals for the whole batch;
- :func:`terminal_normals` fills the terminal sensors' (only where a lander is below
  acquisition);
- :func:`navigation_error` gives lander i's six errors; it is inlined into the caller, so the
  model's arithmetic is written once and costs no call per lander;
- the model's :meth:`~lunar_env.uncertainty.UncertaintyModel.navigation_constants` packs the
  navigation part once per task.

:meth:`~lunar_env.uncertainty.EpisodeErrors.navigation_errors` composes the same kernel from
Python; the tasks' fused kernels equal it bit for bit.
"""

from __future__ import annotations

import numba
import numpy as np
from numba.extending import register_jitable

from ._random import NUMPY_ERROR_MODEL, standard_normals

__all__ = ["standard_normals", "terminal_normals", "navigation_error", "navigation_noise",
           "blend_weight", "TERMINAL_SALT", "IMU_SALT", "EPISODE_SALT"]

#: salts of the keys of the terminal sensors' and the IMU's counter-based noise, derived from an
#: episode's navigation noise key (so they are streams of their own: the inertial solution's
#: noise is the same with or without them)
TERMINAL_SALT = np.uint64(0x7E2A_11DA_5E45_0125)
IMU_SALT = np.uint64(0x1A11_5EED_AC0E_1E20)
#: salt of the key of the sensors' per-episode draws
EPISODE_SALT = np.uint64(0x5E50_0E91_50DE_D2A3)


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
@register_jitable(inline="always", **NUMPY_ERROR_MODEL)
def blend_weight(altitude_m, acquisition_m, band_fraction):
    """The weight of the inertial solution's error at ``altitude_m`` (scalars or arrays): 1 at
    and above the acquisition altitude, 0 below the hand-over band (``band_fraction`` of the
    acquisition altitude below it), linear in between; the terminal sensors' error has
    weight 1 − w."""
    if acquisition_m <= 0.0:  # no terminal sensors: the inertial solution throughout
        return altitude_m * 0.0 + 1.0
    low = acquisition_m * (1.0 - band_fraction)
    return np.minimum(np.maximum((altitude_m - low) / (acquisition_m - low), 0.0), 1.0)


@register_jitable(inline="always", **NUMPY_ERROR_MODEL)
def terminal_normals(keys, counters, altitude_m, acquisition_m, z):
    """Fill ``z`` (6, n) with the terminal sensors' standard normals of landers with navigation
    noise keys ``keys`` at decision indices ``counters`` (laid out as :func:`standard_normals`),
    when any lander's true altitude ``altitude_m`` (n,) is below ``acquisition_m``; otherwise
    leave it (nobody reads it)."""
    below = False
    for i in range(keys.shape[0]):
        if altitude_m[i] < acquisition_m and acquisition_m > 0.0:
            below = True
            break
    if below:
        tkeys = np.empty(keys.shape[0], dtype=np.uint64)
        for i in range(keys.shape[0]):
            tkeys[i] = keys[i] ^ TERMINAL_SALT
        standard_normals(tkeys, counters, z)


@register_jitable(inline="always", **NUMPY_ERROR_MODEL)
def navigation_error(z, zt, i, altitude_m, bias_p, bias_v, t_frac, t_floor, t_vel, c, n_axes):
    """Lander i's navigation errors (position up, downrange, crossrange (m), velocity up,
    downrange, crossrange (m/s)) as a 6-tuple, at true altitude ``altitude_m``.

    Above the acquisition altitude the errors are the inertial solution's alone, bias + σ·z,
    the arithmetic of a model without terminal sensors.

    Parameters
    ----------
    z : ndarray, shape (2 · n_axes, n)
        The decision's standard normals of the inertial solution, as :func:`standard_normals`
        lays them out (interleaved position/velocity per axis, see :func:`navigation_noise`).
    zt : ndarray, shape (6, n)
        The terminal sensors' normals (:func:`terminal_normals`; read only below acquisition).
    i : int
        The lander's row.
    altitude_m : float
        Its true altitude (m).
    bias_p, bias_v : ndarray, shape (n, 3)
        The episodes' inertial biases (m, m/s).
    t_frac, t_floor, t_vel : ndarray, shape (n, 3)
        The episodes' terminal-sensor errors: position as a fraction of the altitude, the
        position floor (m), the velocity bias (m/s).
    c : ndarray, shape (14,)
        :meth:`~lunar_env.uncertainty.UncertaintyModel.navigation_constants` of the model.
    n_axes : int
        2 leaves the crossrange errors 0 (``z`` then needs only 4 rows); 3 for a 3D task.
    """
    p0 = bias_p[i, 0] + z[0, i] * c[0]
    v0 = bias_v[i, 0] + z[1, i] * c[3]
    p1 = bias_p[i, 1] + z[2, i] * c[1]
    v1 = bias_v[i, 1] + z[3, i] * c[4]
    p2 = 0.0
    v2 = 0.0
    if n_axes > 2:
        p2 = bias_p[i, 2] + z[4, i] * c[2]
        v2 = bias_v[i, 2] + z[5, i] * c[5]
    if altitude_m >= c[6] or c[6] <= 0.0:  # above acquisition, or no terminal sensors
        return p0, p1, p2, v0, v1, v2
    w = blend_weight(altitude_m, c[6], c[7])
    h = max(altitude_m, 0.0)
    q0 = h * (t_frac[i, 0] + zt[0, i] * c[8]) + t_floor[i, 0]
    u0 = t_vel[i, 0] + zt[1, i] * c[11]
    q1 = h * (t_frac[i, 1] + zt[2, i] * c[9]) + t_floor[i, 1]
    u1 = t_vel[i, 1] + zt[3, i] * c[12]
    q2 = 0.0
    u2 = 0.0
    if n_axes > 2:
        q2 = h * (t_frac[i, 2] + zt[4, i] * c[10]) + t_floor[i, 2]
        u2 = t_vel[i, 2] + zt[5, i] * c[13]
    return (w * p0 + (1.0 - w) * q0, w * p1 + (1.0 - w) * q1, w * p2 + (1.0 - w) * q2,
            w * v0 + (1.0 - w) * u0, w * v1 + (1.0 - w) * u1, w * v2 + (1.0 - w) * u2)


@numba.njit(cache=True, **NUMPY_ERROR_MODEL)
def _errors_kernel(keys, counters, altitude_m, bias_p, bias_v, t_frac, t_floor, t_vel, c,
                   n_axes, dpos, dvel):  # pragma: no cover  (compiled)
    n = keys.shape[0]
    z = np.empty((2 * n_axes, n))
    standard_normals(keys, counters, z)
    zt = np.zeros((6, n))
    terminal_normals(keys, counters, altitude_m, c[6], zt)
    for i in range(n):
        e = navigation_error(z, zt, i, altitude_m[i], bias_p, bias_v, t_frac, t_floor, t_vel,
                             c, n_axes)
        for j in range(3):
            dpos[i, j] = e[j]
            dvel[i, j] = e[3 + j]


def _errors(c: np.ndarray, errors, counters: np.ndarray, altitude_m: np.ndarray, n_axes: int
            ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`navigation_error` of every lander of ``errors`` (an EpisodeErrors), in one
    compiled call: (dpos, dvel) (n, 3)."""
    n = len(counters)
    dpos = np.empty((n, 3))
    dvel = np.empty((n, 3))
    _errors_kernel(np.ascontiguousarray(errors.noise_key, dtype=np.uint64),
                   np.ascontiguousarray(counters, dtype=np.int64),
                   np.ascontiguousarray(altitude_m, dtype=np.float64),
                   errors.nav_position_bias_m, errors.nav_velocity_bias_m_s,
                   errors.sensor_position_fraction, errors.sensor_position_floor_m,
                   errors.sensor_velocity_bias_m_s, c, int(n_axes), dpos, dvel)
    return dpos, dvel
