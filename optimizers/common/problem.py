"""The Problem interface every optimiser consumes, modelled on pygmo's user-defined problems.

A problem has box bounds, a scalar objective to **minimise** (pygmo's convention), equality
constraints ``ceq(x) = 0`` and inequality constraints ``cin(x) <= 0``. ``fitness(x)`` returns
``[obj, *ceq, *cin]`` exactly as pygmo expects; ``batch_fitness(X)`` maps ``(n_pop, dim)`` to
``(n_pop, n_f)`` and is the fast path: implementations integrate the whole population in one
call of the shared batched dynamics. ``decode(x)`` turns a decision vector into its physical
meaning (control law, trajectory).

Algorithms that use a penalty (the GAs of the papers) get what they need from the same
numbers: the objective and the constraint violations, grouped and scaled as the problem says
(:meth:`Problem.penalty_groups`, :attr:`Problem.objective_scale`).

**The problem, not the algorithm, decides feasibility and success.** :meth:`Problem.assess`
returns an :class:`Assessment`: the objective, SI terminal errors under named keys, the
constraint violation, whether the point is feasible (every constraint within ``c_tol``) and
whether it is a *success* by the problem's own terminal and path conditions (by default the same
as feasible; a landing problem states its own tolerances). Every solver builds its
:class:`~optimizers.common.result.OptimResult` from it.
"""

from __future__ import annotations

import hashlib
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Problem", "PygmoProblem", "Assessment", "PenaltyGroup", "central_difference_jacobian"]


@dataclass(frozen=True)
class PenaltyGroup:
    """Constraints that a penalty function treats together (one term of the penalty).

    The term is ``factor · ‖c[eq]‖₂ / scale`` for equalities plus ``factor · Σ max(0, c[ineq])
    / scale`` for inequalities. Indices count within the equalities and within the
    inequalities respectively (0-based).

    Attributes
    ----------
    name : str
    eq : tuple of int
    ineq : tuple of int
    scale : float
        Divisor that makes the term dimensionless (e.g. a reference velocity).
    factor : float
        Relative weight of the term (e.g. [000] eq. (11): σ1 = 5σ2 for the velocity term).
    """

    name: str
    eq: tuple[int, ...] = ()
    ineq: tuple[int, ...] = ()
    scale: float = 1.0
    factor: float = 1.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"PenaltyGroup {self.name!r}: scale = {self.scale!r} must be > 0")
        if not (math.isfinite(self.factor) and self.factor >= 0):
            raise ValueError(f"PenaltyGroup {self.name!r}: factor = {self.factor!r} must be >= 0")


@dataclass
class Assessment:
    """The problem's verdict on one decision vector (:meth:`Problem.assess`).

    Attributes
    ----------
    objective : float
        ``fitness(x)[0]`` (minimised).
    feasible : bool
        Finite fitness, every equality within ``c_tol`` of 0 and every inequality <= ``c_tol``.
    success : bool
        The problem's own terminal and path conditions are met (for a landing: touchdown
        within its speed and radius tolerances). Never decided by an algorithm.
    terminal_errors : dict of str -> float
        SI errors under named keys (``speed_m_s``, ``radius_m``, ...); generic problems report
        the constraint values as ``eq_<i>`` and ``ineq_<j>``.
    constraint_violation : float
        Largest violation beyond ``c_tol`` (0 when feasible; inf for a non-finite fitness).
    fuel_kg, tf_s : float
        Propellant and final time when the problem knows them, else NaN.
    message : str
        Why it is (not) a success, in words.
    f : ndarray, shape (n_f,)
        The fitness row.
    """

    objective: float
    feasible: bool
    success: bool
    terminal_errors: dict[str, float]
    constraint_violation: float
    fuel_kg: float = math.nan
    tf_s: float = math.nan
    message: str = ""
    f: np.ndarray = field(default_factory=lambda: np.zeros(0))


