"""optimizers: trajectory optimisers from the literature on the shared lunar_env dynamics.

Two problem contracts, one result, three families:

- :class:`~optimizers.common.problem.Problem` — black-box (pygmo's UDP) for the global
  optimisers; its :meth:`~optimizers.common.problem.Problem.assess` is the verdict;
- :class:`~optimizers.common.ocp.OCP` — an optimal-control problem for the transcriptions and
  the indirect solvers;
- :class:`~optimizers.common.result.OptimResult` — what every solver returns;
- :func:`~optimizers.certification.certify` — replay a result and compare it with the
  certified optimum;
- families: :mod:`optimizers.evolutionary`, :mod:`optimizers.transcription`,
  :mod:`optimizers.indirect`; problems in :mod:`optimizers.problems`; paper reproductions in
  :mod:`optimizers.reproduce`.
"""

from .certification import certify
from .common.ocp import OCP
from .common.problem import Problem
from .common.result import OptimResult

__all__ = ["Problem", "OCP", "OptimResult", "certify"]
