"""The pinpoint optimal feedback (optimizers.indirect.pinpoint_feedback): its state–costate
right-hand side against CasADi's automatic derivative of the shared model, its extremal
against the certified backward Pontryagin solution, and its closed loop in the env."""

from __future__ import annotations

import numpy as np
import pytest

from lunar_env import get_scenario
from optimizers.indirect import pinpoint_feedback as pf

SC = get_scenario("peng2012")
K = pf.feedback_constants(SC)


@pytest.fixture(scope="module")
def feedback():
    fb = pf.PinpointFeedback(SC)
    fb.nominal_costates()
    return fb


def _casadi_rhs():
    from optimizers.common.casadi_tools import casadi
    from optimizers.indirect.pinpoint import _optimal_control
    from optimizers.problems.pinpoint import PinpointOCP

    ca = casadi()
    ocp = PinpointOCP(SC)
    x = ca.SX.sym("x", 7)
    lam = ca.SX.sym("lam", 7)
    u = ca.SX.sym("u", 2)
    f = ocp.rhs(x, u)
    dlam = -ca.jacobian(ca.dot(lam, f), x).T
    ustar = _optimal_control(ocp, x, lam[3:6])
    return ca.Function("F", [x, lam], [ca.vertcat(ca.substitute(f, u, ustar),
                                                  ca.substitute(dlam, u, ustar)), ustar])


def test_state_costate_rhs_equals_casadi_derivative_of_the_shared_model():
    """λ' = −∂H/∂x by hand (gravity gradient, Coriolis, centrifugal, frame term on box arcs)
    equals CasADi's AD of lunar_env.dynamics; interior and box-constrained controls."""
    F = _casadi_rhs()
    rng = np.random.default_rng(3)
    x0 = SC.state_nd(scaling=SC.scaling())
    n_clipped = 0
    for _ in range(40):
        x = x0 + np.r_[rng.normal(0, 3e-3, 3), rng.normal(0, 0.05, 3), rng.normal(0, 0.02, 1)]
        lam = np.r_[rng.normal(0, 10, 3), rng.normal(0, 1, 3)]
        y = np.r_[x, lam]
        out = np.empty(13)
        pf._rhs(y, K.c, out)
        ref, u = (np.asarray(v).ravel() for v in F(x, np.r_[lam, 0.0]))
        a, b, clipped = pf._angles(y, K.c)
        n_clipped += bool(clipped)
        np.testing.assert_allclose([a, b], u, atol=1e-12)
        np.testing.assert_allclose(out[:7], ref[:7], rtol=1e-12, atol=1e-12)
        # the frame term is a central difference (step 1e-6): ~1e-9 relative
        np.testing.assert_allclose(out[7:13], ref[7:13], rtol=1e-7, atol=1e-7 * np.abs(ref).max())
    assert 5 < n_clipped < 40  # both kinds of arcs were checked


