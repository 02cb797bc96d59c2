"""The per-case optimum of each env family: the minimum-fuel landing from a drawn state.

Evaluations score every law against the certified optimum of each case they fly, and Monte
Carlo campaigns against each case's *omniscient* optimum (its true plant from its true start).
An :class:`OptimumFamily` answers both for one env family, and gives the re-planning problem
convex guidance solves:

- ``planar`` (:mod:`.planar`): Pontryagin indirect shooting;
- ``pinpoint`` (:mod:`.pinpoint`): [001]'s serial GPM + direct shooting (cached on disk), and
  for the omniscient reference the compiled Pontryagin extremal with the direct method as
  fallback;
- ``pinpoint_touchdown`` (:mod:`.touchdown`): the throttled landing to touchdown, certified by
  two methods that agree (phased Legendre–Gauss collocation and Pontryagin multi-arc shooting),
  cached on disk.

Families are registered in :data:`OPTIMUM_FAMILIES` (a :class:`lunar_env.families.
FamilyRegistry`; entry-point group ``lunar_env.optimum_families``)::

    from optimizers.optimum import optimum_family
    opt = optimum_family(scenario).per_case_optimum(scenario, states_nd)
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lunar_env.families import FamilyRegistry

__all__ = ["OptimumFamily", "PerCaseOptimum", "PlantOptimumFuel", "plant_scenario",
           "OPTIMUM_FAMILIES", "optimum_family"]


def plant_scenario(scenario, thrust_scale: float, isp_scale: float):
    """``scenario`` with its engine's thrust and Isp multiplied by the given scales (a true
    plant of the uncertainty model); the same scenario for scales of 1. The normalisation
    (length, μ, mass units) does not depend on either, so normalised states carry over."""
    if thrust_scale == 1.0 and isp_scale == 1.0:
        return scenario
    v = scenario.vehicle
    return dataclasses.replace(
        scenario, name=f"{scenario.name}[T×{thrust_scale:.6g},Isp×{isp_scale:.6g}]",
        vehicle=dataclasses.replace(v, thrust_n=v.thrust_n * float(thrust_scale),
                                    isp_s=v.isp_s * float(isp_scale)))


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


@dataclass(frozen=True)
class PlantOptimumFuel:
    """The omniscient reference of a campaign's cases (:meth:`OptimumFamily.plant_optimum_fuel`).

    Attributes
    ----------
    fuel_kg : ndarray, shape (n,)
        Minimum propellant (kg) of each case's true plant from its true start; NaN where no
        method found an optimum.
    solver : tuple of str, length n
        The method that found each case's optimum (``""`` where none did).
    """

    fuel_kg: np.ndarray
    solver: tuple[str, ...]

    def __post_init__(self) -> None:
        if len(self.solver) != len(self.fuel_kg):
            raise ValueError(f"{len(self.solver)} solver names for {len(self.fuel_kg)} cases")


class OptimumFamily(ABC):
    """The optimum of an env family (see the module docstring)."""

    @abstractmethod
    def per_case_optimum(self, scenario, states_nd: np.ndarray, *, progress: bool = True,
                         workers: int = 1, executor=None) -> PerCaseOptimum:
        """The certified minimum-fuel optimum from each normalised initial state (n, n_state)."""

    def plant_optimum_fuel(self, scenario, states_nd: np.ndarray, thrust_scale: np.ndarray,
                           isp_scale: np.ndarray, *, progress: bool = False
                           ) -> PlantOptimumFuel:
        """Minimum propellant (kg) of each case (n,) from its true normalised start (n, n_state)
        with its true engine (thrust and Isp scales (n,)): the omniscient reference of a
        campaign, NaN where no optimum was found, with the method that found each. This default
        groups the cases by plant and calls :meth:`per_case_optimum`; families with a faster
        certified solver override it."""
        fuel = np.full(len(states_nd), np.nan)
        solver = [""] * len(states_nd)
        plants = np.stack([np.asarray(thrust_scale, float), np.asarray(isp_scale, float)], 1)
        for plant in np.unique(plants, axis=0):
            rows = np.flatnonzero(np.all(plants == plant, axis=1))
            opt = self.per_case_optimum(plant_scenario(scenario, *plant), states_nd[rows],
                                        progress=progress)
            fuel[rows] = opt.fuel_kg
            for r, f in zip(rows, opt.fuel_kg, strict=True):
                solver[r] = opt.info["solver"] if np.isfinite(f) else ""
        return PlantOptimumFuel(fuel, tuple(solver))

    @abstractmethod
    def replan_ocp(self, scenario):
        """The optimal-control problem (:class:`optimizers.common.ocp.OCP`) a re-planning law
        solves from a mid-flight state of the scenario."""


#: the optimum families, by ``scenario.family``
OPTIMUM_FAMILIES: FamilyRegistry[OptimumFamily] = FamilyRegistry(
    "optimum", entry_point_group="lunar_env.optimum_families")
OPTIMUM_FAMILIES.register("planar", "optimizers.optimum.planar:PlanarOptimum")
OPTIMUM_FAMILIES.register("pinpoint", "optimizers.optimum.pinpoint:PinpointOptimumFamily")
OPTIMUM_FAMILIES.register("pinpoint_touchdown",
                          "optimizers.optimum.touchdown:TouchdownOptimumFamily")


def optimum_family(obj) -> OptimumFamily:
    """The :class:`OptimumFamily` of a scenario, env or flight computer."""
    return OPTIMUM_FAMILIES.of(obj)
