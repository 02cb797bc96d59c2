"""Equations of motion: the single source of truth for every env and optimiser.

Two models, each written once as a pure function of its state *components*. The same
function evaluates on floats, on NumPy arrays (batched, one column per component), inside
compiled numba kernels (:mod:`lunar_env.integrators`) and on CasADi symbols (collocation
constraints and Pontryagin costate equations get exact derivatives from it). It only uses
arithmetic and NumPy ufuncs (``np.sin``, ``np.cos``, ``np.sqrt``), which all four back-ends
understand.

All quantities here are **normalised** (suffix ``_nd`` at the API edges): μ = 1, lengths in
units of ``Scaling.length_m``, masses in ``Scaling.mass_kg`` (see :mod:`lunar_env.scaling`).

Planar polar two-body model ([000] Zhu & Xu 2007, eq. (1)–(5); [003]; [002])
-----------------------------------------------------------------------------

With heliocentric constants, the same model is [002]'s Earth–Mars transfer.

=========  ======  ================================  =================
index      symbol  meaning                           unit (normalised)
=========  ======  ================================  =================
``R``      r       radius from the body's centre     L
``VR``     v       radial velocity                   sqrt(μ/L)
``THETA``  θ       polar angle (downrange), from Oy  rad
``OMEGA``  ω       angular rate dθ/dt                sqrt(μ/L³)
``M``      m       mass                              m_ref
=========  ======  ================================  =================

Control: ``PHI`` φ (rad), thrust angle to the local horizontal, positive when the thrust has an
upward radial component; cos φ > 0 brakes the horizontal motion (thrust opposes the direction
of motion, [000]). ``THROTTLE`` ∈ [0, 1] multiplies the maximum thrust (paper 000's engine is
"constant or 0"; paper 003 varies the magnitude)::

    r' = v
    v' = (F/m) sin φ − 1/r² + r ω²
    θ' = ω
    ω' = −[(F/m) cos φ + 2 v ω] / r
    m' = −F / c                        (c = Isp·g0, effective exhaust velocity)

3D landing on a rotating Moon ([001] Peng et al. 2012)
------------------------------------------------------

The paper's spherical equations (eq. 11) are singular at the poles and OCR-garbled; we
integrate the vector equation they come from::

    dV/dt = F/m − μ r/|r|³ − 2 Ω × V − Ω × (Ω × r),

in a **Moon-fixed Cartesian** frame (singularity-free):

======  ========  =========================================
index   symbol    meaning
======  ========  =========================================
``X``   x         Moon-fixed position; +Z is the spin axis, +X through (lon 0, lat 0)
``Y``   y
``Z``   z
``VX``  vx        velocity relative to the rotating Moon (= the paper's V)
``VY``  vy
``VZ``  vz
``M3``  m         mass
======  ========  =========================================

Frame conventions. The paper's inertial frame has its O X1 axis along the spin axis; ours puts
the spin axis on +Z (the usual selenographic convention), so the paper's (X1, Y1, Z1) map to our
(Z, X, Y). Longitude λ = atan2(y, x), latitude φ = asin(z/r). The *orbital frame* o x y z of the
controls ([001], §1) is

- x̂ = r/|r|                         (radial, up),
- ŷ = (n̂ × x̂)/|n̂ × x̂|               (horizontal, along the reference orbit plane: at the
  initial instant it is the direction of motion),
- ẑ = x̂ × ŷ                          (horizontal, toward the reference orbit normal),

where n̂ is the unit normal of the *initial* Moon-fixed orbit plane, n̂ = r0 × V0/|r0 × V0|, a
constant of the scenario. The frame is singular only at the two poles of that plane (90° of arc
from the ground track, never approached by a descent). Thrust direction from elevation α and
azimuth β ([001] eq. 10): ê = sin α x̂ + cos α cos β ŷ + cos α sin β ẑ; β = 180° brakes along the
track. The paper's relative velocity components are u = V·x̂, v = V·ŷ, w = V·ẑ
(:func:`moon3d_derived`). Control channels: ``ALPHA``, ``BETA`` (rad), ``THROTTLE3`` ∈ [0, 1].

With Ω = 0 and the motion and thrust in the reference plane, this model reduces exactly to the
planar one (tested).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba.extending import register_jitable

__all__ = [
    "R", "VR", "THETA", "OMEGA", "M", "PHI", "THROTTLE", "PLANAR_STATE_NAMES",
    "X", "Y", "Z", "VX", "VY", "VZ", "M3", "ALPHA", "BETA", "THROTTLE3", "MOON3D_STATE_NAMES",
    "PlanarParams", "Moon3DParams", "planar_eom", "moon3d_eom", "planar_thrust_terms",
    "planar_eom_terms", "moon3d_thrust_terms", "moon3d_eom_terms", "planar_rhs", "moon3d_rhs",
    "planar_rhs_casadi", "moon3d_rhs_casadi", "moon3d_derived", "orbital_frame",
    "planar_energy", "planar_angular_momentum", "moon3d_jacobi",
]

R, VR, THETA, OMEGA, M = range(5)
PHI, THROTTLE = range(2)
PLANAR_STATE_NAMES = ("r", "vr", "theta", "omega", "m")

X, Y, Z, VX, VY, VZ, M3 = range(7)
ALPHA, BETA, THROTTLE3 = range(3)
MOON3D_STATE_NAMES = ("x", "y", "z", "vx", "vy", "vz", "m")


@dataclass(frozen=True)
class PlanarParams:
    """Normalised constants of the planar model (μ = 1).

    Attributes
    ----------
    thrust_nd : float
        Maximum thrust F / (m_ref · μ/L²).
    exhaust_velocity_nd : float
        c = Isp·g0 in units of sqrt(μ/L).
    """

    thrust_nd: float
    exhaust_velocity_nd: float

    def as_array(self) -> np.ndarray:
        """Parameters packed for the compiled kernels, shape (2,)."""
        return np.array([self.thrust_nd, self.exhaust_velocity_nd], dtype=np.float64)


@dataclass(frozen=True)
class Moon3DParams:
    """Normalised constants of the rotating-Moon model (μ = 1).

    Attributes
    ----------
    thrust_nd, exhaust_velocity_nd : float
        As in :class:`PlanarParams`.
    spin_rate_nd : float
        Moon's spin rate Ω about +Z in units of sqrt(μ/L³).
    plane_normal : tuple of 3 floats
        Unit normal n̂ of the reference (initial) orbit plane in the Moon-fixed frame; defines
        the orbital frame of the thrust angles.
    """

    thrust_nd: float
    exhaust_velocity_nd: float
    spin_rate_nd: float
    plane_normal: tuple[float, float, float]

    def as_array(self) -> np.ndarray:
        """Parameters packed for the compiled kernels, shape (6,)."""
        n = self.plane_normal
        return np.array(
            [self.thrust_nd, self.exhaust_velocity_nd, self.spin_rate_nd, n[0], n[1], n[2]],
            dtype=np.float64,
        )


# --------------------------------------------------------------------------------------------
# The equations, once. Keep these to arithmetic and np ufuncs: numba and CasADi evaluate them.
# --------------------------------------------------------------------------------------------


# Each model is split into the part that depends on the control only (its trigonometry) and the
# part that depends on the state. ``*_eom`` composes the two and is what every consumer calls;
# the compiled kernels call the two halves themselves so that a control held over an RK4 step
# costs one sin/cos, not four.


@register_jitable(inline="always")
def planar_thrust_terms(phi, throttle):
    """Control part of the planar model: ``(throttle·sin φ, throttle·cos φ, throttle)``."""
    return throttle * np.sin(phi), throttle * np.cos(phi), throttle


@register_jitable(inline="always")
def planar_eom_terms(r, vr, omega, m, up, brake, throttle, thrust, exhaust_velocity):
    """State part of the planar model, given :func:`planar_thrust_terms` ``(up, brake, throttle)``.
    """
    accel = thrust / m
    dr = vr
    dvr = accel * up - 1.0 / (r * r) + r * omega * omega
    dtheta = omega
    domega = -(accel * brake + 2.0 * vr * omega) / r
    dm = -thrust * throttle / exhaust_velocity
    return dr, dvr, dtheta, domega, dm


def planar_eom(r, vr, omega, m, phi, throttle, thrust, exhaust_velocity):
    """Right-hand side of the planar model, component-wise ([000] eq. (1)).

    Arguments are normalised scalars, equal-shape arrays, or CasADi symbols. θ does not appear
    on the right-hand side. Returns ``(dr, dvr, dtheta, domega, dm)``.
    """
    up, brake, thr = planar_thrust_terms(phi, throttle)
    return planar_eom_terms(r, vr, omega, m, up, brake, thr, thrust, exhaust_velocity)


# register_jitable: a plain Python function that compiled kernels may also call.
@register_jitable(inline="always")
def orbital_frame(x, y, z, nx, ny, nz):
    """Unit vectors (x̂, ŷ, ẑ) of the orbital frame at Moon-fixed position (x, y, z).

    ``(nx, ny, nz)`` is the reference orbit normal n̂. Returns nine components
    ``(xr, yr, zr, xt, yt, zt, xn, yn, zn)``: radial x̂, along-track ŷ, cross-track ẑ.
    """
    r = np.sqrt(x * x + y * y + z * z)
    xr = x / r
    yr = y / r
    zr = z / r
    # n̂ × x̂, normalised
    xt = ny * zr - nz * yr
    yt = nz * xr - nx * zr
    zt = nx * yr - ny * xr
    nt = np.sqrt(xt * xt + yt * yt + zt * zt)
    xt = xt / nt
    yt = yt / nt
    zt = zt / nt
    # x̂ × ŷ
    xn = yr * zt - zr * yt
    yn = zr * xt - xr * zt
    zn = xr * yt - yr * xt
    return xr, yr, zr, xt, yt, zt, xn, yn, zn


@register_jitable(inline="always")
def moon3d_thrust_terms(alpha, beta, throttle):
    """Control part of the 3D model: throttle-scaled thrust direction in the orbital frame,
    ``(radial, along-track, cross-track, throttle)`` = throttle·(sin α, cos α cos β, cos α sin β).
    """
    ca = np.cos(alpha)
    return (throttle * np.sin(alpha), throttle * ca * np.cos(beta), throttle * ca * np.sin(beta),
            throttle)


@register_jitable(inline="always")
def moon3d_eom_terms(x, y, z, vx, vy, vz, m, e_r, e_t, e_n, throttle, thrust, exhaust_velocity,
                     spin, nx, ny, nz):
    """State part of the 3D model, given :func:`moon3d_thrust_terms` ``(e_r, e_t, e_n, throttle)``.
    """
    xr, yr, zr, xt, yt, zt, xn, yn, zn = orbital_frame(x, y, z, nx, ny, nz)
    accel = thrust / m
    ex = e_r * xr + e_t * xt + e_n * xn
    ey = e_r * yr + e_t * yt + e_n * yn
    ez = e_r * zr + e_t * zt + e_n * zn
    r2 = x * x + y * y + z * z
    inv_r3 = 1.0 / (r2 * np.sqrt(r2))
    spin2 = spin * spin
    # −2Ω×V = 2·spin·(vy, −vx, 0);  −Ω×(Ω×r) = spin²·(x, y, 0)
    dvx = accel * ex - x * inv_r3 + 2.0 * spin * vy + spin2 * x
    dvy = accel * ey - y * inv_r3 - 2.0 * spin * vx + spin2 * y
    dvz = accel * ez - z * inv_r3
    dm = -thrust * throttle / exhaust_velocity
    return vx, vy, vz, dvx, dvy, dvz, dm


def moon3d_eom(x, y, z, vx, vy, vz, m, alpha, beta, throttle, thrust, exhaust_velocity,
               spin, nx, ny, nz):
    """Right-hand side of the rotating-Moon model in the Moon-fixed frame, component-wise.

    dV/dt = F/m − r/|r|³ − 2Ω×V − Ω×(Ω×r) with Ω = spin·Ẑ and μ = 1 ([001] eq. (1)).
    Returns ``(dx, dy, dz, dvx, dvy, dvz, dm)``.
    """
    e_r, e_t, e_n, thr = moon3d_thrust_terms(alpha, beta, throttle)
    return moon3d_eom_terms(x, y, z, vx, vy, vz, m, e_r, e_t, e_n, thr, thrust,
                            exhaust_velocity, spin, nx, ny, nz)


# --------------------------------------------------------------------------------------------
# Batched NumPy front ends: rhs(state, control, params) -> dstate
# --------------------------------------------------------------------------------------------


def planar_rhs(state: np.ndarray, control: np.ndarray, params: PlanarParams) -> np.ndarray:
    """Batched planar right-hand side.

    Parameters
    ----------
    state : ndarray, shape (batch, 5)
        Normalised state (r, vr, θ, ω, m).
    control : ndarray, shape (batch, 2)
        (φ rad, throttle).
    params : PlanarParams

    Returns
    -------
    ndarray, shape (batch, 5)
    """
    s = np.asarray(state, dtype=np.float64)
    u = np.asarray(control, dtype=np.float64)
    d = planar_eom(s[..., R], s[..., VR], s[..., OMEGA], s[..., M], u[..., PHI],
                   u[..., THROTTLE], params.thrust_nd, params.exhaust_velocity_nd)
    return np.stack(d, axis=-1)


def moon3d_rhs(state: np.ndarray, control: np.ndarray, params: Moon3DParams) -> np.ndarray:
    """Batched rotating-Moon right-hand side.

    Parameters
    ----------
    state : ndarray, shape (batch, 7)
        Normalised Moon-fixed (x, y, z, vx, vy, vz, m).
    control : ndarray, shape (batch, 3)
        (α rad, β rad, throttle).
    params : Moon3DParams

    Returns
    -------
    ndarray, shape (batch, 7)
    """
    s = np.asarray(state, dtype=np.float64)
    u = np.asarray(control, dtype=np.float64)
    n = params.plane_normal
    d = moon3d_eom(s[..., X], s[..., Y], s[..., Z], s[..., VX], s[..., VY], s[..., VZ],
                   s[..., M3], u[..., ALPHA], u[..., BETA], u[..., THROTTLE3], params.thrust_nd,
                   params.exhaust_velocity_nd, params.spin_rate_nd, n[0], n[1], n[2])
    return np.stack(d, axis=-1)


def _casadi():
    import casadi

    try:
        casadi.GlobalOptions.setNumpyMode(1)
    except AttributeError:  # CasADi < 3.7 has no numpy mode and needs none
        pass
    return casadi


def planar_rhs_casadi(state, control, params: PlanarParams):
    """Planar right-hand side on CasADi symbols: state (5,), control (2,) -> column (5,)."""
    ca = _casadi()
    d = planar_eom(state[R], state[VR], state[OMEGA], state[M], control[PHI],
                   control[THROTTLE], params.thrust_nd, params.exhaust_velocity_nd)
    return ca.vertcat(*d)


def moon3d_rhs_casadi(state, control, params: Moon3DParams):
    """Rotating-Moon right-hand side on CasADi symbols: state (7,), control (3,) -> (7,)."""
    ca = _casadi()
    n = params.plane_normal
    d = moon3d_eom(state[X], state[Y], state[Z], state[VX], state[VY], state[VZ], state[M3],
                   control[ALPHA], control[BETA], control[THROTTLE3], params.thrust_nd,
                   params.exhaust_velocity_nd, params.spin_rate_nd, n[0], n[1], n[2])
    return ca.vertcat(*d)


# --------------------------------------------------------------------------------------------
# Derived outputs and invariants
# --------------------------------------------------------------------------------------------


def moon3d_derived(state: np.ndarray, params: Moon3DParams) -> dict[str, np.ndarray]:
    """Longitude, latitude, radius and the paper's u, v, w from a Moon-fixed state.

    Parameters
    ----------
    state : ndarray, shape (..., 7)
        Normalised state.
    params : Moon3DParams
        Supplies the reference plane normal that defines the orbital frame.

    Returns
    -------
    dict
        ``longitude_rad``, ``latitude_rad``, ``radius_nd``, ``u_nd`` (radial), ``v_nd``
        (along-track), ``w_nd`` (cross-track), each of shape (...).
    """
    s = np.asarray(state, dtype=np.float64)
    x, y, z = s[..., X], s[..., Y], s[..., Z]
    vx, vy, vz = s[..., VX], s[..., VY], s[..., VZ]
    n = params.plane_normal
    xr, yr, zr, xt, yt, zt, xn, yn, zn = orbital_frame(x, y, z, n[0], n[1], n[2])
    r = np.sqrt(x * x + y * y + z * z)
    return {
        "longitude_rad": np.arctan2(y, x),
        "latitude_rad": np.arcsin(z / r),
        "radius_nd": r,
        "u_nd": vx * xr + vy * yr + vz * zr,
        "v_nd": vx * xt + vy * yt + vz * zt,
        "w_nd": vx * xn + vy * yn + vz * zn,
    }


def planar_energy(state: np.ndarray) -> np.ndarray:
    """Specific orbital energy ½(v² + r²ω²) − 1/r, shape (...,). Conserved with thrust off."""
    s = np.asarray(state, dtype=np.float64)
    r, vr, om = s[..., R], s[..., VR], s[..., OMEGA]
    return 0.5 * (vr * vr + r * r * om * om) - 1.0 / r


def planar_angular_momentum(state: np.ndarray) -> np.ndarray:
    """Specific angular momentum r²ω, shape (...,). Conserved with thrust off."""
    s = np.asarray(state, dtype=np.float64)
    return s[..., R] ** 2 * s[..., OMEGA]


def moon3d_jacobi(state: np.ndarray, spin_rate_nd: float) -> np.ndarray:
    """Jacobi integral ½|V|² − 1/r − ½Ω²(x² + y²), shape (...,). Conserved with thrust off."""
    s = np.asarray(state, dtype=np.float64)
    x, y, z = s[..., X], s[..., Y], s[..., Z]
    v2 = s[..., VX] ** 2 + s[..., VY] ** 2 + s[..., VZ] ** 2
    r = np.sqrt(x * x + y * y + z * z)
    return 0.5 * v2 - 1.0 / r - 0.5 * spin_rate_nd**2 * (x * x + y * y)