def test_forward_extremal_matches_the_certified_backward_solution(feedback):
    """The nominal extremal from the start (numba, forward) = the certified Pontryagin optimum
    (CasADi, backward from the target, 2000 RK4 steps; README: tf 553.3419 s)."""
    from optimizers.indirect.pinpoint import solve_pinpoint_min_time
    from optimizers.problems.pinpoint import PinpointOCP
    from optimizers.transcription.serial import solve_serial

    ocp = PinpointOCP(SC)
    ref = solve_pinpoint_min_time(ocp, solve_serial(ocp))
    assert ref.success
    z = feedback.nominal_costates()
    sol = pf.solve_extremal(K, ocp.x0_nd, z, step_s=1.0)
    assert sol.converged
    assert abs(sol.tgo_s - ref.tf_s) < 2e-3
    # same control law along the path (the costate direction is scale-free)
    ts, path = pf.extremal_path(K, ocp.x0_nd, sol.z, step_s=1.0)
    ang = pf.optimal_angles(K, path)
    assert np.degrees(ang[0, 0]) == pytest.approx(-50.0)  # the dive starts on the α bound
    mid = ang[len(ang) // 2]
    assert 20.0 < np.degrees(mid[0]) < 23.0 and 179.0 < np.degrees(mid[1]) < 183.0
    # the extremal lands: terminal position and velocity
    end = path[-1]
    tgt = SC.scaling().length_nd(SC.target_position_m())
    assert np.linalg.norm(end[:3] - tgt) * K.length_m < 0.01
    assert np.linalg.norm(end[3:6]) * K.velocity_m_s < 1e-4


def test_feedback_law_lands_in_the_env_at_the_extremal_fuel(feedback):
    """Closed loop in LunarPinpointLanding-v2 at 1 s decisions: gate speed < 0.2 m/s, miss
    < 1 m, fuel = ṁ·tgo of the extremal from the drawn start (to 0.05 kg)."""
    import gymnasium as gym

    import lunar_env  # noqa: F401
    from lunar_env.envs.pinpoint_landing import action_from_angles

    env = gym.make("LunarPinpointLanding-v2")
    core = env.unwrapped
    env.reset(seed=11)
    x0 = core.state_nd
    tgo0 = feedback.solve(x0).tgo_s
    feedback.reset()
    done = False
    info = {}
    while not done:
        ang = feedback(core.state_nd[None], [core.t_s], core.dt_s)
        a = action_from_angles(ang[:, 0], ang[:, 1], SC.alpha_bounds_rad, SC.beta_bounds_rad)
        _, _, term, trunc, info = env.step(a[0].astype(np.float32))
        done = term or trunc
    assert info["is_success"]
    assert info["touchdown_speed_m_s"] < 0.2 and info["miss_distance_m"] < 1.0
    mdot = SC.vehicle.mass_flow_kg_s
    assert info["fuel_used_kg"] == pytest.approx(mdot * tgo0, abs=0.05)


def test_memory_follows_the_episode_clock(feedback):
    x0 = SC.state_nd(scaling=SC.scaling())
    feedback.reset()
    feedback(x0[None], [0.0], 1.0)
    assert feedback.last_status == ["optimal"] and 0 in feedback._memory
    # a clock that goes back is a new episode: the memory is replaced, not reused
    feedback(x0[None], [-5.0], 1.0)
    assert feedback._memory[0][1] == -5.0
    # inactive rows get the braking fallback and keep their memory
    feedback(x0[None], [0.0], 1.0, active=[False])
    assert feedback.last_status == ["fallback"] and 0 in feedback._memory


@pytest.mark.parametrize("bad", [np.full(7, np.nan), np.zeros(6)])
def test_bad_states_are_refused(feedback, bad):
    with pytest.raises(ValueError, match="states_nd"):
        feedback(bad[None], [0.0], 1.0)


def test_bad_guess_is_refused():
    x0 = SC.state_nd(scaling=SC.scaling())
    with pytest.raises(ValueError, match="guess"):
        pf.solve_extremal(K, x0, np.r_[np.zeros(6), 0.5])


def test_the_stop_flown_to_is_reported_beyond_or_on_the_target():
    # the reserve law picks its engine by the side its extremal misses on
    import dataclasses

    import gymnasium as gym

    import lunar_env  # noqa: F401

    sc = gym.make("LunarPinpointLanding-v2").unwrapped.scenario
    x0 = sc.state_nd(scaling=sc.scaling())
    full = pf.PinpointFeedback(sc)
    full(x0[None], [0.0], 2.0)
    assert full.last_status == ["optimal"] and abs(full.last_beyond_m[0]) < pf.TARGET_REACHED_M
    weak = dataclasses.replace(sc, vehicle=dataclasses.replace(
        sc.vehicle, thrust_n=0.93 * sc.vehicle.thrust_n))
    fb = pf.PinpointFeedback(weak, nominal_guess=full.nominal_costates())
    fb(x0[None], [0.0], 2.0)
    # measured: 93 % of the thrust stops ~1.5 km beyond the target from the nominal start
    assert fb.last_status == ["nearest"] and 1000.0 < fb.last_beyond_m[0] < 2500.0
    fb(x0[None], [2.0], 2.0, active=[False])
    assert fb.last_status == ["fallback"] and np.isnan(fb.last_beyond_m[0])


def test_a_row_with_a_thrust_scale_flies_the_extremal_of_that_engine():
    # the reserve law plans its full engine with the thrust it estimated it has
    import dataclasses

    import gymnasium as gym

    import lunar_env  # noqa: F401

    sc = gym.make("LunarPinpointLanding-v2").unwrapped.scenario
    x0 = sc.state_nd(scaling=sc.scaling())
    strong = dataclasses.replace(sc, vehicle=dataclasses.replace(
        sc.vehicle, thrust_n=1.03 * sc.vehicle.thrust_n))
    alone = pf.PinpointFeedback(strong)
    ang_alone = alone(x0[None], [0.0], 2.0)
    fb = pf.PinpointFeedback(sc)
    nominal = fb(x0[None], [0.0], 2.0).copy()
    fb.reset()
    both = fb(np.stack([x0, x0]), [0.0, 0.0], 2.0, thrust_scale=[1.03, 1.0])
    np.testing.assert_allclose(both[0], ang_alone[0], atol=1e-9)
    np.testing.assert_allclose(both[1], nominal[0], atol=1e-9)
    np.testing.assert_allclose(fb.last_tgo_s[0], alone.last_tgo_s[0], rtol=1e-9)
    assert fb.last_tgo_s[0] < fb.last_tgo_s[1]  # the stronger engine stops sooner
    assert fb.k is fb._k_scenario  # the scenario's engine again after the call
    for bad in (0.0, -1.0, np.nan):
        with pytest.raises(ValueError, match="thrust_scale"):
            fb(x0[None], [4.0], 2.0, thrust_scale=bad)


def test_a_guess_whose_newton_iterate_divides_by_zero_is_not_converged():
    # a DAgger roll-out's state and warm start (a student's
    # flight, the window law's thrust estimate) whose Newton iterate overflows its
    # integration, where the compiled kernel raised ZeroDivisionError and ended the run
    from optimizers.indirect.pinpoint_feedback import FeedbackConstants, solve_extremal

    c = np.array([1.5191126357915623, 1.7504512194307813, 0.0027543020090812875,
                  0.08682408883346514, -0.49240387650610395, 0.8660254037844388,
                  -0.8726646259971648, 0.6981317007977318, 2.2689280275926285,
                  3.839724354387525, 0.8951496342466803, 0.417415129643873, 0.1564344650402309,
                  -0.4385339088218182, 0.7616623890575763, 0.47703083328917273,
                  1.0011576524741082])
    k = FeedbackConstants(c=c, time_s=1034.7905508063598, length_m=1738000.0,
                          velocity_m_s=1679.56694100624, mass_kg=600.0, dry_mass_nd=0.5)
    x0 = [0.9029411024732739, 0.40757992167332685, 0.1487157367476927, -0.14722938019125065,
          0.22624590675087994, 0.1366194629131431, 0.6490404436097998]
    guess = [-6.212224434707565, 4.092887672956114, 1.8903990215221564, -0.8082251676057562,
             0.5274987843259835, 0.26175773337813163, 0.13570308187103153]
    sol = solve_extremal(k, np.array(x0), np.array(guess))
    assert not sol.converged and sol.residual == float("inf")


def test_the_natural_stop_comes_no_later_than_the_target_and_is_refused_bad_input(feedback):
    # minimum time over a free stop point is at most the minimum time to the target itself
    x0 = SC.state_nd(scaling=SC.scaling())
    free = feedback.natural_stop(x0)
    to_target = pf.solve_extremal(feedback.k, x0, feedback.nominal_costates())
    assert free is not None and free.converged and to_target.converged
    assert free.tgo_s <= to_target.tgo_s + 1e-6
    # a weaker engine brakes less per second: its natural stop lies further along the track
    assert feedback.natural_stop(x0, 0.95).beyond_m > free.beyond_m
    with pytest.raises(ValueError, match="thrust_scale"):
        feedback.natural_stop(x0, 0.0)
    with pytest.raises(ValueError, match="state_nd"):
        feedback.natural_stop(np.full(7, np.nan))
