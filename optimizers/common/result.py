"""The result object every solver returns (scipy ``OdeResult`` / ``OptimizeResult`` style).

Non-convergence is a value (``success=False`` and a ``message``), not an exception.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["OptimResult", "Trajectory"]


@dataclass
class Trajectory:
    """A decoded trajectory in SI units.

    Attributes
    ----------
    t_s : ndarray, shape (n,)
    states : dict of str -> ndarray, shape (n,)
        Named state histories with units in the names (``radius_m``, ``radial_velocity_m_s``,
        ``mass_kg``, ...).
    controls : dict of str -> ndarray, shape (n,)
        Named control histories (``phi_rad``, ``alpha_rad``, ``beta_rad``, ``throttle``).
    """

    t_s: np.ndarray
    states: dict[str, np.ndarray]
    controls: dict[str, np.ndarray]

    def sample(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """``(t_s, values)`` of a named state or control (rockit's ``sol.sample``)."""
        if name in self.states:
            return self.t_s, self.states[name]
        if name in self.controls:
            return self.t_s, self.controls[name]
        known = sorted(self.states) + sorted(self.controls)
        raise KeyError(f"{name!r} is not recorded; have {known}")


@dataclass
class OptimResult:
    """Outcome of one optimiser run.

    Attributes
    ----------
    x : ndarray, shape (dim,)
        Best decision vector.
    fuel_kg : float
        Propellant used.
    tf_s : float
        Final time.
    terminal_errors : dict of str -> float
        SI terminal errors, e.g. ``{"speed_m_s": .., "radius_m": ..}``.
    history : ndarray
        Best objective (or fitness) per generation / iteration.
    n_fevals : int
    wall_s : float
    success : bool
    message : str
    trajectory : Trajectory or None
    extra : dict
        Solver-specific details.
    """

    x: np.ndarray
    fuel_kg: float
    tf_s: float
    terminal_errors: dict[str, float]
    history: np.ndarray
    n_fevals: int
    wall_s: float
    success: bool
    message: str
    trajectory: Trajectory | None = None
    extra: dict = field(default_factory=dict)
