"""PlanarLandingProblem: bounds, batched fitness, decoding, RK4 accuracy, pygmo adapter."""

import numpy as np
import pytest

from lunar_env.integrators import PLANAR, integrate_reference
from optimizers.common.penalties import penalised_fitness
from optimizers.problems.landing import DEFAULT_N_STEPS, PlanarLandingProblem
from optimizers.problems.penalised import PenalisedProblem

# Near the optimum of the cubic parameterisation (input only: found once by SLSQP; the node
# values are not unique, the cubic they fit is).
X_NEAR_OPT = np.array([2.868, 5.867, 8.977, 12.218, 15.606, 19.161, 22.901, 26.845, 31.01,
                       35.414, 604.519])


@pytest.fixture(scope="module")
def problem():
    return PlanarLandingProblem()


def _random_x(problem, n, seed=0):
    lb, ub = problem.get_bounds()
    return lb + (ub - lb) * np.random.default_rng(seed).random((n, lb.size))


def test_zhu2007_bounds_eq24_25(problem):
    lb, ub = problem.get_bounds()
    np.testing.assert_array_equal(lb, [0] * 10 + [500])
    np.testing.assert_array_equal(ub, [9, 18, 27, 36, 45, 54, 63, 72, 81, 90, 700])
    assert problem.dim == 11 and problem.get_nec() == 3 and problem.get_nic() == 0


def test_batch_fitness_equals_loop_of_fitness(problem):
    X = np.vstack([_random_x(problem, 7), X_NEAR_OPT])
    F = problem.batch_fitness(X)
    assert F.shape == (8, 4)
    loop = np.array([problem.fitness(x) for x in X])
    np.testing.assert_allclose(F, loop, rtol=0, atol=1e-9)


def test_fuel_is_mass_flow_times_tf(problem):
    F = problem.fitness(X_NEAR_OPT)
    v = problem.scenario.vehicle
    assert F[0] == pytest.approx(v.mass_flow_kg_s * X_NEAR_OPT[-1], rel=1e-12)


def test_near_optimal_point_lands(problem):
    # sanity of the physics: the SLSQP point meets the terminal conditions to < 1 m/s, 10 m
    F = problem.fitness(X_NEAR_OPT)
    assert np.hypot(F[1], F[2]) < 1.0 and abs(F[3]) < 10.0


@pytest.mark.parametrize("which", ["near_opt", "random"])
def test_rk4_step_count_is_accurate_against_dop853(problem, which):
    x = X_NEAR_OPT if which == "near_opt" else _random_x(problem, 1, seed=3)[0]
    ctrl, tf_nd = problem.control(x[None])
    ref = integrate_reference(PLANAR, problem.y0_nd, (0.0, float(tf_nd[0])),
                              lambda t: ctrl(np.array([[t]]))[0, 0], problem.params)
    e_ref = problem.terminal_errors_from_state(ref.y[:, -1][None])
    F = problem.fitness(x)
    d_vr = abs(F[1] - e_ref["radial_velocity_m_s"][0])
    d_vt = abs(F[2] - e_ref["tangential_velocity_m_s"][0])
    d_r = abs(F[3] - e_ref["radius_m"][0])
    d_m = abs(F[0] - (problem.y0_nd[4] - ref.y[4, -1]) * problem.scaling.mass_kg)
    msg = f"n_steps={DEFAULT_N_STEPS}: dvr {d_vr:.2e} m/s, dvt {d_vt:.2e} m/s, dr {d_r:.2e} m"
    assert d_vr < 1e-4 and d_vt < 1e-4, msg
    assert d_r < 1e-2, msg
    assert d_m < 1e-9


def test_decode_is_consistent_with_fitness(problem):
    x = X_NEAR_OPT
    d = problem.decode(x)
    F = problem.fitness(x)
    assert d["fuel_kg"] == pytest.approx(F[0], abs=1e-9)
    assert d["terminal_errors"]["radial_velocity_m_s"] == pytest.approx(F[1], abs=1e-9)
    assert d["terminal_errors"]["radius_m"] == pytest.approx(F[3], abs=1e-9)
    tr = d["trajectory"]
    assert tr.t_s[0] == 0 and tr.t_s[-1] == pytest.approx(x[-1])
    assert tr.states["mass_kg"][-1] == pytest.approx(600.0 - F[0], abs=1e-9)
    assert tr.states["radius_m"][-1] - 1738e3 == pytest.approx(F[3], abs=1e-6)
    # the control is the cubic through the nodes: at the node times it is the fitted value
    phi_nodes = problem.thrust_angle_rad(x, d["node_times_s"])
    np.testing.assert_allclose(np.polyval(d["coefficients_rad"][::-1], d["node_times_s"]),
                               phi_nodes, atol=1e-10)
    # the fitted cubic passes close to the node angles (least squares, not interpolation)
    assert np.max(np.abs(phi_nodes - d["node_angles_rad"])) < np.deg2rad(2.0)
    t, phi = tr.sample("phi_rad")
    np.testing.assert_allclose(phi, problem.thrust_angle_rad(x, t))


