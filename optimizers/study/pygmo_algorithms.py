"""pygmo's unconstrained optimisers as study algorithms (``solve(problem, seed) -> OptimResult``).

sade, cmaes and pso handle no constraints: they minimise the problem's penalty function
(:class:`~optimizers.problems.penalised.PenalisedProblem`, the penalty of [000] eq. (11)
with a fixed weight, as in ``benchmarks/bench_optimizers.py``). The verdict on the champion is
the original problem's (:meth:`~optimizers.common.problem.Problem.assess`), as for every solver.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..common.problem import Problem
from ..common.result import OptimResult
from ..problems.penalised import PenalisedProblem

__all__ = ["PygmoAlgorithm", "PygmoCMAES", "PygmoSADE", "PygmoPSO"]


class PygmoAlgorithm:
    """A pygmo algorithm on the penalised problem.

    Parameters
    ----------
    algorithm : {"cmaes", "sade", "pso"}
    n_pop : int
        Population (20, ASAGA's M).
    n_generations : int
        Generations (600: about the evaluations of a 300-generation ASAGA run).
    penalty_weight : float
        Fixed weight of the penalty (10: ASAGA's final σ2).
    """

    _ALGOS = ("cmaes", "sade", "pso")

    def __init__(self, algorithm: str = "cmaes", n_pop: int = 20, n_generations: int = 600,
                 penalty_weight: float = 10.0) -> None:
        if algorithm not in self._ALGOS:
            raise ValueError(f"algorithm = {algorithm!r}; allowed: {self._ALGOS}")
        if int(n_pop) < 5 or int(n_generations) < 1:
            raise ValueError(f"n_pop = {n_pop!r} must be >= 5 and n_generations = "
                             f"{n_generations!r} >= 1")
        if not float(penalty_weight) > 0:
            raise ValueError(f"penalty_weight = {penalty_weight!r} must be > 0")
        self.algorithm = algorithm
        self.n_pop, self.n_generations = int(n_pop), int(n_generations)
        self.penalty_weight = float(penalty_weight)
        self.name = f"pygmo {algorithm}"

    def settings(self) -> dict[str, Any]:
        return {"algorithm": self.algorithm, "n_pop": self.n_pop,
                "n_generations": self.n_generations, "penalty_weight": self.penalty_weight}

    def solve(self, problem: Problem, *, seed=None) -> OptimResult:
        import pygmo as pg

        if isinstance(seed, np.random.Generator):
            seed = int(seed.integers(0, 2**31 - 1))
        seed = int(np.random.default_rng().integers(0, 2**31 - 1)) if seed is None else int(seed)
        t0 = time.perf_counter()
        pen = PenalisedProblem(problem, self.penalty_weight)
        make = {"cmaes": lambda: pg.cmaes(gen=self.n_generations, seed=seed, force_bounds=True),
                "sade": lambda: pg.sade(gen=self.n_generations, seed=seed),
                "pso": lambda: pg.pso(gen=self.n_generations, seed=seed)}[self.algorithm]
        pop = pg.population(pen.to_pygmo(), size=self.n_pop, seed=seed)
        pop = pg.algorithm(make()).evolve(pop)
        x = np.asarray(pop.champion_x, dtype=np.float64)
        verdict = problem.assess(x)
        return OptimResult.from_assessment(
            verdict, x, history=[float(pop.champion_f[0])], n_fevals=int(pop.problem.get_fevals()),
            n_iter=self.n_generations, wall_s=time.perf_counter() - t0, algorithm=self.name,
            problem=problem.get_name(), message=f"{self.n_generations} generations",
            control=problem.control_law(x))


class PygmoCMAES(PygmoAlgorithm):
    def __init__(self, **kw) -> None:
        super().__init__("cmaes", **kw)


class PygmoSADE(PygmoAlgorithm):
    def __init__(self, **kw) -> None:
        super().__init__("sade", **kw)


class PygmoPSO(PygmoAlgorithm):
    def __init__(self, **kw) -> None:
        super().__init__("pso", **kw)
