"""The uniform-random guidance law: the 0 reference of the benchmark score
(:mod:`guidance.evaluation.score`) and of the Minari datasets' ``ref_min_score``."""

from __future__ import annotations

import numpy as np

from guidance.law import FlightComputer, GuidanceLaw, Navigation

__all__ = ["RandomLaw", "RANDOM_SEED", "random_from_spec"]

#: seed of the random reference's action draws (the cases themselves are the evaluation's)
RANDOM_SEED = 12345


class RandomLaw(GuidanceLaw):
    """Uniform-random actions in the env's action space: the score's 0 reference.

    Case ``i`` draws from its own generator seeded ``(seed, case_id)``, so a case's actions do
    not depend on the batch it flies in.
    """

    name = "random"

    def __init__(self, seed: int = RANDOM_SEED) -> None:
        self.seed = int(seed)
        self._rngs: list[np.random.Generator] = []

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        """Bind the action bounds and seed one generator per case."""
        super().reset(computer, case_ids)
        self._low = np.asarray(computer.action_space.low, dtype=np.float64)
        self._high = np.asarray(computer.action_space.high, dtype=np.float64)
        self._ids = [int(c) for c in case_ids]
        self._rngs = [np.random.default_rng([self.seed, c]) for c in self._ids]

    def act(self, nav: Navigation) -> np.ndarray:
        """One uniform draw per lander within the action bounds (a row's draws restart with
        its episode)."""
        if len(self._rngs) != nav.n:
            raise ValueError(f"RandomLaw was reset for {len(self._rngs)} cases, asked for "
                             f"{nav.n}")
        for i in np.flatnonzero(nav.episode_start):
            self._rngs[i] = np.random.default_rng([self.seed, self._ids[i]])
        u = np.stack([g.uniform(self._low, self._high) for g in self._rngs])
        return u.astype(np.float32)


def random_from_spec(spec, context) -> RandomLaw:
    """``random[:seed=N]``: :class:`RandomLaw` (seed :data:`RANDOM_SEED` by default)."""
    from guidance.registry import require_no_argument

    spec.require_known_options(("seed",))
    require_no_argument(spec)
    law = RandomLaw(seed=spec.option("seed", int, RANDOM_SEED))
    law.name = spec.text or "random"
    return law