class Problem(ABC):
    """Base class of optimisation problems (pygmo UDP conventions).

    Subclasses implement :meth:`get_bounds` and :meth:`_batch_fitness` (and optionally
    :meth:`decode`, :meth:`get_nec`, :meth:`get_nic`, :meth:`gradient`, :meth:`penalty_groups`
    and the verdict hooks :meth:`terminal_errors`, :meth:`success_from`). ``fitness``, the
    evaluation counter, :meth:`assess` and :meth:`fingerprint` come for free.

    Attributes
    ----------
    c_tol : float
        Constraint tolerance of :meth:`assess` (pygmo's ``c_tol``), in the constraints' units.
    objective_scale : float
        Divisor that makes the objective dimensionless in a penalised fitness.
    """

    c_tol: float = 1e-6
    objective_scale: float = 1.0

    def __init__(self) -> None:
        self.n_fevals = 0

    # ---- pygmo UDP surface ----------------------------------------------------------------
    @abstractmethod
    def get_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds, each shape (dim,)."""

    def get_nec(self) -> int:
        """Number of equality constraints (``ceq(x) = 0``)."""
        return 0

    def get_nic(self) -> int:
        """Number of inequality constraints (``cin(x) <= 0``)."""
        return 0

    def get_name(self) -> str:
        return type(self).__name__

    @property
    def dim(self) -> int:
        return len(self.get_bounds()[0])

    @property
    def n_f(self) -> int:
        return 1 + self.get_nec() + self.get_nic()

    @abstractmethod
    def _batch_fitness(self, X: np.ndarray) -> np.ndarray:
        """Implementations: (n_pop, dim) -> (n_pop, n_f), ``[obj, *ceq, *cin]`` per row."""

    def batch_fitness(self, X: np.ndarray) -> np.ndarray:
        """Fitness of a population.

        Parameters
        ----------
        X : ndarray, shape (n_pop, dim)

        Returns
        -------
        ndarray, shape (n_pop, n_f)

        Raises
        ------
        ValueError
            If X has the wrong width or non-finite entries.
        """
        X = np.atleast_2d(np.asarray(X, dtype=np.float64))
        if X.shape[1] != self.dim:
            raise ValueError(f"decision vectors have {X.shape[1]} entries; {self.get_name()} "
                             f"needs {self.dim}")
        if not np.all(np.isfinite(X)):
            raise ValueError("decision vectors must be finite")
        self.n_fevals += X.shape[0]
        return self._batch_fitness(X)

    def fitness(self, x: np.ndarray) -> np.ndarray:
        """``[obj, *ceq, *cin]`` of one decision vector, shape (n_f,)."""
        return self.batch_fitness(np.asarray(x, dtype=np.float64)[None, :])[0]

    def decode(self, x: np.ndarray):
        """Physical meaning of ``x`` (control law and trajectory); problem specific."""
        raise NotImplementedError(f"{self.get_name()} does not implement decode()")

    # ---- the problem's verdict ------------------------------------------------------------
    def checked_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`get_bounds` as float arrays, validated.

        Raises
        ------
        ValueError
            Non-finite bounds, lower > upper, or shapes that differ.
        """
        lb, ub = (np.asarray(b, dtype=np.float64) for b in self.get_bounds())
        if lb.shape != ub.shape or lb.ndim != 1 or lb.size == 0:
            raise ValueError(f"{self.get_name()}: bounds have shapes {lb.shape} and {ub.shape}; "
                             "expected two equal 1-D shapes")
        if not (np.all(np.isfinite(lb)) and np.all(np.isfinite(ub))):
            raise ValueError(f"{self.get_name()}: bounds must be finite, got {lb!r}, {ub!r}")
        bad = np.flatnonzero(lb > ub)
        if bad.size:
            i = int(bad[0])
            raise ValueError(f"{self.get_name()}: bounds of variable {i} are reversed "
                             f"(lower {lb[i]!r} > upper {ub[i]!r}); lower must be <= upper")
        return lb, ub

    def penalty_groups(self) -> list[PenaltyGroup]:
        """How a penalty function groups and scales the constraints.

        Default: all equalities as one Euclidean term, all inequalities as one summed term,
        unscaled. Problems whose constraints have physical units override it.
        """
        groups = []
        if self.get_nec():
            groups.append(PenaltyGroup("equality", eq=tuple(range(self.get_nec()))))
        if self.get_nic():
            groups.append(PenaltyGroup("inequality", ineq=tuple(range(self.get_nic()))))
        return groups

    def terminal_errors(self, x: np.ndarray, f: np.ndarray) -> dict[str, float]:
        """SI terminal errors of ``x`` with fitness row ``f`` (hook of :meth:`assess`).

        Default: the constraint values, ``eq_<i>`` and ``ineq_<j>``.
        """
        nec = self.get_nec()
        out = {f"eq_{i}": float(v) for i, v in enumerate(f[1:1 + nec])}
        out.update({f"ineq_{j}": float(v) for j, v in enumerate(f[1 + nec:])})
        return out

    def success_from(self, x: np.ndarray, f: np.ndarray, errors: dict[str, float],
                     feasible: bool) -> tuple[bool, str]:
        """The problem's success criterion (hook of :meth:`assess`); default: feasible."""
        return feasible, ("all constraints within c_tol" if feasible
                          else "constraints violated beyond c_tol")

    def fuel_tf(self, x: np.ndarray, f: np.ndarray) -> tuple[float, float]:
        """``(fuel_kg, tf_s)`` of ``x`` when the problem knows them (hook), else NaNs."""
        return math.nan, math.nan

    def assess(self, x: np.ndarray, f: np.ndarray | None = None) -> Assessment:
        """The problem's verdict on ``x`` (see :class:`Assessment`).

        Parameters
        ----------
        x : ndarray, shape (dim,)
        f : ndarray, shape (n_f,), optional
            Its fitness row, if already computed (saves an evaluation).
        """
        x = np.asarray(x, dtype=np.float64)
        if x.shape != (self.dim,):
            raise ValueError(f"x has shape {x.shape}; {self.get_name()} needs ({self.dim},)")
        f = self.fitness(x) if f is None else np.asarray(f, dtype=np.float64)
        nec = self.get_nec()
        if not np.all(np.isfinite(f)):
            errors = {k: (v if math.isfinite(v) else math.nan)
                      for k, v in self.terminal_errors(x, np.where(np.isfinite(f), f, np.nan))
                      .items()}
            return Assessment(float(f[0]), False, False, errors, math.inf,
                              message="the fitness is not finite", f=f)
        viol_eq = np.maximum(np.abs(f[1:1 + nec]) - self.c_tol, 0.0)
        viol_in = np.maximum(f[1 + nec:] - self.c_tol, 0.0)
        violation = float(max(viol_eq.max(initial=0.0), viol_in.max(initial=0.0)))
        feasible = violation == 0.0
        errors = self.terminal_errors(x, f)
        success, why = self.success_from(x, f, errors, feasible)
        fuel, tf = self.fuel_tf(x, f)
        return Assessment(float(f[0]), bool(feasible), bool(success), errors, violation,
                          float(fuel), float(tf), why, f)

    def control_law(self, x: np.ndarray):
        """The open-loop control law that ``x`` encodes (a picklable ``u(t_s)`` callable, e.g.
        :class:`~optimizers.common.result.ControlLaw`), or None when ``x`` is not a control
        (hook used by solvers to fill ``OptimResult.control``)."""
        return None

    def fingerprint(self) -> str:
        """A short hash identifying this problem (name, bounds, constraint counts); checkpoints
        record it and refuse to resume on another problem. Problems with hidden data (an initial
        state, a scenario) extend :meth:`_fingerprint_items`."""
        h = hashlib.sha256()
        for item in self._fingerprint_items():
            h.update(repr(item).encode())
        return h.hexdigest()[:16]

    def _fingerprint_items(self) -> list:
        lb, ub = self.get_bounds()
        return [type(self).__qualname__, self.get_name(), np.asarray(lb).tolist(),
                np.asarray(ub).tolist(), self.get_nec(), self.get_nic()]

    def clip(self, X: np.ndarray) -> np.ndarray:
        lb, ub = self.get_bounds()
        return np.clip(X, lb, ub)

    def __repr__(self) -> str:
        return (f"{self.get_name()}(dim={self.dim}, n_eq={self.get_nec()}, "
                f"n_ineq={self.get_nic()}, n_fevals={self.n_fevals})")

    def to_pygmo(self):
        """A ``pygmo.problem`` wrapping this problem (pygmo's algorithms then solve it)."""
        import pygmo as pg

        return pg.problem(PygmoProblem(self))



