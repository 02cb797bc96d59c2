"""Evolutionary algorithms from the papers on one base class (:mod:`.base`), sharing their GA
operators (:mod:`.operators`), penalty weight schedules (:mod:`.penalties`) and the
problems' penalised fitness (:mod:`optimizers.common.penalties`).

- :class:`~.asaga.ASAGA`: adaptive simulated-annealing GA, [000] Zhu & Xu 2007 (the template a
  new evolutionary algorithm copies).
- :class:`~.ea.EA`: (λ+μ) EA with niching, [004] Wang et al. 2001 (two-impulse transfers).
- :class:`~.gaia.GAIA` / :class:`~.gaia.AIA`: (guiding) artificial immune algorithm, and
  :class:`~.aga.AGA`, the adaptive GA it is compared with, [002] Peng et al.
- :class:`~.fga.FGA`: float-coded GA, [003] Wang et al. 2003.
"""

from .aga import AGA
from .asaga import ASAGA
from .base import EvolutionaryAlgorithm
from .ea import EA
from .fga import FGA
from .gaia import AIA, GAIA

__all__ = ["ASAGA", "EA", "EvolutionaryAlgorithm", "GAIA", "AIA", "AGA", "FGA"]
