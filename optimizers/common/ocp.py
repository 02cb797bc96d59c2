"""The optimal-control problem contract (rockit's ``Ocp`` is the model).

An :class:`OCP` states one continuous problem once: dynamics from :mod:`lunar_env.dynamics`,
the fixed initial state, the terminal conditions, bounds, path constraints, the (Mayer)
objective and the scaling, all in the normalised units of the kernels. Transcriptions
(:mod:`optimizers.transcription`) and indirect solvers (:mod:`optimizers.indirect`) consume it;
none rebuilds a problem from a scenario. Its numeric half — SI terminal errors and the verdict
on a final state — is what every solver's :class:`~optimizers.common.result.OptimResult`
reports, so success is decided by the problem, not by the solver.

The symbolic members evaluate on CasADi symbols (``casadi.SX``/``MX``):

===================================  ==================================================
member                               meaning
===================================  ==================================================
``n_state``, ``n_control``           sizes of x and of the steered control u
``rhs(x, u)``                        dx/dt from the shared right-hand side
``initial_state``                    fixed x(t0 = 0), ndarray (n_state,)
``terminal_residual(xf)``            vector that is 0 at an admissible final state
``path_constraints(x, u)``           ``(expr, lower, upper)`` or None, imposed at nodes
``control_lower``/``control_upper``  bounds on u, ndarray (n_control,)
``state_bounds()``                   (lower, upper), each (n_state,)
``tf_bounds_nd``                     (low, high) of the free final time
``objective(xf, tf)``                Mayer cost to minimise
===================================  ==================================================
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from lunar_env.scaling import Scaling

__all__ = ["OCP"]


class OCP(ABC):
    """Base class of the optimal-control problems (normalised units; SI at the edges).

    Subclasses set ``n_state``, ``n_control`` and implement the abstract members; they may
    override :meth:`path_constraints`, :meth:`state_bounds` and :meth:`success_from`.
    """

    n_state: int
    n_control: int

    # ---- symbolic ---------------------------------------------------------------------------
    @abstractmethod
    def rhs(self, state, control):
        """Right-hand side on CasADi symbols: (n_state,), (n_control,) -> (n_state,)."""

    @property
    @abstractmethod
    def initial_state(self) -> np.ndarray:
        """Fixed initial state, normalised, shape (n_state,)."""

    @abstractmethod
    def terminal_residual(self, final_state):
        """CasADi vector that vanishes at an admissible final state (normalised)."""

    def path_constraints(self, state, control):
        """``(expr, lower, upper)`` imposed at the nodes of a transcription, or None."""
        return None

    @property
    def control_lower(self) -> np.ndarray:
        return np.full(self.n_control, -np.inf)

    @property
    def control_upper(self) -> np.ndarray:
        return np.full(self.n_control, np.inf)

    def state_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) on every node state; default unbounded."""
        return np.full(self.n_state, -np.inf), np.full(self.n_state, np.inf)

    #: Bounds (low, high) of the free final time, normalised.
    tf_bounds_nd: tuple[float, float]

    def objective(self, final_state, tf):
        """Mayer objective (default: tf, minimum time)."""
        return tf

    # ---- numeric ----------------------------------------------------------------------------
    #: SI <-> normalised conversion of this problem (:class:`lunar_env.scaling.Scaling`).
    scaling: Scaling

    @abstractmethod
    def fuel_kg(self, tf_nd: float) -> float:
        """Propellant used by a solution of final time ``tf_nd`` (constant-thrust problems)."""

    @abstractmethod
    def terminal_errors(self, final_state_nd: np.ndarray) -> dict[str, float]:
        """SI terminal errors of a normalised final state (n_state,), under named keys."""

    def success_from(self, errors: dict[str, float], path: dict[str, float] | None = None
                     ) -> tuple[bool, str]:
        """The problem's verdict on terminal errors (and path quantities such as the minimum
        altitude). Default: every error below its tolerance in :attr:`tolerances`."""
        bad = [f"{k} = {errors[k]:.3g} (tolerance {tol:g})"
               for k, tol in self.tolerances.items() if not abs(errors.get(k, np.inf)) <= tol]
        if bad:
            return False, "terminal conditions NOT met: " + ", ".join(bad)
        return True, "terminal conditions met"

    #: SI tolerance per terminal-error key; a solution succeeds when every error is below it.
    tolerances: dict[str, float] = {}

    #: The integrator model (:data:`lunar_env.integrators.PLANAR` or ``MOON3D``) and its
    #: parameters, for replays by the compiled RK4 and the DOP853 reference.
    model: object
    params: object

    def path_quantities(self, states_nd: np.ndarray) -> dict[str, float]:
        """Path quantities of a trajectory (n, n_state) that :meth:`success_from` judges
        (e.g. ``min_altitude_m``, ``final_mass_kg``); default none."""
        return {}
