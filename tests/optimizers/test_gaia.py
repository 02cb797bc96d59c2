"""[002] Peng et al.: the low-thrust transfer problem, GAIA / AIA and the AGA baseline."""

import math

import numpy as np
import pytest

from lunar_env.integrators import PLANAR, integrate_reference
from optimizers.common.checkpoint import CheckpointMismatch
from optimizers.evolutionary.aga import AGA
from optimizers.evolutionary.gaia import AIA, GAIA, annealed_penalty_weight
from optimizers.problems.low_thrust import LowThrustTransferProblem, paper_node_bounds


@pytest.fixture(scope="module")
def problem():
    return LowThrustTransferProblem()


# a point near the parameterisation's optimum (SLSQP, see optimizers.reproduce.peng_mars)
X_NEAR_OPT = np.array([0.0, 0.2522, 0.8235, 0.9027, 1.1721, 4.1826, 4.9390, 5.3415, 5.5192,
                       5.7029, 3.7468])


def test_paper_bounds_and_dimensions(problem):
    lb, ub = problem.get_bounds()
    np.testing.assert_allclose(lb, [0] * 5 + [math.pi] * 5 + [3.5])
    np.testing.assert_allclose(ub, [math.pi] * 5 + [2 * math.pi] * 5 + [4.0])
    assert problem.get_nec() == 3 and problem.dim == 11
    assert repr(problem.parameterisation) == "NodePolynomial(n_nodes=10, degree=5)"  # N = 6
    lo, hi = paper_node_bounds(4)
    np.testing.assert_allclose(lo, [0, 0, math.pi, math.pi])


def test_thrust_angle_convention(problem):
    """u = 0 is thrust along the motion: the spacecraft spirals outward and gains energy;
    u = π brakes it inward (the paper's v_θ' = … + (F/m) cos u)."""
    tf = 3.5
    out = problem.fitness(np.r_[np.zeros(10), tf])
    inward = problem.fitness(np.r_[np.full(10, math.pi), tf])
    r0 = problem.y0_nd[0]
    assert out[1] + problem.target_nd[0] > r0 + 0.1
    assert inward[1] + problem.target_nd[0] < r0 - 0.1
    np.testing.assert_allclose(problem.paper_angle(problem.model_angle([0.3, 5.9])), [0.3, 5.9])


def test_rk4_against_dop853(problem):
    """The fixed-step RK4 of the fitness against an adaptive DOP853 replay of the same law."""
    f = problem.fitness(X_NEAR_OPT)
    control, tf_nd = problem.control(X_NEAR_OPT[None, :])
    ref = integrate_reference(PLANAR, problem.y0_nd, (0.0, float(tf_nd[0])),
                              lambda t: control(np.array([[t]]))[0, 0], problem.params,
                              rtol=1e-11, atol=1e-13)
    y = ref.y[:, -1]
    assert abs(f[1] - (y[0] - problem.target_nd[0])) < 1e-6   # r0 units: < 150 km
    assert abs(f[2] - y[1]) < 1e-6 and abs(f[3] - (y[0] * y[3] - problem.target_nd[2])) < 1e-6
    assert abs(-f[0] - y[4]) < 1e-12  # the mass depends on tf only


def test_assess_and_decode(problem):
    a = problem.assess(X_NEAR_OPT)
    assert a.success, a.message  # 4-decimal rounding of the optimum still arrives
    assert 252.0 < a.fuel_kg < 253.0
    assert a.tf_s == pytest.approx(3.7468 * problem.scaling.time_s)
    d = problem.decode(X_NEAR_OPT)
    tr = d["trajectory"]
    assert tr.states["mass_kg"][-1] == pytest.approx(800.0 - a.fuel_kg)
    np.testing.assert_allclose(tr.controls["u_rad"][0], problem.thrust_angle_rad(X_NEAR_OPT,
                                                                                  [0.0])[0])
    far = problem.assess(np.r_[np.zeros(10), 3.5])
    assert not far.success and "did NOT arrive" in far.message
    with pytest.raises(ValueError, match="planar"):
        LowThrustTransferProblem("peng2012")
    with pytest.raises(ValueError, match="radius_tol_m"):
        LowThrustTransferProblem(radius_tol_m=0.0)


def test_penalty_readings():
    assert annealed_penalty_weight(0, 100) == 1.0
    assert annealed_penalty_weight(100, 100) == pytest.approx(20.0)  # T_λ / β
    g_on = math.log(10) / math.log(200) * 100  # the curve crosses 1 at 43.5 % of the run
    assert annealed_penalty_weight(int(g_on), 100) == 1.0
    assert annealed_penalty_weight(int(g_on) + 2, 100) > 1.0
    assert annealed_penalty_weight(0, 100, reading="inverse") == pytest.approx(10.0)
    assert annealed_penalty_weight(100, 100, reading="inverse") == pytest.approx(2000.0)
    assert annealed_penalty_weight(70, 100, reading="constant") == 1.0
    with pytest.raises(ValueError, match="reading"):
        annealed_penalty_weight(1, 10, reading="linear")


