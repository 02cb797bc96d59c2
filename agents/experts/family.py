"""The env-family contract: one object answers every question that depends on the env family.

An env family is a kind of landing problem with its own state, optimum and expert: the planar
soft landing (:mod:`agents.experts.planar`) and the 3D pinpoint landing
(:mod:`agents.experts.pinpoint`). Code outside the family modules asks
:func:`agents.experts.registry.family_of` for the family of a scenario and calls its methods; it
never branches on the family itself. A new family (a throttled vehicle, another body) is one
new module with an :class:`EnvFamily` subclass, registered in :mod:`agents.experts.registry`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from agents.common.law import GuidanceLaw

__all__ = ["EnvFamily", "PerCaseOptimum"]


@dataclass
class PerCaseOptimum:
    """The minimum-fuel optimum of each case of an evaluation, from the env's own initial states.

    Attributes
    ----------
    fuel_kg, tf_s : ndarray, shape (n,)
        Optimal propellant and final time per case (NaN where the solve failed).
    solutions : list
        The family's solution objects, one per case (each with ``success``).
    info : dict
        ``solver`` (what computed it), ``converged``, ``fuel_mean_kg``, ``wall_s``.
    """

    fuel_kg: np.ndarray
    tf_s: np.ndarray
    solutions: list
    info: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_solutions(cls, solutions: list, solver: str, wall_s: float) -> PerCaseOptimum:
        """From solution objects with ``success``, ``fuel_kg`` and ``tf_s``."""
        fuel = np.array([s.fuel_kg if s.success else np.nan for s in solutions], dtype=float)
        tf = np.array([s.tf_s if s.success else np.nan for s in solutions], dtype=float)
        ok = np.isfinite(fuel)
        return cls(fuel, tf, list(solutions), {
            "solver": solver, "converged": int(ok.sum()),
            "fuel_mean_kg": float(np.mean(fuel[ok])) if ok.any() else float("nan"),
            "wall_s": float(wall_s)})


class EnvFamily(ABC):
    """What an env family answers (see the module docstring)."""

    #: short name ("planar", "pinpoint")
    name: str = ""
    #: cases the family's closed-loop expert flies in an evaluation by default (None: all)
    default_expert_cases: int | None = None

    @abstractmethod
    def handles(self, scenario) -> bool:
        """True if ``scenario`` belongs to this family."""

    @abstractmethod
    def per_case_optimum(self, scenario, states_nd: np.ndarray, *, progress: bool = True,
                         workers: int = 1, executor=None) -> PerCaseOptimum:
        """The certified minimum-fuel optimum from each normalised initial state (n, n_state)."""

    @abstractmethod
    def open_loop_law(self, optimum: PerCaseOptimum) -> GuidanceLaw:
        """The replay of each case's optimal control history (case id = row of ``optimum``)."""

    @abstractmethod
    def expert_law(self, scenario) -> GuidanceLaw:
        """The closed-loop expert: the optimum re-solved from the navigation solution."""

    @abstractmethod
    def start_pool(self, scenario, n_trajectories: int, seed: int, n_points: int,
                   progress: bool) -> tuple[np.ndarray, np.ndarray]:
        """Curriculum starts: states (M, n_state) (normalised) along optimal flights from
        dispersed initial states, and the episode time (M,) (s) of each."""

    def start_noise_nd(self, scenario, noise: dict[str, float]) -> tuple[float, float]:
        """Validated curriculum start perturbation in normalised units (families that have
        one override this)."""
        raise ValueError(f"start_noise is not available for the {self.name} env family")

    def perturb_starts(self, states_nd: np.ndarray, sigma_nd: tuple[float, float],
                       rng: np.random.Generator) -> np.ndarray:
        """Curriculum starts with the errors of :meth:`start_noise_nd` added (a copy)."""
        raise ValueError(f"start_noise is not available for the {self.name} env family")

    @abstractmethod
    def plot_optimum(self, ax_trajectory, ax_control, solution, scenario) -> None:
        """Draw one case's optimum (dashed) on the trajectory and control axes."""

    @abstractmethod
    def plot_flight(self, ax_trajectory, ax_control, trace: dict[str, np.ndarray], scenario,
                    label: str) -> None:
        """Draw one flown case (``trace``: ``t_s``, ``state_nd``, ``action``)."""

    #: axis labels of the evaluation plots: (trajectory x, trajectory y, control y)
    plot_labels: tuple[str, str, str] = ("", "altitude (km)", "")

    def baseline_laws(self, scenario, optimum: PerCaseOptimum, n_states: int, *,
                      open_loop: bool = True, n_expert_cases: int | None = None
                      ) -> list[tuple[GuidanceLaw, int]]:
        """The optimiser baselines of an evaluation: the open-loop optimum on every case and
        the closed-loop expert on the first ``n_expert_cases`` (None: the family's default;
        0: none)."""
        rows: list[tuple[GuidanceLaw, int]] = []
        if open_loop:
            rows.append((self.open_loop_law(optimum), n_states))
        n_exp = self.default_expert_cases if n_expert_cases is None else n_expert_cases
        n_exp = n_states if n_exp is None else min(int(n_exp), n_states)
        if n_exp > 0:
            rows.append((self.expert_law(scenario), n_exp))
        return rows
