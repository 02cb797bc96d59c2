"""Pontryagin shooting for the planar minimum-fuel landing and its collocation check."""

import numpy as np
import pytest

from lunar_env import dynamics as dyn
from lunar_env.scenarios import get_scenario
from optimizers.indirect.batch import solve_many
from optimizers.indirect.planar import (
    PontryaginGuess,
    replay_reference,
    solve_planar_min_fuel,
)
from optimizers.indirect.planar_system import hamiltonian, optimal_thrust_angle, system_for
from optimizers.transcription.collocation import solve_planar_min_time_collocation
from optimizers.transcription.polynomial_shooting import solve_planar_min_time_polynomial

PAPER_000_PONTRYAGIN_FUEL_KG = 277.5765  # [000]: the paper's indirect optimum (target only)


@pytest.fixture(scope="module")
def scenario():
    return get_scenario("zhu2007")


@pytest.fixture(scope="module")
def nominal(scenario):
    return solve_planar_min_fuel(scenario)  # check="reference": DOP853 replay


def test_nominal_optimum_meets_the_boundary_conditions_on_replay(scenario, nominal):
    assert nominal.success, nominal.message
    assert nominal.check == "reference"
    err = nominal.terminal_errors
    assert err["radius_m"] < 1e-6
    assert err["radial_velocity_m_s"] < 1e-6
    assert err["tangential_velocity_m_s"] < 1e-6
    assert err["speed_m_s"] < 1e-6
    # An independent replay with scipy's default-ish tolerance agrees to the metre level too.
    xf = replay_reference(nominal, rtol=1e-12, atol=1e-14)
    assert abs(xf[dyn.R] * scenario.scaling().length_m - scenario.target.radius_m) < 1e-4
    # Fuel is the mass flow times tf, and the mass history agrees.
    traj = nominal.sample(51)
    assert traj.states["mass_kg"][0] - traj.states["mass_kg"][-1] == pytest.approx(
        nominal.fuel_kg, abs=1e-9)
    assert nominal.fuel_kg == pytest.approx(scenario.vehicle.mass_flow_kg_s * nominal.tf_s)
    # Ours differs from the paper's 277.5765 kg by < 0.01 kg (see the module docstring).
    assert abs(nominal.fuel_kg - PAPER_000_PONTRYAGIN_FUEL_KG) < 0.01


def test_hamiltonian_vanishes_along_the_arc_and_transversality(scenario, nominal):
    traj = nominal.sample(301)
    assert np.max(np.abs(traj.states["hamiltonian"])) < 1e-9
    z = nominal.state_costate_at(np.array([0.0, nominal.tf_s]))
    lam0, lamf = z[0, 5:], z[1, 5:]
    assert lam0[dyn.THETA] == 0.0 and lamf[dyn.THETA] == 0.0  # θ free and cyclic
    assert abs(lamf[dyn.M]) < 1e-12  # m(tf) free
    assert lam0[dyn.M] > 0  # more mass is worth less time: λ_m > 0 before tf


def test_optimal_angle_minimises_the_hamiltonian_pointwise(scenario, nominal):
    z = nominal.state_costate_at(np.linspace(0.0, nominal.tf_s, 40))
    x, lam = z[:, :5], z[:, 5:]
    phi_star = optimal_thrust_angle(x, lam)
    grid = np.linspace(-np.pi, np.pi, 1441)
    for k in range(len(z)):
        h_star = hamiltonian(scenario, x[k], lam[k], phi_star[k])[0]
        h_grid = hamiltonian(scenario, np.broadcast_to(x[k], (grid.size, 5)),
                             np.broadcast_to(lam[k], (grid.size, 5)), grid)
        assert h_star <= h_grid.min() + 1e-14
    # φ rises through the burn (the paper's figure) and stays in (0, π/2).
    assert 0.0 < phi_star[0] < phi_star[-1] < np.pi / 2


