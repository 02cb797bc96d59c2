"""What one law's flight over an evaluation's cases gives: :class:`PolicyResult`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["PolicyResult"]


@dataclass
class PolicyResult:
    """Per-case outcome of one policy (arrays of length n_cases)."""

    name: str
    case_ids: np.ndarray
    is_success: np.ndarray
    touchdown_speed_m_s: np.ndarray
    miss_distance_m: np.ndarray
    fuel_used_kg: np.ndarray
    episode_time_s: np.ndarray
    n_decisions: int
    policy_wall_s: float
    traces: dict[int, dict[str, np.ndarray]] = field(default_factory=dict)

    @property
    def us_per_decision(self) -> float:
        return 1e6 * self.policy_wall_s / max(self.n_decisions, 1)
