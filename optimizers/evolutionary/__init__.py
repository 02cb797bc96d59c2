"""Evolutionary algorithms from the papers on one base class (:mod:`.base`), sharing their GA
operators (:mod:`.operators`) and penalties (:mod:`.penalties`).

- :class:`~.asaga.ASAGA`: adaptive simulated-annealing GA, [000] Zhu & Xu 2007 (the template a
  new evolutionary algorithm copies).
"""

from .asaga import ASAGA
from .base import EvolutionaryAlgorithm

__all__ = ["ASAGA", "EvolutionaryAlgorithm"]
