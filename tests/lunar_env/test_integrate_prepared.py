"""The lean fast path integrate_prepared gives exactly what integrate gives."""

import numpy as np
import pytest

from lunar_env import get_scenario
from lunar_env import integrators as integ


@pytest.mark.parametrize("name", ["zhu2007", "peng2012"])
def test_integrate_prepared_equals_integrate(name):
    sc = get_scenario(name)
    s = sc.scaling()
    params = sc.params(s)
    model = integ.PLANAR if sc.model == "planar" else integ.MOON3D
    rng = np.random.default_rng(0)
    y0 = np.repeat(sc.state_nd()[None], 40, axis=0)
    y0[:, -1] *= rng.uniform(0.52, 1.0, 40)  # some burn out inside the interval
    u = rng.uniform(-1.0, 1.0, (40, model.n_control))
    u[:, -1] = 1.0
    t0 = rng.uniform(0.0, 0.1, 40)
    t1 = t0 + s.time_nd(300.0)
    r_stop = float(s.length_nd(sc.body.radius_m + 3000.0))
    ctrl = integ.PiecewisePolynomial.constant(u, t0, t1)
    h = (t1 - t0) / 300
    dry = float(s.mass_nd(sc.vehicle.dry_mass_kg))
    ref = integ.integrate(model, y0, t0_nd=t0, dt_nd=h, n_steps=300, control=ctrl, params=params,
                          dry_mass_nd=dry,
                          events=(integ.RadiusCrossing(r_stop), integ.SpeedMinimum()))
    for parallel in (False, True):
        y, t, st, tb = integ.integrate_prepared(
            model, y0, t0, h, 300, ctrl.breaks, ctrl.coefs, integ.params_rows(params, len(y0)), dry,
            np.full(40, r_stop), True, parallel)
        np.testing.assert_array_equal(y, ref.y_end)
        np.testing.assert_array_equal(t, ref.t_end)
        np.testing.assert_array_equal(st, ref.status)
        np.testing.assert_array_equal(tb, ref.t_burnout)
        # into the caller's arrays (stale contents must not leak into the results)
        out = (np.full_like(y0, np.nan), np.full(40, -1.0), np.full(40, 7, dtype=np.int64),
               np.zeros(40))
        got = integ.integrate_prepared(
            model, y0, t0, h, 300, ctrl.breaks, ctrl.coefs, integ.params_rows(params, len(y0)), dry,
            np.full(40, r_stop), True, parallel, out=out)
        assert all(g is o for g, o in zip(got, out, strict=True))
        for g, r in zip(got, (ref.y_end, ref.t_end, ref.status, ref.t_burnout), strict=True):
            np.testing.assert_array_equal(g, r)
    assert len(set(ref.status.tolist())) >= 2  # the batch exercises events, not just the grid


@pytest.mark.parametrize("name", ["zhu2007", "peng2012"])
def test_piecewise_constant_on_the_grid_is_a_zero_order_hold(name):
    """One integrate call over a piecewise-constant control with breaks on the RK4 grid gives
    the same states as integrating one held segment at a time (as an env does), including
    across a control jump that turns a decreasing speed into an increasing one (no event)."""
    sc = get_scenario(name)
    s = sc.scaling()
    params = sc.params(s)
    model = integ.PLANAR if sc.model == "planar" else integ.MOON3D
    rng = np.random.default_rng(1)
    n_seg, sub = 30, 4
    dt = float(s.time_nd(1.0))
    u = rng.uniform(-1.0, 1.0, (n_seg, model.n_control))
    u[:, -1] = 1.0
    breaks = (np.arange(n_seg + 1) * dt)[None]
    whole = integ.integrate(model, sc.state_nd()[None], t0_nd=0.0, dt_nd=dt / sub,
                            n_steps=n_seg * sub,
                            control=integ.PiecewisePolynomial(breaks, u[None, :, :, None]),
                            params=params, dry_mass_nd=0.5, events=(integ.SpeedMinimum(),),
                            record=True)
    y = sc.state_nd()[None]
    for k in range(n_seg):
        ctl = integ.PiecewisePolynomial.constant(u[k][None], k * dt, (k + 1) * dt)
        step = integ.integrate(model, y, t0_nd=k * dt, dt_nd=dt / sub, n_steps=sub, control=ctl,
                               params=params, dry_mass_nd=0.5, events=(integ.SpeedMinimum(),))
        if step.status[0] != integ.STATUS_COMPLETED:
            assert whole.status[0] == step.status[0]
            np.testing.assert_allclose(whole.y_end, step.y_end, rtol=0, atol=1e-12)
            return
        y = step.y_end
        np.testing.assert_allclose(whole.states[0, sub * (k + 1)], y[0], rtol=0, atol=1e-12)
    assert whole.status[0] == integ.STATUS_COMPLETED
