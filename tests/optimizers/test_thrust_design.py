"""[003]'s problem: thrust as a design variable, physics checks, the paper's 14-variable view."""

import numpy as np
import pytest

from lunar_env import dynamics as dyn
from lunar_env import get_scenario
from lunar_env.integrators import PLANAR, integrate_reference
from optimizers.problems import ThrustDesignProblem
from optimizers.problems.thrust_design import scenario_at_thrust

# near the certified optimum: T = 2.989 kN, tf = 219.86 s, ψ from −11.6° to 23.9°
X_OPT = np.array([219.855, 2.989, -11.600, -0.797, 11.408, 23.855])


@pytest.fixture(scope="module")
def problem():
    return ThrustDesignProblem()


def test_layout_and_bounds(problem):
    lb, ub = problem.get_bounds()
    np.testing.assert_array_equal(lb, [100, 0, -90, -90, -90, -90])
    np.testing.assert_array_equal(ub, [800, 4, 90, 90, 90, 90])
    assert problem.get_nec() == 3 and problem.dim == 6
    with pytest.raises(ValueError, match="thrust_bounds_kn"):
        ThrustDesignProblem(thrust_bounds_kn=(0.0, 5.0))
    with pytest.raises(ValueError, match="penalty_units"):
        ThrustDesignProblem(penalty_units="furlongs")
    with pytest.raises(ValueError, match="thrust_n"):
        scenario_at_thrust("wang2003", -1.0)


def test_fuel_is_T_tf_over_isp_g0(problem):
    f = problem.fitness(X_OPT)
    veh = get_scenario("wang2003").vehicle
    assert f[0] == pytest.approx(2989.0 * 219.855 / (veh.isp_s * veh.g0_m_s2), rel=1e-12)
    # near the optimum the terminal errors are small (the cubic is close to optimal)
    assert abs(f[1]) < 0.1 and abs(f[2]) < 0.1 and abs(f[3]) < 2.0


def test_rk4_against_dop853(problem):
    law = problem.control_law(X_OPT)
    s = problem.scaling
    ref = integrate_reference(PLANAR, problem.y0_nd, (0.0, X_OPT[0] / s.time_s),
                              lambda t: law(t * s.time_s), problem.params)
    err = problem.terminal_errors_from_state(ref.y[:, -1][None, :])
    f = problem.fitness(X_OPT)
    assert abs(err["radial_velocity_m_s"][0] - f[1]) < 1e-4
    assert abs(err["tangential_velocity_m_s"][0] - f[2]) < 1e-4
    assert abs(err["radius_m"][0] - f[3]) < 1e-2


def test_zero_thrust_is_a_kepler_arc(problem):
    x = np.array([300.0, 0.0, 0.0, 10.0, 20.0, 30.0])
    d = problem.decode(x)
    assert d["fuel_kg"] == 0.0
    st = d["trajectory"].states
    s = problem.scaling
    y = np.c_[st["radius_m"] / s.length_m, st["radial_velocity_m_s"] / s.velocity_m_s,
              st["theta_rad"], st["angular_rate_rad_s"] * s.time_s, st["mass_kg"] / s.mass_kg]
    e = dyn.planar_energy(y)
    h = dyn.planar_angular_momentum(y)
    assert np.ptp(e) < 1e-10 and np.ptp(h) < 1e-10


def test_full_thrust_equals_the_fixed_thrust_scenario(problem):
    """T = T_max through the throttle equals the scenario flown at full thrust."""
    x = X_OPT.copy()
    x[1] = 4.0
    f = problem.fitness(x)
    p4 = ThrustDesignProblem(scenario_at_thrust("wang2003", 4000.0), thrust_bounds_kn=(0, 4))
    np.testing.assert_array_equal(f, p4.fitness(x))
    x2 = X_OPT.copy()
    x2[1] = 2.0  # half throttle of 4 kN = full throttle of a 2 kN engine
    p2 = ThrustDesignProblem(scenario_at_thrust("wang2003", 2000.0), thrust_bounds_kn=(0, 2))
    np.testing.assert_allclose(problem.fitness(x2), p2.fitness(x2), rtol=1e-12, atol=1e-9)


def test_paper_view_14_variables_6_equalities(problem):
    v = problem.paper_variables(X_OPT)
    assert len(v) == 14
    res = problem.boundary_residuals(X_OPT)
    assert len(res) == 6
    assert res["r_t0_m"] == 0 and res["v_r_t0_m_s"] == 0 and abs(res["v_theta_t0_m_s"]) < 1e-9
    f = problem.fitness(X_OPT)
    assert res["r_tf_m"] == pytest.approx(f[3], abs=1e-6)
    # a0..a3 reproduce the node angles
    a = problem.coefficients(X_OPT)
    t = X_OPT[0] * np.array([0, 1 / 3, 2 / 3, 1])
    np.testing.assert_allclose(np.degrees(np.polyval(a[::-1], t)), X_OPT[2:], atol=1e-9)
    d = problem.decode(X_OPT)
    assert 5.0 < d["downrange_deg"] < 8.0
    assert d["fuel_fraction"] == pytest.approx(d["fuel_kg"] / 500.0)


def test_a_dive_into_the_moon_stays_finite(problem):
    x = np.array([792.4, 2.07, 5.94, -80.9, 5.71, 37.75])  # found by a GA: passes r = 0
    f = problem.fitness(x)
    assert np.all(np.isfinite(f)) and f[3] < -800e3
    assert not problem.assess(x).success
