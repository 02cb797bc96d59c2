"""ASAGA ([000] Zhu & Xu 2007): operators, adaptive rates, determinism, progress, resume."""

import numpy as np
import pytest

from optimizers.common.checkpoint import CheckpointMismatch
from optimizers.common.problem import Problem
from optimizers.evolutionary.asaga import ASAGA
from optimizers.evolutionary.penalties import paper_penalty_weight
from optimizers.problems.landing import PlanarLandingProblem


@pytest.fixture(scope="module")
def problem():
    return PlanarLandingProblem()


def test_paper_defaults():
    a = ASAGA()
    assert (a.n_pop, a.n_generations, a.t0, a.kappa) == (20, 300, 10000.0, 0.97)
    assert (a.n_accept_min, a.n_inner_max, a.n_anneal, a.n_recross_max) == (10, 10, 2, 10)
    assert a.temperature(1) == 10000.0
    assert a.temperature(300) == pytest.approx(10000 * 0.97**299)
    assert a.delta(1) == 0.5 and a.delta(300) == pytest.approx(0.5 / 300)
    # [000] eq. (11): σ2 from 1 (first half) to 10 (T = Tmax); σ1 = 5σ2 is the problem's factor
    assert a.penalty_weight is paper_penalty_weight
    assert paper_penalty_weight(0, 300) == paper_penalty_weight(150, 300) == 1.0
    assert paper_penalty_weight(300, 300) == pytest.approx(10.0)
    groups = {g.name: g.factor for g in PlanarLandingProblem().penalty_groups()}
    assert groups == {"velocity": 5.0, "radius": 1.0}


def test_adaptive_rates_eq15_18():
    a = ASAGA()
    T = 150  # r1 = 0.375, k1 = 0.3
    f_max, f_avg = 1.0, 0.5
    pc, r = a.adaptive_rates(np.array([1.0, 0.75, 0.2]), f_max, f_avg, T, "crossover")
    np.testing.assert_allclose(pc, [0.7, 0.8, 0.9])
    np.testing.assert_allclose(r, [0.375, 0.375 + 0.25, 0.375 + 0.5])
    pm, k = a.adaptive_rates(np.array([1.0, 0.75, 0.2]), f_max, f_avg, T, "mutation")
    np.testing.assert_allclose(pm, [0.005, 0.0075, 0.01])
    np.testing.assert_allclose(k, [0.3, 0.55, 0.8])
    pc, r = a.adaptive_rates(np.array([0.3]), 0.3, 0.3, T, "crossover")  # flat population
    assert np.isfinite(pc).all() and np.isfinite(r).all()


def test_operators_respect_bounds_and_are_seeded():
    a = ASAGA()
    rng = np.random.default_rng(0)
    lb = np.zeros(11)
    ub = np.r_[9.0 * np.arange(1, 11), 700.0]
    lb[-1] = 500.0
    A = lb + (ub - lb) * rng.random((50, 11))
    B = lb + (ub - lb) * rng.random((50, 11))
    r = rng.uniform(0.2, 1.0, 50)
    for op in range(3):
        out1 = out2 = None
        for _ in range(2):
            g = np.random.default_rng(42)
            if op == 0:
                out = np.concatenate(a.crossover(A, B, r, lb, ub, g))
            elif op == 1:
                out = a.mutate(A, np.full(50, 0.5), np.full(50, 1.0), lb, ub, g)
            else:
                out = a.neighbour(A, 0.5, lb, ub, g)
            out1, out2 = out, out1
        assert np.all(out1 >= lb) and np.all(out1 <= ub)
        np.testing.assert_array_equal(out1, out2)
    # crossover eq. (12): A' + B' = A + B whenever no clipping was needed
    g = np.random.default_rng(1)
    a2, b2 = a.crossover(A[:1] * 0 + (lb + ub) / 2, B[:1] * 0 + (lb + ub) / 2, np.array([0.05]),
                         lb, ub, g)
    np.testing.assert_allclose((a2 + b2)[0], lb + ub)
    # roulette respects the weights
    idx = a.roulette(np.array([0.0, 1.0, 0.0]), 100, np.random.default_rng(0))
    assert np.all(idx == 1)


def test_seeded_runs_are_deterministic(problem):
    algo = ASAGA(n_generations=8)
    r1 = algo.solve(problem, seed=7)
    r2 = algo.solve(problem, seed=7)
    r3 = algo.solve(problem, seed=8)
    np.testing.assert_array_equal(r1.x, r2.x)
    np.testing.assert_array_equal(r1.history, r2.history)
    assert not np.array_equal(r1.x, r3.x)
    lb, ub = problem.get_bounds()
    assert np.all(r1.x >= lb) and np.all(r1.x <= ub)


def test_short_run_improves_fitness(problem):
    # constant penalty weights: with elitism the best fitness can only grow
    algo = ASAGA(n_generations=40, penalty_weight=lambda T, Tmax: 10.0)
    res = algo.solve(problem, seed=3)
    h = res.extra["history_fitness"]
    assert len(h) == 40 and np.all(np.diff(h) >= -1e-12)
    assert len(res.history) == 40 and res.n_iter == 40
    assert h[-1] > h[0]
    assert res.n_fevals >= 40 * 20
    assert res.fuel_kg == pytest.approx(problem.fitness(res.x)[0])
    assert set(res.terminal_errors) >= {"speed_m_s", "radius_m"}
    assert res.wall_s > 0 and isinstance(res.success, bool) and res.message


