"""SCvx landing solver (optimizers.transcription.convex): replayed by DOP853, certified against
the Pontryagin optimum, unsuccessful (never NaN) from infeasible starts, settings validated."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lunar_env import get_scenario
from lunar_env.integrators import integrate_reference
from optimizers.certification import certify
from optimizers.problems.pinpoint import PinpointOCP
from optimizers.problems.planar_ocp import PlanarOCP
from optimizers.transcription.convex import ConvexGuess, SuccessiveConvexification

pytest.importorskip("cvxpy")


@pytest.fixture(scope="module")
def planar():
    """One solver (one cvxpy compilation) and its zhu2007 solution, shared by the module."""
    ocp = PlanarOCP("zhu2007")
    solver = SuccessiveConvexification(30)
    return ocp, solver, solver.solve(ocp)


def _finite_result(res) -> bool:
    return (math.isfinite(res.fuel_kg) and math.isfinite(res.tf_s)
            and all(math.isfinite(v) for v in res.terminal_errors.values()))


def test_zhu2007_nominal_converges_with_a_tight_relaxation(planar):
    ocp, _, res = planar
    assert res.success, res.message
    assert res.extra["converged"] and res.n_iter <= 15
    # constant engine: Γ = 1 and the relaxed direction ‖w‖ <= 1 is tight at every interval
    assert res.extra["min_throttle"] == pytest.approx(1.0)
    assert res.extra["tightness"] > 1.0 - 1e-6
    assert np.all(np.isfinite(res.states)) and res.states.shape == (30, 5)


def _replay_by_interval(res, ocp) -> np.ndarray:
    """DOP853 replay of the held controls, one call per interval (each segment smooth, so the
    adaptive steps do not stall on the control's jumps); returns the final state."""
    x = np.asarray(ocp.initial_state, dtype=float)
    t = res.t_nd
    for k in range(len(t) - 1):
        u = res.model_controls[k]
        out = integrate_reference(ocp.model, x, (t[k], t[k + 1]), lambda _t, u=u: u,
                                  ocp.params, rtol=1e-12, atol=1e-14)
        x = out.y[:, -1]
    return x


def test_zhu2007_dop853_replay_meets_the_terminal_conditions(planar):
    ocp, _, res = planar
    errors = ocp.terminal_errors(_replay_by_interval(res, ocp))
    assert errors["radius_m"] < ocp.tolerances["radius_m"]
    assert errors["speed_m_s"] < ocp.tolerances["speed_m_s"]


def test_zhu2007_fuel_is_certified_within_half_a_percent_of_pontryagin(planar):
    ocp, _, res = planar
    cert = certify(res, ocp, rtol=1e-9)   # the replay crosses 29 control jumps: 1e-9 is ample
    assert cert.replay_success, cert.replay_message
    assert cert.optimum_success
    # a feasible ZOH control cannot beat the continuous optimum by more than the replay noise
    assert -1e-3 < cert.fuel_gap_pct < 0.5


def test_warm_start_from_the_solution_converges_at_once(planar):
    ocp, solver, res = planar
    again = solver.solve(ocp, res.guess(), max_iter=3)
    assert again.success and again.n_iter <= 2
    assert again.fuel_kg == pytest.approx(res.fuel_kg, abs=1e-3)


def test_replan_from_a_shifted_start_stays_feasible(planar):
    ocp, solver, res = planar
    guess = res.guess().shifted(0.05)               # 52 s later along the plan
    x0 = guess.states[0] * np.array([1.0, 1.0, 1.0, 1.0005, 1.0])  # 0.05 % faster
    new = solver.solve(ocp, guess, initial_state=x0, max_iter=10)
    assert new.success, new.message
    np.testing.assert_allclose(new.states[0], x0)


def test_too_little_propellant_is_an_unsuccessful_result_not_a_nan(planar):
    ocp, solver, _ = planar
    sc = ocp.scenario
    start = ocp.initial_state_si.copy()
    start[4] = sc.vehicle.dry_mass_kg + 50.0        # 50 kg of propellant for ~278 kg needed
    res = solver.solve(ocp.with_initial_state_si(start), max_iter=15)
    assert not res.success
    assert _finite_result(res)
    assert res.message


def test_a_start_too_fast_to_stop_is_an_unsuccessful_result(planar):
    ocp, solver, _ = planar
    start = ocp.initial_state_si.copy()
    start[3] *= 1.6                                 # 2700 m/s: beyond the propellant's Δv
    res = solver.solve(ocp.with_initial_state_si(start), max_iter=15)
    assert not res.success and _finite_result(res)


@pytest.mark.parametrize("kwargs, name", [
    ({"n_nodes": 1}, "n_nodes"), ({"n_nodes": 2.5}, "n_nodes"), ({"trust_region": -0.1},
    "trust_region"), ({"trust_region": float("nan")}, "trust_region"),
    ({"virtual_control_weight": 0.0}, "virtual_control_weight"), ({"max_iter": 0}, "max_iter"),
    ({"n_rk4": 0}, "n_rk4"), ({"engine": "ion"}, "engine"),
    ({"trust_region": 3.0, "trust_region_max": 1.0}, "trust_region_max"),
    ({"engine": "throttled", "throttle_max": 1.5}, "throttle_max"),
    ({"engine": "throttled", "throttle_max": 0.0}, "throttle_max"),
    ({"throttle_max": 0.9}, "throttle_max"),       # the constant engine has no margin to keep
])
def test_bad_settings_raise_a_value_error_naming_them(kwargs, name):
    with pytest.raises(ValueError, match=name):
        SuccessiveConvexification(**kwargs)


def test_a_thrust_margin_caps_the_throttle_and_costs_propellant(planar):
    """A plan at most 94 % of the maximum thrust (three 1σ of a 2 % thrust error)
    keeps a margin for a weaker engine; it lands, replayed, and pays for it in propellant
    (zhu2007's throttled optimum burns at full thrust throughout, as the constant engine)."""
    ocp, _, full = planar
    res = SuccessiveConvexification(30, engine="throttled", throttle_max=0.94).solve(ocp)
    assert res.success, res.message
    assert res.controls[:, -1].max() <= 0.94 + 1e-6
    assert certify(res, ocp).replay_success
    assert 0.0 < res.fuel_kg - full.fuel_kg < 0.02 * full.fuel_kg


def test_bad_initial_state_or_guess_is_refused(planar):
    ocp, solver, res = planar
    with pytest.raises(ValueError, match="initial_state"):
        solver.solve(ocp, initial_state=np.array([1.0, np.nan, 0.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="guess"):
        solver.solve(ocp, ConvexGuess(res.tf_nd, res.states[:10], res.controls[:9]))


def test_shifted_guess_keeps_the_grid_and_refuses_elapsed_beyond_tf(planar):
    _, _, res = planar
    g = res.guess().shifted(0.1)
    assert g.states.shape == res.states.shape and g.controls.shape == res.controls.shape
    assert g.tf_nd == pytest.approx(res.tf_nd - 0.1)
    with pytest.raises(ValueError, match="elapsed_nd"):
        res.guess().shifted(res.tf_nd + 1.0)


# ---- 3D pinpoint (peng2012) ----------------------------------------------------------------


@pytest.fixture(scope="module")
def pinpoint():
    ocp = PinpointOCP(get_scenario("peng2012"))
    return ocp, SuccessiveConvexification(20).solve(ocp)


def test_peng2012_dop853_replay_meets_the_terminal_conditions(pinpoint):
    """Quick twin of the slow certified-fuel test: the replay lands on the target."""
    ocp, res = pinpoint
    assert res.success, res.message
    assert res.extra["tightness"] > 1.0 - 1e-6
    ok, why = ocp.success_from(ocp.terminal_errors(_replay_by_interval(res, ocp)))
    assert ok, why
    # the papers' angle bounds hold on every interval
    alpha, beta = res.model_controls[:, 0], res.model_controls[:, 1]
    assert np.all(alpha <= ocp.alpha_bounds_rad[1] + 1e-6)
    assert np.all(alpha >= ocp.alpha_bounds_rad[0] - 1e-6)
    assert np.all((beta >= ocp.beta_bounds_rad[0] - 1e-6) & (beta <= ocp.beta_bounds_rad[1]
                                                             + 1e-6))


@pytest.mark.slow
def test_peng2012_fuel_is_certified_within_half_a_percent_of_the_dense_optimum():
    ocp = PinpointOCP(get_scenario("peng2012"))
    res = SuccessiveConvexification(30).solve(ocp)
    cert = certify(res, ocp)
    assert cert.replay_success, cert.replay_message
    assert abs(cert.fuel_gap_pct) < 0.5


@pytest.mark.slow
def test_peng2012_throttled_engine_is_bang_bang_and_cheaper_than_constant_thrust():
    """With a throttle the relaxation stays tight (‖w‖ = Γ) and the optimum coasts first: a
    different problem, cheaper than the papers' constant-thrust optimum."""
    ocp = PinpointOCP(get_scenario("peng2012"))
    res = SuccessiveConvexification(30, engine="throttled").solve(ocp)
    assert res.success, res.message
    assert res.extra["tightness"] > 1.0 - 1e-6
    gam = res.controls[:, -1]
    assert np.all((gam < 0.05) | (gam > 0.999))     # bang-bang up to the switching interval
    cert = certify(res, ocp)
    assert cert.replay_success and cert.fuel_gap_pct < -1.0
