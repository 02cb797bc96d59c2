"""Integrator contract: events located inside the step, input checks, control evaluation."""

import math

import numpy as np
import pytest

from lunar_env import dynamics as dyn
from lunar_env import get_scenario
from lunar_env.integrators import (
    MOON3D,
    PLANAR,
    STATUS_COMPLETED,
    STATUS_RADIUS,
    STATUS_SPEED_MIN,
    PiecewisePolynomial,
    RadiusCrossing,
    SpeedMinimum,
    integrate,
    integrate_reference,
)

SC = get_scenario("zhu2007")
S = SC.scaling()
P = SC.params()


def _braking_control(n=1, phi=0.0):
    return PiecewisePolynomial.constant(np.tile([phi, 1.0], (n, 1)), 0.0, 10.0)


def test_radius_event_located_to_a_millimetre():
    """Coast from 15 km with a downward push; touchdown located inside a 10 s step."""
    y0 = SC.state_nd().copy()
    y0[dyn.VR] = S.velocity_nd(-30.0)
    y0[dyn.OMEGA] *= 0.3
    rL = S.length_nd(SC.target.radius_m)
    dt = S.time_nd(10.0)
    ctrl = PiecewisePolynomial.constant(np.array([[0.0, 0.0]]), 0, 10)
    res = integrate(PLANAR, y0[None], t0_nd=0, dt_nd=dt, n_steps=200, control=ctrl, params=P,
                    events=(RadiusCrossing(rL),))
    assert res.status[0] == STATUS_RADIUS

    def hit(t, y):
        return y[0] - rL

    hit.terminal = True
    hit.direction = -1
    ref = integrate_reference(PLANAR, y0, (0, 200 * dt), lambda t: np.zeros(2), P, events=hit)
    y_ref = ref.y_events[0][0]
    assert abs(res.y_end[0, dyn.R] - rL) * S.length_m < 1e-3
    # located state agrees with the exact solution's event to 1 mm and 1 mm/s
    assert abs(res.t_end[0] - ref.t_events[0][0]) * S.time_s < 1e-3
    assert abs(res.y_end[0, dyn.VR] - y_ref[1]) * S.velocity_m_s < 1e-3
    assert abs(res.y_end[0, dyn.OMEGA] - y_ref[3]) * S.length_m * S.velocity_m_s / S.length_m \
        < 1e-3


def test_speed_minimum_event_is_the_zero_of_relative_speed():
    """Constant braking opposite the motion from a slow horizontal state: the relative speed
    passes through (near) zero; the event stops at its minimum, inside a 5 s step."""
    y0 = np.array([S.length_nd(1738.5e3), 0.0, 0.0, S.rate_nd(40.0 / 1738.5e3), 1.0])
    dt = S.time_nd(5.0)
    res = integrate(PLANAR, y0[None], t0_nd=0, dt_nd=dt, n_steps=20, params=P,
                    control=_braking_control(phi=math.radians(20.0)), events=(SpeedMinimum(),))
    assert res.status[0] == STATUS_SPEED_MIN
    y = res.y_end[0]

    def speed2(state):
        return state[1] ** 2 + (state[0] * state[3]) ** 2

    # the located time is a local minimum of the speed along the RK4 solution
    eps = S.time_nd(1e-3)
    ctrl = _braking_control(phi=math.radians(20.0))
    before = integrate(PLANAR, y0[None], t0_nd=0, dt_nd=(res.t_end[0] - eps) / 10, n_steps=10,
                       control=ctrl, params=P).y_end[0]
    after = integrate(PLANAR, y0[None], t0_nd=0, dt_nd=(res.t_end[0] + eps) / 10, n_steps=10,
                      control=ctrl, params=P).y_end[0]
    assert speed2(y) <= speed2(before) and speed2(y) <= speed2(after)
    # against the exact solution: speed minimum to 1 mm/s
    tt = np.linspace(0, 2 * res.t_end[0], 20001)
    ref = integrate_reference(PLANAR, y0, (0, tt[-1]), lambda t: np.array([math.radians(20), 1]),
                              P, t_eval=tt)
    vmin = np.sqrt(np.min(speed2(ref.y))) * S.velocity_m_s
    assert abs(math.sqrt(speed2(y)) * S.velocity_m_s - vmin) < 1e-3


def test_nominal_state_runs_all_steps_without_events():
    res = integrate(PLANAR, SC.state_nd()[None], t0_nd=0, dt_nd=1e-3, n_steps=10,
                    control=_braking_control(), params=P, events=(RadiusCrossing(0.5),))
    assert res.status[0] == STATUS_COMPLETED
    assert res.t_end[0] == pytest.approx(1e-2)


def test_events_per_trajectory_and_recording_fills_forward():
    n = 3
    y0 = np.tile(SC.state_nd(), (n, 1))
    y0[:, dyn.VR] = S.velocity_nd(np.array([-50.0, -100.0, 0.0]))
    rL = S.length_nd(1738e3)
    res = integrate(PLANAR, y0, t0_nd=0, dt_nd=S.time_nd(20.0), n_steps=30,
                    control=PiecewisePolynomial.constant(np.zeros((n, 2)), 0, 1), params=P,
                    events=(RadiusCrossing(np.full(n, rL)),), record=True)
    assert list(res.status[:2]) == [STATUS_RADIUS, STATUS_RADIUS]
    assert res.t_end[1] < res.t_end[0]
    k = res.n_records[1]
    assert k < 31
    np.testing.assert_array_equal(res.states[1, k - 1], res.y_end[1])
    np.testing.assert_array_equal(res.states[1, -1], res.y_end[1])
    assert res.times[1, k - 1] == res.t_end[1]


