"""[004]: the free-time two-impulse problem, its certification and the EA."""

from __future__ import annotations

import numpy as np
import pytest

from lunar_env.lambert import solve_lambert
from optimizers.evolutionary import operators as ops
from optimizers.evolutionary.ea import EA
from optimizers.problems.two_impulse import TwoImpulseProblem, certify_global_minimum

R1 = np.array([0.0, 7_380_000.0, 0.0])
V1 = np.array([7349.21, 0.0, 0.0])
R2 = np.array([6_401_659.785, 3_696_000.0, 0.0])
V2 = np.array([3671.622, -6359.435, 0.0])
MU = 3.986004418e14


def test_fitness_is_the_cheapest_branch_and_matches_a_direct_computation():
    p = TwoImpulseProblem(0.03, "transfer")
    t = 1052.867
    # the initial orbit is clockwise about +z: the own-sense single-revolution arc
    s = solve_lambert(R1, R2, t, MU, prograde=False)
    direct = (np.linalg.norm(s.v1_m_s[0, 0] - V1) + np.linalg.norm(V2 - s.v2_m_s[0, 0])
              + 0.03 * t)
    assert p.fitness([t])[0] == pytest.approx(direct, rel=1e-12)
    costs = p.branch_costs([t, 8000.0])
    assert np.allclose(p.batch_fitness(np.array([[t], [8000.0]]))[:, 0], np.nanmin(costs, 1))
    d = p.decode([t])
    assert d["branch"] == "cw (own sense) N=0" and d["n_revs"] == 0
    assert d["miss_m"] < 1.0
    # at 8000 s a one-revolution arc exists and is cheaper than the single-revolution one
    assert p.decode([8000.0])["n_revs"] == 1
    a = p.assess(np.array([t]))
    assert a.success and a.tf_s == t and a.terminal_errors["miss_m"] < 1.0


def test_interception_does_not_charge_the_second_impulse():
    t = np.array([[1052.0], [1060.0]])
    tr = TwoImpulseProblem(0.3, "transfer").batch_fitness(t)[:, 0]
    it = TwoImpulseProblem(0.3, "interception").batch_fitness(t)[:, 0]
    assert np.all(it < tr)
    d = TwoImpulseProblem(0.3, "interception").decode([1052.0])
    assert it[0] == pytest.approx(np.linalg.norm(d["dv1_m_s"]) + 0.3 * 1052.0, rel=1e-12)


def test_branch_restrictions_and_bad_input():
    both = TwoImpulseProblem(3.0, "interception")
    same = TwoImpulseProblem(3.0, "interception", directions="same")
    assert len(both.branch_labels) == 2 * len(same.branch_labels)
    assert all(lbl.startswith("cw") for lbl in same.branch_labels)
    with pytest.raises(ValueError, match="mode"):
        TwoImpulseProblem(0.1, "rendezvous")
    with pytest.raises(ValueError, match="k_weight"):
        TwoImpulseProblem(-1.0)
    with pytest.raises(ValueError, match="time_bounds_s"):
        TwoImpulseProblem(0.1, time_bounds_s=(100.0, 50.0))


def test_certified_minimum_reproduces_a_printed_interception_row():
    """[004] Table 2, K = 0.003: J = 12.186, T = 1052.093 (target of an independent method)."""
    p = TwoImpulseProblem(0.003, "interception")
    c = certify_global_minimum(p, n_scan=20_001)
    assert c["cost_m_s"] == pytest.approx(12.186, abs=5e-4)
    assert c["tof_s"] == pytest.approx(1052.093, abs=2e-3)
    assert c["branch"] == "cw (own sense) N=0"
    # every local minimum found is no better, and a denser grid finds the same answer
    assert all(m.cost_m_s >= c["cost_m_s"] for m in c["local_minima"])
    grid = np.linspace(1040.0, 1065.0, 5001)
    assert p.batch_fitness(grid[:, None]).min() >= c["cost_m_s"] - 1e-9


def test_ea_reaches_the_certified_optimum_and_never_beats_it():
    p = TwoImpulseProblem(0.03, "transfer")
    c = certify_global_minimum(p, n_scan=20_001)
    res = EA(stall_generations=1000).solve(p, seed=0)
    assert res.n_iter == 80 and res.n_fevals == 50 + 80 * 150
    assert res.fun >= c["cost_m_s"] - 1e-9
    assert res.fun == pytest.approx(c["cost_m_s"], abs=1e-3)
    assert res.success and res.tf_s == pytest.approx(c["tof_s"], abs=0.05)
    assert np.all(np.diff(res.history) <= 1e-12)  # (λ+μ) selection is elitist


def test_ea_as_printed_stops_on_the_epsilon_rule():
    p = TwoImpulseProblem(0.3, "interception")
    res = EA().solve(p, seed=1)
    assert res.n_iter < 80 and "converged" in res.message
    assert len(res.history) == res.n_iter


def test_ea_is_deterministic_and_resumes_from_a_checkpoint(tmp_path):
    p = TwoImpulseProblem(0.3, "transfer")
    algo = EA(n_generations=12, stall_generations=100)
    a = algo.solve(p, seed=4)
    b = algo.solve(p, seed=4)
    assert a.fun == b.fun and np.array_equal(a.history, b.history)
    ck = tmp_path / "ea.ckpt"
    stopped = algo.solve(p, seed=4, checkpoint=ck, checkpoint_every=1,
                         callback=lambda g, s: g == 5)
    assert stopped.n_iter == 5
    resumed = algo.solve(p, seed=4, checkpoint=ck)
    assert resumed.fun == a.fun and np.array_equal(resumed.history, a.history)


def test_ea_as_pygmo_uda():
    import pygmo as pg

    p = TwoImpulseProblem(3.0, "interception")
    pop = pg.population(p.to_pygmo(), size=50, seed=1)
    algo = pg.algorithm(EA(n_generations=10, stall_generations=100))
    algo.set_seed(3)
    pop = algo.evolve(pop)
    assert pop.champion_f[0] < 3164.573 + 50


def test_ea_settings_are_validated():
    for kw in (dict(n_children=151), dict(n_parents=1), dict(mutation_probability=1.5),
               dict(epsilon=-1.0), dict(b=0.0), dict(stall_generations=0)):
        with pytest.raises(ValueError):
            EA(**kw)


def test_operators_of_004():
    rng = np.random.default_rng(0)
    lb, ub = np.array([100.0]), np.array([10_000.0])
    A = rng.uniform(lb, ub, (500, 1))
    B = rng.uniform(lb, ub, (500, 1))
    a, b = ops.linear_crossover(A, B, rng)
    assert np.allclose(a + b, A + B)  # α Z + (1−α) Y and α Y + (1−α) Z
    assert np.all((a >= np.minimum(A, B) - 1e-9) & (a <= np.maximum(A, B) + 1e-9))
    early = ops.nonuniform_mutation(A, 1, 80, 2.5, lb, ub, rng)
    late = ops.nonuniform_mutation(A, 79, 80, 2.5, lb, ub, rng)
    last = ops.nonuniform_mutation(A, 80, 80, 2.5, lb, ub, rng)
    assert np.all((early >= lb) & (early <= ub))
    assert np.abs(late - A).mean() < 0.01 * np.abs(early - A).mean()
    assert np.array_equal(last, A)  # Δ(T, y) = 0
    X = np.array([[0.0], [0.5], [3.0], [3.2], [9.0]])
    pen = ops.niche_clearing(X, np.array([1.0, 0.0, 5.0, 2.0, np.inf]), np.array([1.0]))
    assert pen.tolist() == [True, False, True, False, True]
