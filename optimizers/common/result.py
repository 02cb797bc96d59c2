"""The result object every solver returns (scipy ``OdeResult`` / ``OptimizeResult`` style).

Non-convergence is a value (``success=False`` and a ``message``), not an exception.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["OptimResult", "Trajectory", "ControlLaw"]


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


@dataclass(frozen=True)
class ControlLaw:
    """An open-loop control law on SI time: a :class:`~lunar_env.integrators.PiecewisePolynomial`
    in normalised time (batch 1) and the time unit. Picklable (process pools return results).

    Calling it with ``t_s`` (float) returns the model's control vector (n_control,), throttle
    included (e.g. (φ, throttle) for the planar model).
    """

    law: object
    time_s: float

    def __call__(self, t_s: float) -> np.ndarray:
        t = np.array([[float(t_s) / self.time_s]])
        return np.asarray(self.law(t))[0, 0]


@dataclass
class OptimResult:
    """Outcome of one solver run; every solver in :mod:`optimizers` returns one.

    Every field means the same for every solver:

    Attributes
    ----------
    x : ndarray, shape (dim,)
        Best decision vector (solver-specific layout; :meth:`Problem.decode` reads it).
    fuel_kg : float
        Propellant used (NaN when the problem has no fuel).
    tf_s : float
        Final time (NaN when the problem has none).
    terminal_errors : dict of str -> float
        SI terminal errors under the problem's named keys (``speed_m_s``, ``radius_m``, ...).
    history : ndarray, shape (n_iter,) or (n_iter + 1,)
        Best objective (the problem's, minimised) per generation or solver iteration.
    n_fevals : int
        Objective evaluations (fitness rows for black-box solvers; objective calls of the NLP
        solver; integrations of the state–costate system for shooting).
    wall_s : float
    success : bool
        Decided by the problem (its terminal and path conditions), never by the algorithm.
    message : str
    trajectory : Trajectory or None
    extra : dict
        Solver-specific details (documented by each solver).
    n_iter : int
        Generations (evolutionary) or solver iterations (Newton, IPOPT).
    fun : float
        Objective value at ``x`` (the problem's, minimised).
    feasible : bool or None
        Every constraint within the problem's tolerance (None when not assessed).
    constraint_violation : float
        Largest violation beyond the tolerance (0 when feasible).
    algorithm, problem : str
        Names of the solver and of the problem.
    control : callable or None
        The control law ``u(t_s) -> ndarray (n_control,)`` of the answer on SI time since the
        start, throttle included (picklable, e.g. :class:`ControlLaw`); what
        :func:`optimizers.certification.certify` replays. Read it with :meth:`control_at`.
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
    n_iter: int = 0
    fun: float = math.nan
    feasible: bool | None = None
    constraint_violation: float = math.nan
    algorithm: str = ""
    problem: str = ""
    control: object = field(default=None, repr=False)

    def control_at(self, t_s: float) -> np.ndarray:
        """The answer's control vector (n_control,) at ``t_s`` seconds after the start.

        Raises
        ------
        ValueError
            The solver recorded no control law for this result.
        """
        if self.control is None:
            raise ValueError(f"this {type(self).__name__} ({self.algorithm or 'unknown solver'}) "
                             "carries no control law")
        return np.asarray(self.control(t_s), dtype=np.float64)

    @classmethod
    def from_assessment(cls, assessment, x: np.ndarray, *, history, n_fevals: int, n_iter: int,
                        wall_s: float, message: str = "", algorithm: str = "",
                        problem: str = "", trajectory: Trajectory | None = None,
                        extra: dict | None = None, control=None) -> OptimResult:
        """Build a result whose verdict is the problem's :class:`~optimizers.common.problem.
        Assessment` (success, terminal errors, fuel and tf come from it)."""
        verdict = assessment.message
        msg = f"{message}; {verdict}" if message and verdict else (message or verdict)
        return cls(x=np.asarray(x, dtype=np.float64).copy(), fuel_kg=float(assessment.fuel_kg),
                   tf_s=float(assessment.tf_s), terminal_errors=dict(assessment.terminal_errors),
                   history=np.asarray(history, dtype=np.float64), n_fevals=int(n_fevals),
                   wall_s=float(wall_s), success=bool(assessment.success), message=msg,
                   trajectory=trajectory, extra=dict(extra or {}), n_iter=int(n_iter),
                   fun=float(assessment.objective), feasible=bool(assessment.feasible),
                   constraint_violation=float(assessment.constraint_violation),
                   algorithm=algorithm, problem=problem, control=control)
