"""Penalty weight schedules of the evolutionary algorithms.

The penalised fitness itself is the problem's definition
(:func:`optimizers.common.penalties.penalised_fitness`); an algorithm supplies only the weight
of each generation.
"""

from __future__ import annotations

__all__ = ["paper_penalty_weight"]


def paper_penalty_weight(generation: int, n_generations: int) -> float:
    """σ2 of [000] eq. (11): ``max(1, 10^(2T/Tmax − 1))``, from 1 (T ≤ Tmax/2) to 10."""
    return max(1.0, 10.0 ** (2.0 * generation / n_generations - 1.0))
