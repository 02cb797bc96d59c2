"""Evolutionary algorithms from the papers on one base class (:mod:`.base`), sharing their GA
operators (:mod:`.operators`) and penalties (:mod:`.penalties`).

- :class:`~.asaga.ASAGA`: adaptive simulated-annealing GA, [000] Zhu & Xu 2007 (the template a
  new evolutionary algorithm copies).
- :class:`~.ea.EA`: (λ+μ) EA with niching, [004] Wang et al. 2001 (two-impulse transfers).
"""

from .asaga import ASAGA
from .base import EvolutionaryAlgorithm
from .ea import EA

__all__ = ["ASAGA", "EA", "EvolutionaryAlgorithm"]