def test_costate_equations_are_minus_dh_dx(scenario, nominal):
    """CasADi's AD costate rhs against central differences of the NumPy Hamiltonian."""
    sysm = system_for(scenario.params())
    z = nominal.state_costate_at(np.array([0.3 * nominal.tf_s]))[0]
    x, lam = z[:5], z[5:]
    phi = optimal_thrust_angle(x, lam)
    rhs = np.asarray(sysm.rhs(z)).ravel()
    for i in range(5):
        e = np.zeros(5)
        e[i] = 1e-6 * max(1.0, abs(x[i]))
        dh = (hamiltonian(scenario, x + e, lam, phi)[0]
              - hamiltonian(scenario, x - e, lam, phi)[0]) / (2 * e[i])
        assert rhs[5 + i] == pytest.approx(-dh, rel=1e-6, abs=1e-8)


def test_independent_direct_collocation_agrees(scenario, nominal):
    """Dense Hermite–Simpson collocation (IPOPT): a direct method, no costates, no shooting."""
    col = solve_planar_min_time_collocation(scenario, n_intervals=100)
    assert col.success, col.message
    assert col.fuel_kg == pytest.approx(nominal.fuel_kg, abs=1e-4)
    assert col.tf_s == pytest.approx(nominal.tf_s, abs=2e-4)
    phi_ind = nominal.thrust_angle_at(col.t_nd * scenario.scaling().time_s)
    assert np.max(np.abs(phi_ind - col.phi_rad)) < 1e-3
    # Its multipliers estimate the costates with the sign convention of the indirect solver.
    lam_col = col.costates_nd[0]
    lam_ind = nominal.state_costate_at(col.t_mid_nd[0] * scenario.scaling().time_s)[0, 5:]
    assert np.allclose(lam_col, lam_ind, atol=2e-3)


def test_independent_direct_shooting_through_the_compiled_integrator(scenario, nominal):
    """Polynomial thrust angle, SLSQP, lunar_env.integrators.integrate (numba RK4)."""
    rich = solve_planar_min_time_polynomial(scenario, degree=7)
    assert rich.success, rich.message
    assert rich.terminal_errors["radius_m"] < 1e-5
    assert rich.fuel_kg == pytest.approx(nominal.fuel_kg, abs=1e-5)
    t = np.linspace(0.0, rich.tf_s, 50)
    assert np.max(np.abs(rich.thrust_angle_at(t) - nominal.thrust_angle_at(t))) < 2e-3
    # Paper 000's cubic is a restriction of the control space: an upper bound, barely above.
    cubic = solve_planar_min_time_polynomial(scenario, degree=3)
    assert cubic.success, cubic.message
    assert nominal.fuel_kg - 1e-6 < cubic.fuel_kg < nominal.fuel_kg + 1e-4


def test_dispersed_states_solve_warm_started(scenario, nominal):
    rng = np.random.default_rng(12)
    states = scenario.sample_initial(rng, 6)
    sols = solve_many(scenario, states, progress=False)
    assert all(s.success for s in sols), [s.message for s in sols]
    for s, row in zip(sols, states, strict=True):
        assert s.x0_nd[dyn.M] * scenario.scaling().mass_kg == pytest.approx(row[4])
        assert s.n_iter <= 8
        assert 250.0 < s.fuel_kg < 300.0
        assert s.terminal_errors["radius_m"] < 1e-6
    # One of them certified by the DOP853 replay.
    one = solve_planar_min_fuel(scenario, states[0], guess=nominal)
    assert one.success and one.terminal_errors["speed_m_s"] < 1e-6
    assert one.fuel_kg == pytest.approx(sols[0].fuel_kg, abs=1e-9)


