"""Conversion between SI and the normalised units of the kernels (μ = 1).

[000] Zhu & Xu 2007, eq. (5): r_ref = L, v_ref = sqrt(μ/L), t_ref = L/v_ref, m_ref,
F_ref = m_ref v_ref²/L. Angular rates scale with 1/t_ref, exhaust velocities with v_ref.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .validation import require_finite_positive

__all__ = ["Scaling"]


@dataclass(frozen=True)
class Scaling:
    """Reference quantities that make μ = 1.

    Attributes
    ----------
    length_m : float
        Reference length L (m): r0 for paper 000, the lunar radius for paper 001.
    mu_m3_s2 : float
        Gravitational parameter μ (m³/s²).
    mass_kg : float
        Reference mass (kg), the initial mass.
    """

    length_m: float
    mu_m3_s2: float
    mass_kg: float

    def __post_init__(self) -> None:
        for name in ("length_m", "mu_m3_s2", "mass_kg"):
            require_finite_positive(f"Scaling.{name}", getattr(self, name))

    @property
    def velocity_m_s(self) -> float:
        """v_ref = sqrt(μ/L) (m/s)."""
        return math.sqrt(self.mu_m3_s2 / self.length_m)

    @property
    def time_s(self) -> float:
        """t_ref = L / v_ref (s)."""
        return self.length_m / self.velocity_m_s

    @property
    def acceleration_m_s2(self) -> float:
        """a_ref = μ / L² (m/s²)."""
        return self.mu_m3_s2 / self.length_m**2

    @property
    def force_n(self) -> float:
        """F_ref = m_ref a_ref (N)."""
        return self.mass_kg * self.acceleration_m_s2

    # Scalars or arrays both work: these are plain multiplications.
    def length_nd(self, metres):
        return np.asarray(metres, dtype=np.float64) / self.length_m

    def velocity_nd(self, m_s):
        return np.asarray(m_s, dtype=np.float64) / self.velocity_m_s

    def time_nd(self, seconds):
        return np.asarray(seconds, dtype=np.float64) / self.time_s

    def rate_nd(self, rad_s):
        return np.asarray(rad_s, dtype=np.float64) * self.time_s

    def mass_nd(self, kg):
        return np.asarray(kg, dtype=np.float64) / self.mass_kg

    def force_nd(self, newton):
        return np.asarray(newton, dtype=np.float64) / self.force_n
