"""FGA ([003] Wang et al. 2003): operators against their definitions, elitism, Pc/Pm, seeds,
resume, pygmo UDA."""

import numpy as np
import pytest

from optimizers.common.problem import Problem
from optimizers.evolutionary import FGA
from optimizers.evolutionary import operators as ops
from optimizers.problems import ThrustDesignProblem


class Sphere(Problem):
    """Shifted sphere with one equality: the constrained optimum is known."""

    def get_bounds(self):
        return np.full(4, -5.0), np.full(4, 5.0)

    def get_nec(self):
        return 1

    def _batch_fitness(self, X):
        return np.c_[((X - 1.0) ** 2).sum(axis=1), X[:, 0] - 2.0]


def test_paper_defaults_and_validation():
    a = FGA()
    assert (a.n_pop, a.n_generations, a.pc, a.pm, a.n_elite) == (20, 10_000, 0.6, 0.05, 10)
    for bad in (dict(pc=1.5), dict(pm=-0.1), dict(n_pop=1), dict(n_elite=20), dict(n_elite=1),
                dict(n_generations=0), dict(mutation_b=np.nan), dict(penalty_weight=-1.0)):
        with pytest.raises(ValueError, match=next(iter(bad))):
            FGA(**bad)


def test_whole_arithmetic_crossover_is_convex_and_conserves_the_sum():
    rng = np.random.default_rng(0)
    A, B = rng.random((2000, 3)), rng.random((2000, 3)) + 2.0
    a, b = ops.linear_crossover(A, B, np.random.default_rng(1))
    np.testing.assert_allclose(a + b, A + B)
    lam = (a - B) / (A - B)  # A' = λA + (1 − λ)B: one λ per pair, the same for every gene
    np.testing.assert_allclose(lam, lam[:, :1] * np.ones(3))
    assert lam.min() >= 0 and lam.max() <= 1
    assert abs(lam[:, 0].mean() - 0.5) < 0.03  # λ ~ U(0, 1)


def test_non_uniform_mutation_definition():
    lb, ub = np.zeros(5), np.full(5, 10.0)
    C = np.full((4000, 5), 4.0)

    def mutate(C, pm, progress, lb, ub, rng):
        return FGA(pm=pm).mutate(C, progress, lb, ub, rng)

    out = mutate(C, 0.05, 0.0, lb, ub, np.random.default_rng(2))
    moved = out != C
    assert abs(moved.mean() - 0.05) < 0.005  # each parameter mutates with probability Pm
    assert np.all(out >= lb) and np.all(out <= ub)
    # at progress 0 the step is uniform over the distance to the chosen bound
    up = out[moved & (out > C)]
    assert abs((up - 4.0).mean() / 6.0 - 0.5) < 0.05
    # the step shrinks with progress and vanishes at the end of the run
    late = mutate(C, 1.0, 0.9, lb, ub, np.random.default_rng(3))
    assert np.abs(late - C).mean() < 0.01 * np.abs(
        mutate(C, 1.0, 0.0, lb, ub, np.random.default_rng(3)) - C).mean()
    end = mutate(C, 1.0, 1.0, lb, ub, np.random.default_rng(4))
    np.testing.assert_array_equal(end, C)


def test_crossover_probability_is_pc():
    lb, ub = np.zeros(3), np.ones(3)
    pool = np.random.default_rng(0).random((10, 3))
    a = FGA(pm=0.0)
    rng = np.random.default_rng(5)
    n_same = n_tot = 0
    for _ in range(400):
        kids = a._offspring(pool, 10, 0.5, lb, ub, rng)
        # an uncrossed pair is copied: its children are members of the pool
        is_copy = (np.abs(kids[:, None, :] - pool[None]).max(axis=2) == 0).any(axis=1)
        n_same += is_copy.sum()
        n_tot += kids.shape[0]
    assert abs(1.0 - n_same / n_tot - 0.6) < 0.03


def test_elitism_best_never_worsens_and_converges_on_a_sphere():
    # the L1 penalty is exact once its weight exceeds the multiplier (2 here); with w = 1 the
    # penalised optimum is x0 = 1.5
    assert FGA(n_generations=300).solve(Sphere(), seed=0).x[0] == pytest.approx(1.5, abs=0.02)
    res = FGA(n_generations=600, penalty_weight=10.0).solve(Sphere(), seed=0)
    f = np.asarray(res.extra["history_fitness"])
    assert np.all(np.diff(f) >= 0)  # the elite survive unchanged
    np.testing.assert_allclose(res.x, [2.0, 1.0, 1.0, 1.0], atol=0.02)
    assert res.n_fevals == 20 + 600 * 10  # only the offspring are evaluated


def test_seeded_deterministic_and_resume(tmp_path):
    p = ThrustDesignProblem()
    a = FGA(n_generations=40)
    r1, r2 = a.solve(p, seed=3), a.solve(p, seed=3)
    np.testing.assert_array_equal(r1.x, r2.x)
    ck = tmp_path / "fga.pkl"
    FGA(n_generations=40).solve(p, seed=3, checkpoint=ck, checkpoint_every=7,
                                callback=lambda g, s: g == 21)
    r3 = a.solve(p, seed=3, checkpoint=ck, checkpoint_every=7)
    np.testing.assert_array_equal(r1.x, r3.x)
    np.testing.assert_array_equal(r1.history, r3.history)
    assert r1.algorithm == "FGA" and r1.n_iter == 40
    assert set(r1.terminal_errors) >= {"speed_m_s", "radius_m"}


class CountedThrustDesign(ThrustDesignProblem):
    """The thrust-design problem, recording the size of every batch it evaluates."""

    def __init__(self) -> None:
        super().__init__()
        self.batches: list[int] = []

    def _batch_fitness(self, X):
        self.batches.append(len(X))
        return super()._batch_fitness(X)


def test_pygmo_uda():
    """``pygmo.algorithm(FGA).evolve``: the evolved population's best penalised fitness beats
    the initial population's, the fitness written back is that of the individuals, and the
    problem's ``n_fevals`` counts every evaluation: pygmo's initial population (one by one),
    then the run's (its initial population, then the 10 children of each generation, the 10
    elite being carried), then the final population written back."""
    import pygmo as pg

    from optimizers.common.problem import PygmoProblem

    pop = pg.population(CountedThrustDesign().to_pygmo(), size=20, seed=1)
    F0 = pop.get_f().copy()
    algo = FGA(n_generations=30)
    algo.set_seed(4)
    pop = pg.algorithm(algo).evolve(pop)
    p = pop.problem.extract(PygmoProblem).problem  # pygmo evolves its own copy
    assert p.batches == [1] * 20 + [20] + [10] * 30 + [20]
    assert p.n_fevals == 20 + (20 + 30 * 10) + 20 == sum(p.batches)
    F = pop.get_f()
    assert algo.fitness(p, F, 30).max() > algo.fitness(p, F0, 30).max()
    np.testing.assert_array_equal(F, p.batch_fitness(pop.get_x()))
