"""What one law's flight over an evaluation's cases gives: :class:`PolicyResult`."""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from agents.common.rollout import CaseOutcomes, Rollout

__all__ = ["PolicyResult"]


@dataclass
class PolicyResult(CaseOutcomes):
    """Per-case outcome of one law (:class:`~agents.common.rollout.CaseOutcomes`), its table
    name, the case ids and the traced cases' histories (``t_s``, ``state_nd``, ``action``)."""

    name: str = ""
    case_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    traces: dict[int, dict[str, np.ndarray]] = field(default_factory=dict)

    @classmethod
    def from_rollout(cls, name: str, case_ids: np.ndarray, rollout: Rollout,
                     traces: dict[int, dict[str, np.ndarray]]) -> PolicyResult:
        """The result of a law whose flight :func:`~agents.common.rollout.fly` returned."""
        outcomes = {f.name: getattr(rollout, f.name) for f in fields(CaseOutcomes)}
        return cls(name=name, case_ids=np.asarray(case_ids), traces=traces, **outcomes)
