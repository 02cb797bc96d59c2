"""The Problem interface every optimiser consumes, modelled on pygmo's user-defined problems.

A problem has box bounds, a scalar objective to **minimise** (pygmo's convention), equality
constraints ``ceq(x) = 0`` and inequality constraints ``cin(x) <= 0``. ``fitness(x)`` returns
``[obj, *ceq, *cin]`` exactly as pygmo expects; ``batch_fitness(X)`` maps ``(n_pop, dim)`` to
``(n_pop, n_f)`` and is the fast path: implementations integrate the whole population in one
call of the shared batched dynamics. ``decode(x)`` turns a decision vector into its physical
meaning (control law, trajectory).

Algorithms that use a penalty (the GAs of the papers) get what they need from the same
numbers: the objective and the constraint violations.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

__all__ = ["Problem", "PygmoProblem"]


class Problem(ABC):
    """Base class of optimisation problems (pygmo UDP conventions).

    Subclasses implement :meth:`get_bounds` and :meth:`batch_fitness` (and optionally
    :meth:`decode`, :meth:`get_nec`, :meth:`get_nic`, :meth:`gradient`). ``fitness`` and the
    evaluation counter come for free.
    """

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
