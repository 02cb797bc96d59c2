"""certify(result, problem): DOP853 replay of any solver's control and the gap to the optimum."""

import numpy as np
import pytest

from lunar_env import get_scenario
from optimizers import OptimResult, certify
from optimizers.certification import certified_optimum
from optimizers.evolutionary.asaga import ASAGA
from optimizers.problems import PinpointOCP, PlanarLandingProblem, PlanarOCP
from optimizers.transcription.serial import solve_serial


@pytest.fixture(scope="module")
def landing():
    return PlanarLandingProblem("zhu2007")


def test_the_optimum_certifies_itself(landing):
    opt = certified_optimum(landing.ocp)
    assert certified_optimum(landing.ocp) is opt  # solved once per problem
    cert = certify(opt, landing.ocp)
    assert cert.replay_success, cert.replay_message
    assert cert.replay_terminal_errors["radius_m"] < 1e-4
    assert cert.fuel_gap_kg == 0.0 and cert.optimum_fuel_kg == pytest.approx(277.5852, abs=1e-3)


def test_a_ga_answer_is_replayed_and_judged_by_its_problem(landing):
    res = ASAGA(n_generations=30).solve(landing, seed=2)
    cert = certify(res, landing)
    # the DOP853 replay of the cubic lands where the compiled RK4 said (RK4 error ~1e-4 m)
    for key in ("radius_m", "radial_velocity_m_s", "tangential_velocity_m_s"):
        assert abs(abs(res.terminal_errors[key]) - cert.replay_terminal_errors[key]) < 1e-2
    assert cert.replay_success == res.success
    assert cert.fuel_gap_kg == pytest.approx(res.fuel_kg - cert.optimum_fuel_kg)


def test_pinpoint_serial_solution_against_dense_collocation():
    ocp = PinpointOCP(get_scenario("peng2012"))
    res = solve_serial(ocp)
    cert = certify(res, ocp)
    assert cert.replay_success, cert.replay_message
    assert cert.replay_path["min_altitude_m"] > 1900.0
    assert abs(cert.fuel_gap_kg) < 0.01 and abs(cert.tf_gap_s) < 0.02


def test_bad_use_raises():
    no_law = OptimResult(x=np.zeros(1), fuel_kg=1.0, tf_s=10.0, terminal_errors={},
                         history=np.zeros(0), n_fevals=0, wall_s=0.0, success=False, message="")
    with pytest.raises(ValueError, match="control law"):
        certify(no_law, PlanarOCP("zhu2007"), reference=no_law)
    with pytest.raises(TypeError, match="optimal-control problem"):
        certify(no_law, object())
