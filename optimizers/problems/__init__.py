"""Optimisation problems built on the shared lunar_env dynamics (pygmo UDP conventions)."""

from .landing import PenalisedProblem, PlanarLandingProblem

__all__ = ["PlanarLandingProblem", "PenalisedProblem"]
