"""optimizers: trajectory optimisers from the literature on the shared lunar_env dynamics.

Every optimiser consumes the :class:`optimizers.common.problem.Problem` interface (pygmo's
user-defined problem is the model) and returns an :class:`optimizers.common.result.OptimResult`.
"""

from .common.problem import Problem
from .common.result import OptimResult

__all__ = ["Problem", "OptimResult"]