def test_continuation_from_a_far_guess(scenario, nominal):
    """A guess from a state 3 km higher and 30 m/s faster still leads to the solution."""
    row = np.array([1753.0e3 + 3000.0, -5.0, 0.0, 9.65e-4 * 1753.0e3 + 30.0, 590.0])
    cold = solve_planar_min_fuel(scenario, row, check="grid")
    warm = solve_planar_min_fuel(scenario, row, guess=nominal, check="grid",
                                 collocation_fallback=False)
    assert cold.success and warm.success
    assert warm.fuel_kg == pytest.approx(cold.fuel_kg, abs=1e-8)


def test_heliocentric_low_thrust_transfer_solves():
    """The same problem with paper 002's constants: Earth-to-Mars, minimum time = maximum mass."""
    mars = get_scenario("peng_mars")
    sol = solve_planar_min_fuel(mars, check="doubling")  # RK4 error estimate
    assert sol.success, sol.message
    tf_nd = sol.tf_nd
    assert 3.5 <= tf_nd <= 4.0  # the paper's normalised tf bounds contain the optimum
    rel = sol.terminal_errors["radius_m"] / mars.target.radius_m
    assert rel < 1e-8
    assert np.max(np.abs(sol.sample(101).states["hamiltonian"])) < 1e-6


def test_bad_input_raises(scenario):
    with pytest.raises(ValueError, match="shape"):
        solve_planar_min_fuel(scenario, np.zeros(4))
    with pytest.raises(ValueError, match="finite"):
        solve_planar_min_fuel(scenario, np.array([1.75e6, 0.0, 0.0, np.nan, 600.0]))
    with pytest.raises(ValueError, match="dry mass"):
        solve_planar_min_fuel(scenario, np.array([1.75e6, 0.0, 0.0, 1690.0, 250.0]))
    with pytest.raises(ValueError, match="check"):
        solve_planar_min_fuel(scenario, check="exact")
    with pytest.raises(TypeError, match="PlanarScenario"):
        solve_planar_min_fuel(get_scenario("peng2012"))
    with pytest.raises(TypeError, match="guess"):
        solve_planar_min_fuel(scenario, guess=np.zeros(5))
    with pytest.raises(ValueError, match=r"\(N, 5\)"):
        solve_many(scenario, np.zeros((3, 4)))
    with pytest.raises(ValueError, match="row 1"):
        solve_many(scenario, np.array([[1.75e6, 0, 0, 1690.0, 600.0], [1.75e6, 0, 0, 1690, 1]]))


def test_guess_object_round_trip(scenario, nominal):
    g = nominal.guess
    assert isinstance(g, PontryaginGuess)
    again = solve_planar_min_fuel(scenario, guess=g, check="grid")
    assert again.success and again.n_iter == 0
    res = nominal.as_result()
    assert res.success and res.fuel_kg == nominal.fuel_kg
    assert res.trajectory.controls["phi_rad"].shape == (201,)


@pytest.mark.slow
def test_thousand_dispersed_states(scenario):
    rng = np.random.default_rng(2007)
    states = scenario.sample_initial(rng, 1000)
    sols = solve_many(scenario, states, n_workers=2, progress=False)
    ok = np.array([s.success for s in sols])
    assert ok.all(), [s.message for s in sols if not s.success][:5]
    fuel = np.array([s.fuel_kg for s in sols])
    assert np.all((fuel > 240.0) & (fuel < 320.0))


def test_degenerate_states_fail_cleanly(scenario):
    # a state already on the ground at rest raised ZeroDivisionError, and
    # failures reported terminal errors of 0.0
    s = solve_planar_min_fuel(scenario, [1738e3, 0.0, 0.0, 0.0, 600.0])
    assert not s.success and "already meets the terminal conditions" in s.message
    assert all(np.isnan(v) for v in s.terminal_errors.values())
    hopeless = solve_planar_min_fuel(scenario, [1738e3 + 50.0, -100.0, 0.0, 1600.0, 400.0])
    assert not hopeless.success
    assert not any(v == 0.0 for v in hopeless.terminal_errors.values())