def test_fuel_exhaustion_in_3d():
    sc = get_scenario("peng2012")
    p = sc.params()
    s = sc.scaling()
    dry = s.mass_nd(sc.vehicle.dry_mass_kg)
    t_burn = (1 - dry) * p.exhaust_velocity_nd / p.thrust_nd
    ctrl = PiecewisePolynomial.constant(np.array([[0.0, math.pi, 1.0]]), 0, 10)
    res = integrate(MOON3D, sc.state_nd()[None], t0_nd=0, dt_nd=t_burn / 7.5, n_steps=10,
                    control=ctrl, params=p, dry_mass_nd=dry)
    assert res.t_burnout[0] == pytest.approx(t_burn, rel=1e-12)
    assert res.y_end[0, dyn.M3] == pytest.approx(dry, abs=1e-14)


def test_piecewise_polynomial_evaluation():
    breaks = np.array([[0.0, 1.0, 3.0]])
    coefs = np.zeros((1, 2, 2, 3))
    coefs[0, 0, 0] = [1.0, 2.0, 0.0]     # 1 + 2τ on [0, 1)
    coefs[0, 1, 0] = [3.0, 0.0, 1.0]     # 3 + τ² on [1, 3]
    coefs[0, :, 1, 0] = 1.0
    pp = PiecewisePolynomial(breaks, coefs)
    u = pp(np.array([[0.0, 0.5, 1.0, 2.0, 4.0]]))
    np.testing.assert_allclose(u[0, :, 0], [1.0, 2.0, 3.0, 4.0, 12.0])
    np.testing.assert_allclose(u[0, :, 1], 1.0)


@pytest.mark.parametrize("bad", [
    dict(y0_nd=np.array([[1.0, 0, 0, np.nan, 1.0]])),
    dict(dt_nd=-1.0),
    dict(n_steps=0),
    dict(y0_nd=np.ones((1, 4))),
])
def test_bad_input_is_rejected_with_a_clear_error(bad):
    kw = dict(y0_nd=SC.state_nd()[None], t0_nd=0.0, dt_nd=1e-3, n_steps=5,
              control=_braking_control(), params=P)
    kw.update(bad)
    y0 = kw.pop("y0_nd")
    with pytest.raises(ValueError):
        integrate(PLANAR, y0, **kw)


def test_control_batch_mismatch_rejected():
    with pytest.raises(ValueError, match="control"):
        integrate(PLANAR, np.tile(SC.state_nd(), (2, 1)), t0_nd=0, dt_nd=1e-3, n_steps=2,
                  control=_braking_control(3), params=P)
    with pytest.raises(TypeError, match="unknown event"):
        integrate(PLANAR, SC.state_nd()[None], t0_nd=0, dt_nd=1e-3, n_steps=2,
                  control=_braking_control(), params=P, events=("touchdown",))


def test_touchdown_found_when_the_radius_dips_below_and_back_within_one_step():
    """Regression: a lander braking to a stop 3 mm under the
    surface and climbing back within one step crosses the surface twice; the step's end points
    are both above it. The touchdown must still be located (the first crossing)."""
    rL = S.length_nd(SC.target.radius_m)
    y0 = np.array([rL + S.length_nd(0.5), S.velocity_nd(-2.0), 0.0, 0.0, 0.6])
    up = np.array([[math.pi / 2, 1.0]])  # ~3.8 m/s² net upward: v = 0 after ~0.5 s
    ctrl = PiecewisePolynomial.constant(up, 0.0, 10.0)
    dt = S.time_nd(3.0)
    end = integrate(PLANAR, y0[None], t0_nd=0, dt_nd=dt, n_steps=1, control=ctrl, params=P)
    assert end.y_end[0, dyn.R] > rL  # the dip is invisible at the step's end points
    res = integrate(PLANAR, y0[None], t0_nd=0, dt_nd=dt, n_steps=1, control=ctrl, params=P,
                    events=(RadiusCrossing(rL), SpeedMinimum()))
    assert res.status[0] == STATUS_RADIUS
    assert abs(res.y_end[0, dyn.R] - rL) * S.length_m < 1e-3
    assert res.y_end[0, dyn.VR] < 0
    # no dip below the stop radius: nothing fires, as before
    high = integrate(PLANAR, (y0 + [S.length_nd(5.0), 0, 0, 0, 0])[None], t0_nd=0, dt_nd=dt,
                     n_steps=1, control=ctrl, params=P, events=(RadiusCrossing(rL),))
    assert high.status[0] == STATUS_COMPLETED


def test_read_only_inputs_do_not_compile_another_kernel():
    """Bug fixed: a read-only input (one trajectory's broadcast view, a user's frozen
    array) made numba compile a separate specialisation of the RK4 kernel (~10 s each on a
    fresh machine, seven of them in the default test run). ``integrate`` hands the kernel
    writable copies: read-only and writable inputs give the same result and no new
    signature."""
    y0 = SC.state_nd().copy()[None]
    ctrl = _braking_control()
    dt = S.time_nd(1.0)
    kw = dict(t0_nd=0.0, dt_nd=dt, n_steps=3, control=ctrl, params=P)
    writable = integrate(PLANAR, y0, **kw)
    kernel = PLANAR.kernel(False)
    n_signatures = len(kernel.signatures)
    frozen = y0.copy()
    frozen.setflags(write=False)
    rows = np.broadcast_to(P.as_array(), (1, P.as_array().size))   # read-only views
    read_only = integrate(PLANAR, frozen,
                          **(kw | {"t0_nd": np.broadcast_to(0.0, (1,)), "params": rows}))
    assert len(kernel.signatures) == n_signatures
    np.testing.assert_array_equal(read_only.y_end, writable.y_end)