def test_concentration_and_stimulation():
    lb, ub = np.zeros(3), np.ones(3)
    same = np.full((4, 3), 0.5)
    np.testing.assert_allclose(GAIA.concentration(same, lb, ub), 1.0)
    X = np.array([[0.0, 0, 0], [0, 0, 0], [1, 1, 1]])
    den = GAIA.concentration(X, lb, ub)
    assert den[0] == den[1] > den[2]  # the two identical antibodies are the crowded ones
    g = GAIA()
    sti = g.stimulation(np.array([1.0, 1.0, 0.5]), den)
    assert sti[0] > sti[2] == 0.0  # the worst affinity scales to 0
    sti = g.stimulation(np.array([1.0, 1.0, 1.0]), den)
    assert sti[2] > sti[0]  # equal affinity: the lone antibody is favoured (a = 2)
    assert g.guide_factor(1.0, 1.01) < 0.5 < g.guide_factor(1.0, 0.99)
    assert g.guide_factor(1.0, 1.01) == pytest.approx(1 / (1 + math.exp(1.5)))


def test_gaia_short_run(problem):
    algo = GAIA(n_pop=20, n_generations=8, n_clones=5)
    r1 = algo.solve(problem, seed=3)
    r2 = algo.solve(problem, seed=3)
    np.testing.assert_array_equal(r1.x, r2.x)
    assert r1.n_fevals == 20 + 8 * (10 * 5 + 10)
    h = r1.extra["history_guide"]
    assert len(h) == 8 and np.all((h > 0) & (h < 1))
    # with fixed weights, elitism + clonal suppression never lose the best affinity
    fixed = GAIA(n_pop=20, n_generations=8, n_clones=5, penalty_reading="constant")
    fit = fixed.solve(problem, seed=3).extra["history_fitness"]
    assert np.all(np.diff(fit) >= 0)
    assert r1.fuel_kg == pytest.approx(problem.assess(r1.x).fuel_kg)
    aia = AIA(n_pop=20, n_generations=4, n_clones=5).solve(problem, seed=3)
    assert aia.algorithm == "AIA" and np.all(aia.extra["history_guide"] == 0.0)


def test_gaia_resume_equals_uninterrupted(problem, tmp_path):
    algo = GAIA(n_pop=10, n_generations=6, n_clones=3)
    full = algo.solve(problem, seed=5)
    ck = tmp_path / "gaia.pkl"
    algo.solve(problem, seed=5, checkpoint=ck, checkpoint_every=2, callback=lambda g, s: g == 3)
    resumed = GAIA(n_pop=10, n_generations=6, n_clones=3).solve(problem, seed=5, checkpoint=ck)
    np.testing.assert_array_equal(resumed.x, full.x)
    np.testing.assert_array_equal(resumed.history, full.history)
    with pytest.raises(CheckpointMismatch):
        AIA(n_pop=10, n_generations=6, n_clones=3).solve(problem, seed=5, checkpoint=ck)


def test_aga_short_run_and_resume(problem, tmp_path):
    full = AGA(n_pop=20, n_generations=6).solve(problem, seed=1)
    assert full.n_fevals == 20 * 7 and full.algorithm == "AGA"
    ck = tmp_path / "aga.pkl"
    AGA(n_pop=20, n_generations=6).solve(problem, seed=1, checkpoint=ck, checkpoint_every=3,
                                         callback=lambda g, s: g == 4)
    resumed = AGA(n_pop=20, n_generations=6).solve(problem, seed=1, checkpoint=ck)
    np.testing.assert_array_equal(resumed.x, full.x)


def test_pygmo_uda(problem):
    import pygmo as pg

    pop = pg.population(problem.to_pygmo(), size=10, seed=2)
    pop = pg.algorithm(GAIA(n_pop=10, n_generations=2, n_clones=2)).evolve(pop)
    assert len(pop) == 10 and np.all(np.isfinite(pop.get_f()))
    pop = pg.algorithm(AGA(n_pop=10, n_generations=2)).evolve(pop)
    assert len(pop) == 10


def test_paper_defaults_and_bad_settings():
    g = GAIA()
    assert (g.n_pop, g.n_generations, g.n_clones, g.p_mutation, g.a, g.b) == (
        100, 100, 20, 0.8, 2.0, 150.0)
    assert (g.beta, g.t_lambda) == (0.005, 0.1)
    assert (AGA().n_pop, AGA().n_generations) == (100, 100)
    with pytest.raises(ValueError, match="p_mutation"):
        GAIA(p_mutation=1.5)
    with pytest.raises(ValueError, match="penalty_reading"):
        GAIA(penalty_reading="x")
    with pytest.raises(ValueError, match="n_pop"):
        AGA(n_pop=7)
    with pytest.raises(ValueError, match="AIA"):
        AIA(guided=True)
