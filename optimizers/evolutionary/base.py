"""The base class of the evolutionary algorithms: everything but the generation itself.

A subclass (see :mod:`optimizers.evolutionary.asaga`, the template to copy) implements

- ``name`` (class attribute) and :meth:`settings` (its hyperparameters, recorded in
  checkpoints),
- :meth:`_initial_state` (the population and whatever it carries, as a dict),
- :meth:`_generation` (one generation: updates the state dict in place and appends to the
  histories it keeps in ``state["history"]``),
- :meth:`_best` (the algorithm's answer: index into the final population),
- optionally :meth:`_converged` (an early stop rule of the paper) and :meth:`_result_extra`.

The base class provides the rest, identically for every algorithm: bounds validation, the seeded
``numpy.random.Generator``, a progress bar and periodic progress lines, atomic checkpoints that
record what they belong to (algorithm, settings, problem fingerprint, seed) and resume
bit-for-bit, a ``callback`` that can stop the run, the pygmo UDA interface (``evolve``), and a
result whose verdict comes from the problem (:meth:`optimizers.common.problem.Problem.assess`).
"""

from __future__ import annotations

import os
import time
from abc import ABC, abstractmethod
from typing import Any

import numpy as np

from ..common.checkpoint import load_checkpoint, save_checkpoint
from ..common.problem import Problem, PygmoProblem
from ..common.result import OptimResult
from .operators import uniform_population

__all__ = ["EvolutionaryAlgorithm"]


def _as_rng(seed) -> tuple[np.random.Generator, int | None]:
    if isinstance(seed, np.random.Generator):
        return seed, None
    if seed is not None and (isinstance(seed, bool) or int(seed) != seed):
        raise TypeError(f"seed = {seed!r} must be an int, a numpy.random.Generator or None")
    return np.random.default_rng(seed), (None if seed is None else int(seed))


