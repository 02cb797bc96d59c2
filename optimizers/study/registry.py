"""Algorithms and problems by name, for :mod:`optimizers.study` and anyone who wants one.

Adding an optimiser is one line in :data:`ALGORITHMS`: its name, the ``module:Class`` of a class
whose instances have ``solve(problem, *, seed) -> OptimResult`` (every
:class:`~optimizers.evolutionary.base.EvolutionaryAlgorithm` has), and the settings of a quick
smoke run. Adding a problem is one line in :data:`PROBLEMS`: its name, the ``module:factory`` of
a :class:`~optimizers.common.problem.Problem` and the keyword arguments. Imports are lazy (the
registry imports nothing until an entry is built), so it can list entries whose modules need
optional packages.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["ALGORITHMS", "PROBLEMS", "make_algorithm", "make_problem", "resolve"]

#: name -> ("module:Class", settings of the --quick smoke run)
ALGORITHMS: dict[str, tuple[str, dict[str, Any]]] = {
    "asaga": ("optimizers.evolutionary.asaga:ASAGA", {"n_generations": 30}),
    "gaia": ("optimizers.evolutionary.gaia:GAIA", {"n_generations": 10}),
    "aia": ("optimizers.evolutionary.gaia:AIA", {"n_generations": 10}),
    "aga": ("optimizers.evolutionary.aga:AGA", {"n_generations": 10}),
    "ea": ("optimizers.evolutionary.ea:EA", {"n_generations": 10}),
    "fga": ("optimizers.evolutionary.fga:FGA", {"n_generations": 30}),
    "pygmo-cmaes": ("optimizers.study.pygmo_algorithms:PygmoCMAES", {"n_generations": 30}),
    "pygmo-sade": ("optimizers.study.pygmo_algorithms:PygmoSADE", {"n_generations": 30}),
    "pygmo-pso": ("optimizers.study.pygmo_algorithms:PygmoPSO", {"n_generations": 30}),
}

#: name -> ("module:factory", keyword arguments)
PROBLEMS: dict[str, tuple[str, dict[str, Any]]] = {
    # [000] Zhu & Xu 2007 nominal landing, penalty in the paper's normalised units / in SI
    "zhu2007": ("optimizers.problems.landing:PlanarLandingProblem", {"scenario": "zhu2007"}),
    "zhu2007-si": ("optimizers.problems.landing:PlanarLandingProblem",
                   {"scenario": "zhu2007", "penalty_units": "si"}),
    # [002] Peng et al. Earth–Mars low-thrust transfer
    "peng_mars": ("optimizers.problems.low_thrust:LowThrustTransferProblem",
                  {"scenario": "peng_mars"}),
    # [003] Wang 2003 thrust-magnitude design of the descent
    "wang2003": ("optimizers.problems.thrust_design:ThrustDesignProblem", {"scenario": "wang2003"}),
    # [004] Wang 2001 two-impulse transfer (K = 1: minimum ΔV)
    "wang2001": ("optimizers.problems.two_impulse:TwoImpulseProblem", {"k_weight": 1.0}),
}


def resolve(spec: str):
    """The object named by ``"package.module:attribute"``."""
    mod, _, attr = spec.partition(":")
    if not attr:
        raise ValueError(f"{spec!r} must look like 'package.module:attribute'")
    return getattr(importlib.import_module(mod), attr)


def _lookup(table: dict, name: str, what: str):
    if name not in table:
        raise ValueError(f"unknown {what} {name!r}; available: {sorted(table)}")
    return table[name]


def make_algorithm(name: str, **settings):
    """An instance of the registered algorithm ``name`` with ``settings`` (its constructor's
    keyword arguments)."""
    spec, _ = _lookup(ALGORITHMS, name, "algorithm")
    return resolve(spec)(**settings)


def quick_settings(name: str) -> dict[str, Any]:
    """Settings of the algorithm's --quick smoke run."""
    return dict(_lookup(ALGORITHMS, name, "algorithm")[1])


def make_problem(name: str, **overrides):
    """The registered problem ``name`` (its keyword arguments updated by ``overrides``)."""
    spec, kwargs = _lookup(PROBLEMS, name, "problem")
    return resolve(spec)(**{**kwargs, **overrides})
