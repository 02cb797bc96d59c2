"""Curriculum start states of each env family: states along optimal flights, and their
perturbation (:class:`agents.rl.curriculum.OptimalStartCurriculum`).

A :class:`StartFamily` per env family, registered in :data:`START_FAMILIES` by ``scenario.family``:
``planar`` (:mod:`.planar`, Pontryagin optima), ``pinpoint`` (:mod:`.pinpoint`, the compiled
minimum-fuel extremals) and ``pinpoint_touchdown`` (:mod:`.touchdown`, the certified optima
flown in the env).
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from lunar_env.families import FamilyRegistry

__all__ = ["StartFamily", "START_FAMILIES"]


class StartFamily(ABC):
    """The curriculum starts of an env family."""

    @abstractmethod
    def start_pool(self, scenario, n_trajectories: int, seed: int, n_points: int = 101,
                   progress: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """States (M, n_points, n_state) (normalised) along optimal flights from dispersed
        initial states, and the episode time (s) of each."""

    def start_noise_nd(self, scenario, noise: dict[str, float]) -> tuple[float, float]:
        """Validated start perturbation in normalised units (families that have one override
        this)."""
        raise ValueError(f"start_noise is not available for the {scenario.family} env family")

    def perturb_starts(self, states_nd: np.ndarray, sigma_nd: tuple[float, float],
                       rng: np.random.Generator) -> np.ndarray:
        """Curriculum starts with the errors of :meth:`start_noise_nd` added (a copy)."""
        raise ValueError("start_noise is not available for this env family")


#: the curriculum starts of each env family, by ``scenario.family``
START_FAMILIES: FamilyRegistry[StartFamily] = FamilyRegistry(
    "start-state", entry_point_group="lunar_env.start_families")
START_FAMILIES.register("planar", "agents.rl.starts.planar:PlanarStarts")
START_FAMILIES.register("pinpoint", "agents.rl.starts.pinpoint:PinpointStarts")
START_FAMILIES.register("pinpoint_touchdown", "agents.rl.starts.touchdown:TouchdownStarts")