def central_difference_jacobian(problem: Problem, x: np.ndarray,
                                rel_step: float = 1e-6) -> np.ndarray:
    """Central finite-difference Jacobian of ``problem.fitness`` at ``x``, all 2·dim perturbed
    points in one :meth:`Problem.batch_fitness` call (step ``rel_step · max(1, |x_i|)``).

    Returns
    -------
    ndarray, shape (n_f, dim)
    """
    x = np.asarray(x, dtype=np.float64)
    h = rel_step * np.maximum(1.0, np.abs(x))
    E = np.diag(h)
    F = problem.batch_fitness(np.concatenate([x + E, x - E]))
    d = x.size
    return ((F[:d] - F[d:]) / (2 * h[:, None])).T


class PygmoProblem:
    """pygmo UDP adapter; the only place batches are flattened. Picklable."""

    def __init__(self, problem: Problem) -> None:
        self.problem = problem

    def fitness(self, x):
        return self.problem.fitness(np.asarray(x))

    def batch_fitness(self, dvs):
        X = np.asarray(dvs, dtype=np.float64).reshape(-1, self.problem.dim)
        return self.problem.batch_fitness(X).ravel()

    def has_batch_fitness(self) -> bool:
        return True

    def gradient(self, x):
        """Dense Jacobian of the fitness, flattened row-major (pygmo's dense sparsity), when
        the wrapped problem has ``gradient(x) -> (n_f, dim)``."""
        return np.asarray(self.problem.gradient(np.asarray(x, dtype=np.float64))).ravel()

    def has_gradient(self) -> bool:
        return callable(getattr(self.problem, "gradient", None))

    def get_bounds(self):
        lb, ub = self.problem.get_bounds()
        return (list(lb), list(ub))

    def get_nec(self) -> int:
        return self.problem.get_nec()

    def get_nic(self) -> int:
        return self.problem.get_nic()

    def get_name(self) -> str:
        return self.problem.get_name()