def test_checkpoint_resume_equals_uninterrupted(problem, tmp_path):
    algo = ASAGA(n_generations=12)
    full = algo.solve(problem, seed=5)
    ck = tmp_path / "asaga.pkl"
    part = algo.solve(problem, seed=5, checkpoint=ck, checkpoint_every=4,
                      callback=lambda T, s: T == 6)  # "interrupted" after generation 6
    assert part.extra["n_generations"] == 6
    # the checkpoint on disk is at generation 4; resuming repeats 5..12 with the saved stream
    resumed = ASAGA(n_generations=12).solve(problem, seed=5, checkpoint=ck)
    np.testing.assert_array_equal(resumed.x, full.x)
    np.testing.assert_array_equal(resumed.history, full.history)
    assert resumed.n_fevals == full.n_fevals


def test_checkpoint_of_another_run_is_refused(problem, tmp_path):
    # a finished zhu2007 checkpoint used to answer for wang2003, and a
    # checkpoint of a longer run resumed with fewer generations returned fitness -2.3e36
    ck = tmp_path / "asaga.pkl"
    ASAGA(n_generations=4).solve(problem, seed=5, checkpoint=ck)
    with pytest.raises(CheckpointMismatch, match="problem"):
        ASAGA(n_generations=4).solve(PlanarLandingProblem("wang2003"), seed=5, checkpoint=ck)
    with pytest.raises(CheckpointMismatch, match="n_generations"):
        ASAGA(n_generations=2).solve(problem, seed=5, checkpoint=ck)
    with pytest.raises(CheckpointMismatch, match="seed"):
        ASAGA(n_generations=4).solve(problem, seed=6, checkpoint=ck)
    ck.write_bytes(ck.read_bytes()[:40])  # damaged file: a clear error naming it
    with pytest.raises(ValueError, match="damaged"):
        ASAGA(n_generations=4).solve(problem, seed=5, checkpoint=ck)


class _Infeasible(Problem):
    """min x0² + x1² s.t. x0 + x1 = 10 on [-1, 1]²: no feasible point."""

    def get_bounds(self):
        return np.array([-1.0, -1.0]), np.array([1.0, 1.0])

    def get_nec(self):
        return 1

    def _batch_fitness(self, X):
        return np.stack([(X**2).sum(1), X.sum(1) - 10.0], axis=1)


class _NaNProblem(_Infeasible):
    def _batch_fitness(self, X):
        return np.full((len(X), 2), np.nan)


class _Reversed(_Infeasible):
    def get_bounds(self):
        return np.array([1.0, -1.0]), np.array([-1.0, 1.0])


def test_no_false_success():
    # success is the problem's verdict, not True whatever the problem said
    res = ASAGA(n_generations=5).solve(_Infeasible(), seed=0)
    assert not res.success and not res.feasible
    assert res.terminal_errors["eq_0"] <= -8.0 + 1e-9
    res = ASAGA(n_generations=3).solve(_NaNProblem(), seed=0)
    assert not res.success and "not finite" in res.message
    with pytest.raises(ValueError, match="reversed"):
        ASAGA(n_generations=3).solve(_Reversed(), seed=0)


def test_trajectory_on_request_and_progress(problem, capsys):
    res = ASAGA(n_generations=3, verbose=1).solve(problem, seed=1, return_trajectory=True)
    assert "ASAGA gen    3/3" in capsys.readouterr().out
    tr = res.trajectory
    assert tr is not None and tr.t_s[-1] == pytest.approx(res.tf_s)


class CountedLanding(PlanarLandingProblem):
    """The planar landing problem, recording the size of every batch it evaluates."""

    def __init__(self) -> None:
        super().__init__()
        self.batches: list[int] = []

    def _batch_fitness(self, X):
        self.batches.append(len(X))
        return super()._batch_fitness(X)


def test_pygmo_uda():
    """``pygmo.algorithm(ASAGA).evolve``: the evolved population's best penalised fitness beats
    the initial population's, and the problem's ``n_fevals`` counts every evaluation: pygmo's
    initial population (one by one), the run's initial population, per generation the 20
    children and then the annealing moves of the n0 = 2 best children (batches of at most 2,
    at most n_inner_max + 1 moves each), and the final population written back."""
    import pygmo as pg

    from optimizers.common.problem import PygmoProblem

    uda = ASAGA(n_generations=5)
    uda.set_seed(3)
    pop = pg.population(CountedLanding().to_pygmo(), size=20, seed=2)
    F0 = pop.get_f().copy()
    pop = pg.algorithm(uda).evolve(pop)
    assert len(pop) == 20
    p = pop.problem.extract(PygmoProblem).problem  # pygmo evolves its own copy
    assert p.n_fevals == sum(p.batches)
    b = p.batches
    assert b[:21] == [1] * 20 + [20] and b[-1] == 20
    gens = np.flatnonzero(np.array(b[21:-1]) == 20)
    assert len(gens) == 5 and gens[0] == 0
    for anneal in np.split(np.array(b[21:-1]), gens[1:]):
        moves = anneal[1:]
        assert 1 <= len(moves) <= uda.n_inner_max + 1 and np.all(moves <= uda.n_anneal)
        assert uda.n_anneal <= moves.sum() <= uda.n_anneal * (uda.n_inner_max + 1)
    F = pop.get_f()
    assert uda.fitness(p, F, 5).max() > uda.fitness(p, F0, 5).max()


def test_bad_settings_raise():
    with pytest.raises(ValueError, match="n_pop"):
        ASAGA(n_pop=21)
    with pytest.raises(ValueError, match="kappa"):
        ASAGA(kappa=1.5)
    with pytest.raises(ValueError, match="r1_start"):
        ASAGA(r1_start=float("nan"))
    with pytest.raises(ValueError, match="delta_start"):
        ASAGA(delta_start=-5)
    with pytest.raises(ValueError, match="anneal_result"):
        ASAGA(anneal_result="worst")