class EvolutionaryAlgorithm(ABC):
    """Base of the population-based optimisers (seed, progress, checkpoints, pygmo UDA).

    Parameters
    ----------
    verbose : int
        0 silent; N > 0 prints a progress line every N generations.
    progress_bar : bool
        Show a tqdm progress bar over the generations.
    """

    name = "evolutionary algorithm"
    n_generations: int

    def __init__(self, *, verbose: int = 0, progress_bar: bool = False) -> None:
        self.verbose = int(verbose)
        if self.verbose < 0:
            raise ValueError(f"verbose = {verbose!r} must be >= 0")
        self.progress_bar = bool(progress_bar)

    # ---- what a subclass provides --------------------------------------------------------
    @abstractmethod
    def settings(self) -> dict[str, Any]:
        """The hyperparameters (JSON-like values); part of a checkpoint's identity."""

    @abstractmethod
    def _initial_state(self, problem: Problem, lb: np.ndarray, ub: np.ndarray,
                       rng: np.random.Generator, x0: np.ndarray | None) -> dict[str, Any]:
        """Initial population and bookkeeping; must hold ``X`` (n, dim) and ``F`` (n, n_f)."""

    @abstractmethod
    def _generation(self, problem: Problem, state: dict[str, Any], generation: int,
                    lb: np.ndarray, ub: np.ndarray, rng: np.random.Generator) -> None:
        """Advance ``state`` by generation number ``generation`` (1-based)."""

    @abstractmethod
    def _best(self, problem: Problem, state: dict[str, Any], generation: int) -> int:
        """Index into ``state["X"]`` of the algorithm's answer."""

    def _initial_population(self, lb: np.ndarray, ub: np.ndarray, rng: np.random.Generator,
                            x0: np.ndarray | None, n: int) -> np.ndarray:
        """``x0`` clipped into the bounds, or ``n`` uniform draws in them when ``x0`` is None.

        Raises
        ------
        ValueError
            ``x0`` is not of shape (n, dim).
        """
        if x0 is None:
            return uniform_population(lb, ub, n, rng)
        x0 = np.asarray(x0, dtype=np.float64)
        if x0.shape != (n, lb.size):
            raise ValueError(f"x0 has shape {x0.shape}; {self.name} needs ({n}, {lb.size})")
        return np.clip(x0, lb, ub)

    def _converged(self, state: dict[str, Any], generation: int) -> bool:
        """The paper's early-stop rule, if any (default: run every generation)."""
        return False

    def _progress(self, problem: Problem, state: dict[str, Any], generation: int) -> str:
        h = state["history"]
        return f"best objective {h['objective'][-1]:.7g}" if h.get("objective") else ""

    def _result_extra(self, problem: Problem, state: dict[str, Any], best: int
                      ) -> dict[str, Any]:
        return {}

    # ---- the run --------------------------------------------------------------------------
    def identity(self, problem: Problem, seed: int | None) -> dict[str, Any]:
        """What a checkpoint of this run belongs to."""
        return {"algorithm": type(self).__qualname__, "settings": self.settings(),
                "problem": problem.fingerprint(), "seed": seed}

    def solve(self, problem: Problem, *, seed: int | np.random.Generator | None = None,
              x0: np.ndarray | None = None, return_trajectory: bool = False,
              checkpoint: str | os.PathLike | None = None, checkpoint_every: int = 25,
              callback=None) -> OptimResult:
        """Run the algorithm on ``problem``.

        Parameters
        ----------
        problem : Problem
        seed : int or numpy.random.Generator, optional
            The run is deterministic for a given int seed.
        x0 : ndarray, shape (n_pop, dim), optional
            Initial population (default: uniform in the bounds).
        return_trajectory : bool
            Decode the answer into ``result.trajectory`` (needs ``problem.decode``).
        checkpoint : path, optional
            If the file exists the run **resumes** from it (an interrupted and resumed run equals
            an uninterrupted one); it is rewritten atomically every ``checkpoint_every``
            generations and at the end. A checkpoint of another algorithm, other settings,
            another problem or another seed is refused (:class:`~optimizers.common.checkpoint.
            CheckpointMismatch`).
        callback : callable, optional
            ``callback(generation, state) -> bool``; returning True stops the run.

        Returns
        -------
        OptimResult
            Verdict (success, terminal errors, fuel, tf) from ``problem.assess``; ``history`` the
            objective of the best individual per generation; ``n_iter`` the generations run.

        Raises
        ------
        ValueError
            Reversed or non-finite bounds, a bad ``x0``, a damaged checkpoint.
        """
        t_start = time.perf_counter()
        lb, ub = problem.checked_bounds()
        if int(checkpoint_every) < 1:
            raise ValueError(f"checkpoint_every = {checkpoint_every!r} must be >= 1")
        rng, seed_int = _as_rng(seed)
        ident = self.identity(problem, seed_int)
        n_fevals0 = problem.n_fevals
        state = None
        if checkpoint is not None and os.path.exists(checkpoint):
            state = load_checkpoint(checkpoint, ident)
            rng.bit_generator.state = state["rng_state"]
        if state is None:
            if x0 is not None:
                x0 = np.array(x0, dtype=np.float64)
                if not np.all(np.isfinite(x0)):
                    raise ValueError("x0 must be finite")
            state = self._initial_state(problem, lb, ub, rng, x0)
            state.setdefault("history", {})
            state.update(generation=0, n_fevals=0, wall_s=0.0, rng_state=None)
        n_fevals_prev, wall_prev = state["n_fevals"], state["wall_s"]

        def _snapshot():
            state["n_fevals"] = n_fevals_prev + problem.n_fevals - n_fevals0
            state["wall_s"] = wall_prev + time.perf_counter() - t_start
            state["rng_state"] = rng.bit_generator.state

        bar = None
        if self.progress_bar:
            from tqdm.auto import tqdm

            bar = tqdm(total=self.n_generations, initial=state["generation"], desc=self.name,
                       leave=False)
        stopped = converged = False
        try:
            for g in range(state["generation"] + 1, self.n_generations + 1):
                self._generation(problem, state, g, lb, ub, rng)
                state["generation"] = g
                if bar is not None:
                    bar.update(1)
                if self.verbose and (g % self.verbose == 0 or g == self.n_generations):
                    print(f"{self.name} gen {g:4d}/{self.n_generations}: "
                          f"{self._progress(problem, state, g)}", flush=True)
                converged = self._converged(state, g)
                last = g == self.n_generations or converged
                if checkpoint is not None and (g % checkpoint_every == 0 or last):
                    _snapshot()
                    save_checkpoint(checkpoint, ident, state)
                if callback is not None and callback(g, state):
                    stopped = True
                    break
                if converged:
                    break
        finally:
            if bar is not None:
                bar.close()
        _snapshot()
        g_final = state["generation"]
        i = self._best(problem, state, max(g_final, 1))
        x_best = np.asarray(state["X"][i], dtype=np.float64)
        verdict = problem.assess(x_best, state["F"][i])
        trajectory = problem.decode(x_best)["trajectory"] if return_trajectory else None
        why = ("stopped by callback" if stopped else
               "converged (stop rule)" if converged else "completed")
        extra = {f"history_{k}": np.asarray(v) for k, v in state["history"].items()
                 if k != "objective"}
        extra.update(n_generations=g_final, F=np.asarray(state["F"][i]).copy(),
                     population=np.asarray(state["X"]).copy())
        extra.update(self._result_extra(problem, state, i))
        return OptimResult.from_assessment(
            verdict, x_best, history=state["history"].get("objective", []),
            n_fevals=state["n_fevals"], n_iter=g_final, wall_s=state["wall_s"],
            message=f"{why} after {g_final} generations", algorithm=self.name,
            problem=problem.get_name(), trajectory=trajectory, extra=extra,
            control=problem.control_law(x_best))

    # ---- pygmo user-defined algorithm -----------------------------------------------------
    def get_name(self) -> str:
        return self.name

    def set_verbosity(self, level: int) -> None:
        self.verbose = int(level)

    def set_seed(self, seed: int) -> None:
        self._uda_seed = int(seed)

    def evolve(self, pop):
        """pygmo UDA entry point: ``pygmo.algorithm(algo).evolve(pop)``.

        The population's size is this algorithm's population. If its problem wraps one of ours
        (:class:`~optimizers.common.problem.PygmoProblem`) the batched fitness is used;
        otherwise pygmo's ``fitness`` is called per individual.
        """
        inner = pop.problem.extract(PygmoProblem)
        problem = inner.problem if inner is not None else _PygmoAsProblem(pop.problem)
        res = self.solve(problem, seed=getattr(self, "_uda_seed", None),
                         x0=np.asarray(pop.get_x()))
        Xf = res.extra["population"]
        Ff = problem.batch_fitness(Xf)
        for i in range(len(Xf)):
            pop.set_xf(i, Xf[i], Ff[i])
        return pop


class _PygmoAsProblem(Problem):
    """Wrap a ``pygmo.problem`` for :meth:`EvolutionaryAlgorithm.evolve` (per-individual)."""

    def __init__(self, prob) -> None:
        super().__init__()
        self.prob = prob
        c_tol = np.asarray(prob.c_tol, dtype=float)
        self.c_tol = float(c_tol.max()) if c_tol.size else 0.0

    def get_bounds(self):
        lb, ub = self.prob.get_bounds()
        return np.asarray(lb, float), np.asarray(ub, float)

    def get_nec(self) -> int:
        return self.prob.get_nec()

    def get_nic(self) -> int:
        return self.prob.get_nic()

    def get_name(self) -> str:
        return self.prob.get_name()

    def _batch_fitness(self, X):
        return np.array([self.prob.fitness(x) for x in X])

