"""The uniform-random guidance law: the 0 reference of the benchmark score
(:mod:`agents.evaluation.score`) and of the Minari datasets' ``ref_min_score``."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from agents.common.law import FlightComputer, GuidanceLaw, Navigation

__all__ = ["RandomLaw", "RANDOM_SEED"]

#: seed of the random reference's action draws (the cases themselves are the evaluation's)
RANDOM_SEED = 12345


class RandomLaw(GuidanceLaw):
    """Uniform-random actions in the env's action space: the score's 0 reference.

    Case ``i`` draws from its own generator seeded ``(seed, case_id)``, so a case's actions do
    not depend on the batch it flies in.
    """

    name = "random"
    privileged: ClassVar[bool] = False

    def __init__(self, seed: int = RANDOM_SEED) -> None:
        self.seed = int(seed)
        self._rngs: list[np.random.Generator] = []

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        """Bind the action bounds and seed one generator per case."""
        self._low = np.asarray(computer.action_space.low, dtype=np.float64)
        self._high = np.asarray(computer.action_space.high, dtype=np.float64)
        self._rngs = [np.random.default_rng([self.seed, int(c)]) for c in case_ids]

    def act(self, nav: Navigation) -> np.ndarray:
        """One uniform draw per lander within the action bounds."""
        if len(self._rngs) != nav.n:
            raise ValueError(f"RandomLaw was reset for {len(self._rngs)} cases, asked for "
                             f"{nav.n}")
        u = np.stack([g.uniform(self._low, self._high) for g in self._rngs])
        return u.astype(np.float32)
