"""Local-vertical guidance frames of the two env families, from the navigated state (SI).

:class:`LocalFrame` is what a guidance law reads as ``nav.frame`` (:mod:`guidance.law`); the
frame functions below are the two families' (:mod:`guidance.families`), called by the flight
computer, never by a law.

The explicit laws are written for a flat Moon with uniform gravity ([K74], [GHW]). The descents
here cover 15–18° of arc (about 500 km), so a fixed Cartesian frame at the site would see the
lander's local vertical swing by that much. Instead every decision builds the frame at the
lander ("curvilinear flat Moon"): its axes are the lander's local horizontal and vertical, the
position of the target is measured along the surface (arc length) and in altitude, and the
non-thrust terms of the exact equations of motion in this rotating frame are the law's known
acceleration g, evaluated now and held constant over t_go:

- gravity −μ/r² (vertical);
- the frame's rotation as the lander moves over the sphere: + v_h²/r (vertical,
  "centrifugal"), − v_r v_h/r (horizontal, "Coriolis");
- 3D only, the Moon's rotation (the state is Moon-fixed): −2Ω×V − Ω×(Ω×r), projected; the
  frame also carries the acceleration without it (``g_without_spin``), for laws that leave
  it out.

Axes are ordered (horizontal..., up): planar (downrange, up); 3D (along-track ŷ, cross-track
ẑ, up x̂) in the env's orbital frame (:func:`lunar_env.dynamics.orbital_frame`), so that the
thrust angles follow directly. The target of the 3D env is Moon-fixed (the gate 2 km above the
site, zero velocity relative to the rotating Moon): expressed in the Moon-fixed frame it
carries the Moon's rotation, as Apollo's landing-site update did.

Every function is a pure function of the state batch (shape (N, n_state), normalised as the env
state) and returns float64 SI arrays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from guidance.explicit import check_state
from lunar_env import dynamics as dyn

__all__ = ["LocalFrame", "planar_frame", "pinpoint_frame"]


@dataclass(frozen=True)
class LocalFrame:
    """The guidance frame at N landers (SI).

    Attributes
    ----------
    r_to_target : ndarray, shape (N, d)
        Target position minus lander position (m), horizontal axes first, up last (planar:
        the downrange entry is 0, the site is free).
    v : ndarray, shape (N, d)
        Surface-relative velocity (m/s).
    g : ndarray, shape (N, d)
        Known non-thrust acceleration (m/s²): gravity, the frame's rotation over the sphere,
        and the body's spin.
    mass_kg : ndarray, shape (N,)
        The flight computer's mass estimate (kg).
    height_m : ndarray, shape (N,)
        Height above the terminal surface (planar: the landing surface; 3D: the gate sphere).
    g_without_spin : ndarray, shape (N, d)
        ``g`` without the body's spin terms (the same array where the body does not spin).
    free_axes : tuple of int
        Horizontal axes with no position target (planar: downrange, the landing site is free);
        their ``r_to_target`` entries are 0.
    """

    r_to_target: np.ndarray
    v: np.ndarray
    g: np.ndarray
    mass_kg: np.ndarray
    height_m: np.ndarray
    g_without_spin: np.ndarray | None = None
    free_axes: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        if self.g_without_spin is None:
            object.__setattr__(self, "g_without_spin", self.g)

    @property
    def n(self) -> int:
        """Number of landers."""
        return len(self.mass_kg)

    @property
    def n_axes(self) -> int:
        """Axes of the frame (2 or 3)."""
        return self.v.shape[1]


def planar_frame(state_nd: np.ndarray, scaling, surface_radius_m: float) -> LocalFrame:
    """The (downrange, up) frame of planar states (r, v_r, θ, ω, m) (N, 5), normalised.

    Exact kinematics of [000] eq. (1) in this frame: dv_r/dt = a_up − μ/r² + v_t²/r and
    d(rω)/dt = a_downrange − v_r v_t/r, with v_t = rω; so g = (−v_r v_t/r, −μ/r² + v_t²/r).
    """
    s = check_state("navigated state", state_nd)
    L, V = scaling.length_m, scaling.velocity_m_s
    r = s[:, dyn.R] * L
    vr = s[:, dyn.VR] * V
    vt = s[:, dyn.R] * s[:, dyn.OMEGA] * V
    mu = scaling.mu_m3_s2
    n = len(s)
    h = r - surface_radius_m
    g = np.stack([-vr * vt / r, -mu / (r * r) + vt * vt / r], axis=1)
    return LocalFrame(r_to_target=np.stack([np.zeros(n), -h], axis=1),
                      v=np.stack([vt, vr], axis=1), g=g,
                      mass_kg=s[:, dyn.M] * scaling.mass_kg, height_m=h, free_axes=(0,))


def _rows_dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def pinpoint_frame(state_nd: np.ndarray, scaling, plane_normal: np.ndarray,
                   target_m: np.ndarray, spin_rate_rad_s: float) -> LocalFrame:
    """The (along ŷ, cross ẑ, up x̂) frame of Moon-fixed states (x, y, z, v, m) (N, 7).

    The target's horizontal position is the great-circle arc (at the lander's radius) from the
    lander to the site, along its direction at the lander; its vertical position is the gate
    radius minus the lander's radius.
    """
    s = check_state("navigated state", state_nd)
    L, V = scaling.length_m, scaling.velocity_m_s
    pos = s[:, dyn.X:dyn.Z + 1] * L
    vel = s[:, dyn.VX:dyn.VZ + 1] * V
    r = np.linalg.norm(pos, axis=1)
    up = pos / r[:, None]
    nrm = np.asarray(plane_normal, dtype=np.float64)
    along = np.cross(nrm[None, :], up)
    along /= np.linalg.norm(along, axis=1)[:, None]
    cross = np.cross(up, along)
    tgt = np.asarray(target_m, dtype=np.float64)
    r_gate = float(np.linalg.norm(tgt))
    tu = tgt / r_gate
    cos_psi = up @ tu
    horiz = tu[None, :] - cos_psi[:, None] * up
    sin_psi = np.linalg.norm(horiz, axis=1)
    psi = np.arctan2(sin_psi, cos_psi)
    hdir = horiz / np.maximum(sin_psi, 1e-15)[:, None]
    arc = r * psi
    rel = np.stack([arc * _rows_dot(hdir, along), arc * _rows_dot(hdir, cross),
                    r_gate - r], axis=1)
    vu, va, vc = _rows_dot(vel, up), _rows_dot(vel, along), _rows_dot(vel, cross)
    mu = scaling.mu_m3_s2
    g_up = -mu / (r * r) + (va * va + vc * vc) / r
    g_frame = np.stack([-vu * va / r, -vu * vc / r, g_up], axis=1)
    g = g_frame
    if spin_rate_rad_s != 0.0:
        om = np.array([0.0, 0.0, spin_rate_rad_s])
        a_rot = -2.0 * np.cross(om[None, :], vel) - np.cross(om[None, :],
                                                             np.cross(om[None, :], pos))
        g = g_frame + np.stack([_rows_dot(a_rot, along), _rows_dot(a_rot, cross),
                                _rows_dot(a_rot, up)], axis=1)
    return LocalFrame(r_to_target=rel, v=np.stack([va, vc, vu], axis=1), g=g,
                      mass_kg=s[:, dyn.M3] * scaling.mass_kg, height_m=r - r_gate,
                      g_without_spin=g_frame)
