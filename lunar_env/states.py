"""Named state layouts and their SI <-> normalised conversions (one place for the whole project).

The kernels integrate normalised states (:mod:`lunar_env.dynamics`, μ = 1); users, scenarios,
datasets and experts speak SI. The two layouts of each model and the conversions between them
live here, so no other module indexes a state row by a bare number or re-derives a scaling.

Planar SI row (papers 000, 002, 003)
------------------------------------

======================  ====  ===================================================
index                   unit  meaning
======================  ====  ===================================================
``SI_RADIUS``           m     radius from the body's centre
``SI_RADIAL_VELOCITY``  m/s   radial velocity
``SI_THETA``            rad   polar angle (downrange)
``SI_TANGENTIAL``       m/s   tangential velocity r·ω (positive along the motion)
``SI_MASS``             kg    mass
======================  ====  ===================================================

The normalised planar row is (r, v, θ, ω, m) with the indices of :mod:`lunar_env.dynamics`
(``R, VR, THETA, OMEGA, M``): note ω, not r·ω, in the fourth slot.

3D (paper 001): the normalised Moon-fixed Cartesian row (x, y, z, vx, vy, vz, m) of
:mod:`lunar_env.dynamics`; its SI row has the same order in m, m/s and kg.

>>> import numpy as np
>>> from lunar_env.scaling import Scaling
>>> s = Scaling(1753e3, 4902.75e9, 600.0)
>>> row = np.array([1753e3, -10.0, 0.1, 1691.6, 600.0])
>>> bool(np.allclose(planar_nd_to_si(planar_si_to_nd(row, s), s), row))
True
"""

from __future__ import annotations

import numpy as np

from . import dynamics as dyn
from .scaling import Scaling

__all__ = [
    "SI_RADIUS", "SI_RADIAL_VELOCITY", "SI_THETA", "SI_TANGENTIAL", "SI_MASS",
    "PLANAR_SI_FIELDS", "MOON3D_SI_FIELDS", "planar_si_to_nd", "planar_nd_to_si",
    "moon3d_si_to_nd", "moon3d_nd_to_si", "check_planar_state_si", "check_planar_states_si",
]

SI_RADIUS, SI_RADIAL_VELOCITY, SI_THETA, SI_TANGENTIAL, SI_MASS = range(5)
PLANAR_SI_FIELDS = ("radius_m", "radial_velocity_m_s", "theta_rad", "tangential_velocity_m_s",
                    "mass_kg")
MOON3D_SI_FIELDS = ("x_m", "y_m", "z_m", "vx_m_s", "vy_m_s", "vz_m_s", "mass_kg")
_PLANAR_ROW = "(r m, vr m/s, θ rad, v_t m/s, m kg)"


def planar_si_to_nd(si, scaling: Scaling) -> np.ndarray:
    """SI planar rows (..., 5) -> normalised (r, v, θ, ω, m), same shape."""
    si = np.asarray(si, dtype=np.float64)
    out = np.empty_like(si)
    out[..., dyn.R] = scaling.length_nd(si[..., SI_RADIUS])
    out[..., dyn.VR] = scaling.velocity_nd(si[..., SI_RADIAL_VELOCITY])
    out[..., dyn.THETA] = si[..., SI_THETA]
    out[..., dyn.OMEGA] = scaling.rate_nd(si[..., SI_TANGENTIAL] / si[..., SI_RADIUS])
    out[..., dyn.M] = scaling.mass_nd(si[..., SI_MASS])
    return out


def planar_nd_to_si(nd, scaling: Scaling) -> np.ndarray:
    """Normalised planar rows (..., 5) (r, v, θ, ω, m) -> SI rows (r, vr, θ, v_t, m)."""
    y = np.asarray(nd, dtype=np.float64)
    out = np.empty_like(y)
    out[..., SI_RADIUS] = y[..., dyn.R] * scaling.length_m
    out[..., SI_RADIAL_VELOCITY] = y[..., dyn.VR] * scaling.velocity_m_s
    out[..., SI_THETA] = y[..., dyn.THETA]
    out[..., SI_TANGENTIAL] = y[..., dyn.R] * y[..., dyn.OMEGA] * scaling.velocity_m_s
    out[..., SI_MASS] = y[..., dyn.M] * scaling.mass_kg
    return out


def moon3d_si_to_nd(si, scaling: Scaling) -> np.ndarray:
    """SI Moon-fixed rows (..., 7) (m, m/s, kg) -> normalised."""
    si = np.asarray(si, dtype=np.float64)
    out = np.empty_like(si)
    out[..., dyn.X:dyn.Z + 1] = scaling.length_nd(si[..., dyn.X:dyn.Z + 1])
    out[..., dyn.VX:dyn.VZ + 1] = scaling.velocity_nd(si[..., dyn.VX:dyn.VZ + 1])
    out[..., dyn.M3] = scaling.mass_nd(si[..., dyn.M3])
    return out


def moon3d_nd_to_si(nd, scaling: Scaling) -> np.ndarray:
    """Normalised Moon-fixed rows (..., 7) -> SI (m, m/s, kg)."""
    y = np.asarray(nd, dtype=np.float64)
    out = np.empty_like(y)
    out[..., dyn.X:dyn.Z + 1] = y[..., dyn.X:dyn.Z + 1] * scaling.length_m
    out[..., dyn.VX:dyn.VZ + 1] = y[..., dyn.VX:dyn.VZ + 1] * scaling.velocity_m_s
    out[..., dyn.M3] = y[..., dyn.M3] * scaling.mass_kg
    return out


def check_planar_state_si(row, *, dry_mass_kg: float, name: str = "initial_state_si"
                          ) -> np.ndarray:
    """Validate one SI planar row and return it as a float array of shape (5,).

    Raises
    ------
    ValueError
        Wrong shape, a non-finite component, a radius <= 0 or a mass at or below the dry mass;
        the message names the component, the value and what is allowed.
    """
    arr = np.asarray(row, dtype=np.float64)
    if arr.shape != (5,):
        raise ValueError(f"{name} has shape {arr.shape}; expected (5,) = {_PLANAR_ROW}")
    for i, field in enumerate(PLANAR_SI_FIELDS):
        if not np.isfinite(arr[i]):
            raise ValueError(f"{name}.{field} = {arr[i]!r} is not finite; all 5 components of "
                             f"{_PLANAR_ROW} must be")
    if arr[SI_RADIUS] <= 0.0:
        raise ValueError(f"{name}.radius_m = {arr[SI_RADIUS]!r} must be > 0")
    if arr[SI_MASS] <= dry_mass_kg:
        raise ValueError(f"{name}.mass_kg = {arr[SI_MASS]!r} must be > the dry mass "
                         f"{dry_mass_kg!r} kg")
    return arr


def check_planar_states_si(rows, *, dry_mass_kg: float, name: str = "initial_states_si"
                           ) -> np.ndarray:
    """Validate SI planar rows (N, 5); errors name the first bad row. Returns a float array."""
    arr = np.asarray(rows, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 5:
        raise ValueError(f"{name} has shape {arr.shape}; expected (N, 5) rows {_PLANAR_ROW}")
    for i, row in enumerate(arr):
        check_planar_state_si(row, dry_mass_kg=dry_mass_kg, name=f"{name} row {i}")
    return arr