def test_gradient_matches_differences(problem):
    J = problem.gradient(X_NEAR_OPT)
    assert J.shape == (4, 11)
    h = 1e-3
    e = np.zeros(11)
    e[-1] = h
    fd = (problem.fitness(X_NEAR_OPT + e) - problem.fitness(X_NEAR_OPT - e)) / (2 * h)
    np.testing.assert_allclose(J[:, -1], fd, rtol=1e-4, atol=1e-6)
    assert J[0, -1] == pytest.approx(problem.scenario.vehicle.mass_flow_kg_s, rel=1e-6)


def test_penalised_fitness_is_eq11(problem):
    # [000] eq. (11) up to a constant: −σ1·|ΔV|/v_ref − σ2·|Δr|/L + m(tf)/m0 with σ1 = 5σ2
    F = np.array([[277.0, 3.0, -4.0, 20.0]])
    s = problem.scaling
    expect = -50.0 * 5.0 / s.velocity_m_s - 10.0 * 20.0 / s.length_m + (600 - 277) / 600
    assert penalised_fitness(problem, F, 10.0)[0] + 1.0 == pytest.approx(expect, rel=1e-12)
    si = PlanarLandingProblem(penalty_units="si")
    assert penalised_fitness(si, F, 10.0)[0] == pytest.approx(-250.0 - 200.0 - 277.0)
    with pytest.raises(ValueError, match="penalty_units"):
        PlanarLandingProblem(penalty_units="km")


def test_problem_decides_success(problem):
    ok = problem.assess(X_NEAR_OPT)
    assert set(ok.terminal_errors) == {"radial_velocity_m_s", "tangential_velocity_m_s",
                                       "speed_m_s", "radius_m"}
    assert ok.fuel_kg == pytest.approx(problem.fitness(X_NEAR_OPT)[0])
    assert ok.tf_s == X_NEAR_OPT[-1]
    assert ok.success == (ok.terminal_errors["speed_m_s"] < 0.5
                          and abs(ok.terminal_errors["radius_m"]) < 1.0)
    far = X_NEAR_OPT.copy()
    far[-1] -= 20.0  # 20 s short of the landing: tens of m/s left
    bad = problem.assess(far)
    assert not bad.success and "NOT met" in bad.message


def test_bad_input_raises():
    with pytest.raises(ValueError, match="objective"):
        PlanarLandingProblem(objective="time")
    with pytest.raises(ValueError, match="planar"):
        PlanarLandingProblem("peng2012")
    p = PlanarLandingProblem()
    with pytest.raises(ValueError, match="finite"):
        p.batch_fitness(np.full((1, 11), np.nan))


def test_final_mass_objective_matches_fuel(problem):
    q = PlanarLandingProblem(objective="final_mass")
    X = _random_x(problem, 4, seed=5)
    Fq, Fp = q.batch_fitness(X), problem.batch_fitness(X)
    np.testing.assert_allclose(q.fuel_kg_from_fitness(Fq), Fp[:, 0], atol=1e-9)
    np.testing.assert_allclose(Fq[:, 1:], Fp[:, 1:])


def test_pygmo_algorithms_solve_our_problem(problem):
    import pygmo as pg

    pen = PenalisedProblem(problem)
    prob = pen.to_pygmo()
    pop = pg.population(prob, size=20, seed=1)
    f0 = pop.champion_f[0]
    pop = pg.algorithm(pg.sade(gen=10, seed=1)).evolve(pop)
    assert pop.champion_f[0] <= f0
    assert pop.problem.get_fevals() >= 20 * 11
    # constrained problem with gradients: one SLSQP polish from the near-optimal point
    cprob = problem.to_pygmo()
    assert cprob.has_gradient() and cprob.get_nec() == 3
    algo = pg.algorithm(pg.nlopt("slsqp"))
    algo.extract(pg.nlopt).maxeval = 20
    cpop = pg.population(cprob)
    cpop.push_back(X_NEAR_OPT)
    cpop = algo.evolve(cpop)
    f = cpop.champion_f
    assert np.all(np.isfinite(f)) and abs(f[3]) < 10.0
