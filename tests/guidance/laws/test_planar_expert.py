"""The closed-loop re-planning expert (guidance.laws.pontryagin_planar.PontryaginExpert)."""

import numpy as np
import pytest

from guidance.laws.pontryagin_planar import (
    STATUS_CONSTRAINED,
    STATUS_FALLBACK,
    STATUS_HOLD,
    STATUS_OPTIMAL,
    PontryaginExpert,
)
from lunar_env.scenarios import get_scenario
from optimizers.indirect.planar import solve_planar_min_fuel


@pytest.fixture(scope="module")
def scenario():
    return get_scenario("zhu2007")


@pytest.fixture(scope="module")
def nominal(scenario):
    return solve_planar_min_fuel(scenario, check="grid")


def test_expert_returns_optimal_and_finite_angles(scenario, nominal):
    expert = PontryaginExpert(scenario)
    x0 = np.array([1753.0e3, 0.0, 0.0, 9.65e-4 * 1753.0e3, 600.0])
    phi = expert(x0)
    assert isinstance(phi, float) and np.isfinite(phi)
    assert expert.last_status == [STATUS_OPTIMAL]
    assert phi == pytest.approx(nominal.thrust_angle_at(0.0), abs=1e-6)
    # Along the optimal trajectory (mass clock), the expert reproduces the open-loop plan.
    traj = nominal.sample(7)
    rows = np.stack([traj.states[k] for k in ("radius_m", "radial_velocity_m_s", "theta_rad",
                                             "tangential_velocity_m_s", "mass_kg")], axis=1)
    for k in range(1, 4):
        assert expert(rows[k]) == pytest.approx(traj.controls["phi_rad"][k], abs=1e-5)
    # In the last seconds of the plan the expert holds the previous plan's angle.
    late = nominal.sample(2001)
    k = np.searchsorted(late.t_s, nominal.tf_s - 1.0)
    row = np.array([late.states[n][k] for n in ("radius_m", "radial_velocity_m_s", "theta_rad",
                                               "tangential_velocity_m_s", "mass_kg")])
    assert expert(row) == pytest.approx(late.controls["phi_rad"][k], abs=1e-6)
    assert expert.last_status == [STATUS_HOLD]
    # 500 m up, 22 m/s down, 1531 m/s along: the unconstrained extremal passes below ground,
    # the expert plans with r >= surface instead.
    expert.reset()
    dip = np.array([1738.0e3 + 492.6, -22.2, 0.0, 1530.7, 614.5])
    assert np.isfinite(expert(dip))
    assert expert.last_status == [STATUS_CONSTRAINED]
    # A batch with one hopeless row: 50 m up, falling at 100 m/s.
    bad = np.array([1738.0e3 + 50.0, -100.0, 0.0, 1600.0, 400.0])
    expert.reset()
    out = expert(np.stack([x0, bad]))
    assert out.shape == (2,) and np.all(np.isfinite(out))
    assert expert.last_status == [STATUS_OPTIMAL, STATUS_FALLBACK]
    assert out[1] == pytest.approx(np.arctan2(100.0, 1600.0))


def test_expert_bad_input_raises(scenario):
    expert = PontryaginExpert(scenario)
    with pytest.raises(ValueError, match="finite"):
        expert(np.array([1.75e6, 0.0, 0.0, np.inf, 600.0]))
    with pytest.raises(ValueError, match="shape"):
        expert(np.zeros((2, 3)))
