"""Physics invariants and cross-model checks of the equations of motion."""

import math

import casadi
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lunar_env import dynamics as dyn
from lunar_env import get_scenario
from lunar_env.integrators import (
    MOON3D,
    PLANAR,
    PiecewisePolynomial,
    integrate,
    integrate_reference,
)


def _coast(n, n_control):
    """Engine-off control for a batch of n."""
    return PiecewisePolynomial.constant(np.zeros((n, n_control)), 0.0, 1e9)


def test_planar_energy_and_angular_momentum_conserved_over_one_orbit():
    # the zhu2007 start (slightly elliptic: ω0·r0 exceeds circular speed)
    y0 = get_scenario("zhu2007").state_nd()[None, :]
    e0, h0 = dyn.planar_energy(y0), dyn.planar_angular_momentum(y0)
    a = -0.5 / e0[0]
    period = 2 * math.pi * a**1.5
    n = 4000
    res = integrate(PLANAR, y0, t0_nd=0.0, dt_nd=period / n, n_steps=n,
                    control=_coast(1, 2), params=dyn.PlanarParams(0.0, 1.0), record=True)
    e = dyn.planar_energy(res.states[0])
    h = dyn.planar_angular_momentum(res.states[0])
    assert np.max(np.abs(e / e0 - 1)) < 1e-10
    assert np.max(np.abs(h / h0 - 1)) < 1e-10
    # and the orbit closes
    assert res.y_end[0, dyn.THETA] == pytest.approx(2 * math.pi, abs=1e-8)


def test_moon3d_jacobi_integral_conserved_over_one_orbit():
    sc = get_scenario("peng2012")
    p = sc.params()
    p = dyn.Moon3DParams(0.0, p.exhaust_velocity_nd, 50 * p.spin_rate_nd, p.plane_normal)
    y0 = sc.state_nd()[None, :]
    c0 = dyn.moon3d_jacobi(y0, p.spin_rate_nd)
    n = 6000
    res = integrate(MOON3D, y0, t0_nd=0.0, dt_nd=2 * math.pi / n, n_steps=n,
                    control=_coast(1, 3), params=p, record=True)
    c = dyn.moon3d_jacobi(res.states[0], p.spin_rate_nd)
    assert np.max(np.abs(c / c0 - 1)) < 1e-10


def test_mass_follows_rocket_equation_and_burn_ends_at_dry_mass():
    sc = get_scenario("zhu2007")
    p = sc.params()
    s = sc.scaling()
    y0 = sc.state_nd()[None, :]
    dry = s.mass_nd(sc.vehicle.dry_mass_kg)
    t_burn = (1.0 - dry) * p.exhaust_velocity_nd / p.thrust_nd
    n = 400
    res = integrate(PLANAR, y0, t0_nd=0.0, dt_nd=1.5 * t_burn / n, n_steps=n,
                    control=PiecewisePolynomial.constant(np.array([[math.pi / 2, 1.0]]), 0, 9),
                    params=p, dry_mass_nd=dry, record=True)
    t = res.times[0]
    m = res.states[0, :, dyn.M]
    burning = t < t_burn
    np.testing.assert_allclose(m[burning], 1.0 - p.thrust_nd / p.exhaust_velocity_nd * t[burning],
                               rtol=0, atol=1e-14)
    assert res.t_burnout[0] == pytest.approx(t_burn, abs=1e-12)
    np.testing.assert_allclose(m[~burning], dry, atol=1e-14)
    # Tsiolkovsky in SI: fuel = m0 (1 - exp(-Δv/c)) with Δv = ∫F/m dt
    tt = np.linspace(0, t_burn, 20001)
    dv = np.trapezoid(p.thrust_nd / (1.0 - p.thrust_nd / p.exhaust_velocity_nd * tt), tt)
    propellant_fraction = 1.0 - dry
    assert propellant_fraction == pytest.approx(1.0 - math.exp(-dv / p.exhaust_velocity_nd),
                                                rel=1e-8)


def test_moon3d_without_rotation_matches_planar_model():
    """Ω = 0, equatorial plane, in-plane thrust (β = 180°, α = φ): identical to the planar model."""
    sc = get_scenario("zhu2007")
    pp = sc.params()
    y0p = sc.state_nd()
    r0, vr0, om0, m0 = y0p[dyn.R], y0p[dyn.VR], y0p[dyn.OMEGA], y0p[dyn.M]
    y0c = np.array([[r0, 0.0, 0.0, vr0, r0 * om0, 0.0, m0]])
    p3 = dyn.Moon3DParams(pp.thrust_nd, pp.exhaust_velocity_nd, 0.0, (0.0, 0.0, 1.0))
    tf = sc.scaling().time_nd(600.0)
    n = 600
    # a cubic thrust-angle law, like paper 000
    cphi = np.array([0.05, 0.3, 0.8, -0.2])
    coef_p = np.zeros((1, 2, 4))
    coef_p[0, 0] = cphi
    coef_p[0, 1, 0] = 1.0
    coef_3 = np.zeros((1, 3, 4))
    coef_3[0, 0] = cphi
    coef_3[0, 1, 0] = math.pi
    coef_3[0, 2, 0] = 1.0
    rp = integrate(PLANAR, y0p[None], t0_nd=0, dt_nd=tf / n, n_steps=n, params=pp,
                   control=PiecewisePolynomial.polynomial(coef_p, 0, tf), record=True)
    r3 = integrate(MOON3D, y0c, t0_nd=0, dt_nd=tf / n, n_steps=n, params=p3,
                   control=PiecewisePolynomial.polynomial(coef_3, 0, tf), record=True)
    d = dyn.moon3d_derived(r3.states[0], p3)
    sp = rp.states[0]
    np.testing.assert_allclose(d["radius_nd"], sp[:, dyn.R], rtol=0, atol=1e-9)
    np.testing.assert_allclose(d["u_nd"], sp[:, dyn.VR], rtol=0, atol=1e-9)
    np.testing.assert_allclose(d["v_nd"], sp[:, dyn.R] * sp[:, dyn.OMEGA], rtol=0, atol=1e-9)
    np.testing.assert_allclose(d["longitude_rad"], sp[:, dyn.THETA], rtol=0, atol=1e-9)
    np.testing.assert_allclose(d["w_nd"], 0.0, atol=1e-12)
    np.testing.assert_allclose(r3.states[0, :, dyn.M3], sp[:, dyn.M], atol=1e-13)


def test_moon3d_rhs_equals_vector_form():
    """Independent check of the Cartesian model against dV/dt = F/m − r/|r|³ − 2Ω×V − Ω×(Ω×r)."""
    rng = np.random.default_rng(3)
    sc = get_scenario("peng2012")
    p = sc.params()
    for _ in range(20):
        r = rng.normal(size=3)
        r *= rng.uniform(1.0, 1.2) / np.linalg.norm(r)
        v = rng.normal(scale=0.5, size=3)
        m = rng.uniform(0.5, 1.0)
        alpha, beta, thr = rng.uniform(-1, 1), rng.uniform(2, 4), rng.uniform(0, 1)
        y = np.concatenate([r, v, [m]])
        d = dyn.moon3d_rhs(y[None], np.array([[alpha, beta, thr]]), p)[0]
        x_hat = r / np.linalg.norm(r)
        n = np.array(p.plane_normal)
        y_hat = np.cross(n, x_hat)
        y_hat /= np.linalg.norm(y_hat)
        z_hat = np.cross(x_hat, y_hat)
        e = (math.sin(alpha) * x_hat + math.cos(alpha) * math.cos(beta) * y_hat
             + math.cos(alpha) * math.sin(beta) * z_hat)
        om = np.array([0, 0, p.spin_rate_nd])
        a = (p.thrust_nd * thr / m * e - r / np.linalg.norm(r) ** 3 - 2 * np.cross(om, v)
             - np.cross(om, np.cross(om, r)))
        np.testing.assert_allclose(d[:3], v, rtol=1e-14)
        np.testing.assert_allclose(d[3:6], a, rtol=1e-12, atol=1e-14)
        assert d[6] == pytest.approx(-p.thrust_nd * thr / p.exhaust_velocity_nd, rel=1e-14)


def test_casadi_evaluates_the_same_equations():
    sc = get_scenario("zhu2007")
    p = sc.params()
    x = casadi.SX.sym("x", 5)
    u = casadi.SX.sym("u", 2)
    f = casadi.Function("f", [x, u], [dyn.planar_rhs_casadi(x, u, p)])
    y = np.array([1.01, -0.002, 0.3, 0.99, 0.8])
    c = np.array([0.4, 1.0])
    np.testing.assert_allclose(np.array(f(y, c)).ravel(), dyn.planar_rhs(y[None], c[None], p)[0],
                               rtol=1e-15)
    s3 = get_scenario("peng2012")
    p3 = s3.params()
    x3 = casadi.SX.sym("x", 7)
    u3 = casadi.SX.sym("u", 3)
    f3 = casadi.Function("f3", [x3, u3], [dyn.moon3d_rhs_casadi(x3, u3, p3)])
    y3 = s3.state_nd()
    c3 = np.array([0.2, 3.0, 1.0])
    np.testing.assert_allclose(np.array(f3(y3, c3)).ravel(),
                               dyn.moon3d_rhs(y3[None], c3[None], p3)[0], rtol=1e-14)
    # exact derivatives come for free (what collocation and costate equations use)
    jac = casadi.Function("j", [x, u], [casadi.jacobian(dyn.planar_rhs_casadi(x, u, p), x)])
    J = np.array(jac(y, c))
    h = 1e-7
    fd = np.stack([(dyn.planar_rhs((y + h * e)[None], c[None], p)[0]
                    - dyn.planar_rhs((y - h * e)[None], c[None], p)[0]) / (2 * h)
                   for e in np.eye(5)], axis=1)
    np.testing.assert_allclose(J, fd, atol=1e-7)


def _cubic_descent_and_reference():
    """zhu2007 start, a cubic thrust-angle law over 600 s, and the DOP853 reference end state."""
    sc = get_scenario("zhu2007")
    p = sc.params()
    tf = sc.scaling().time_nd(600.0)
    coef = np.zeros((1, 2, 4))
    coef[0, 0] = [0.05, 0.3, 0.8, -0.2]
    coef[0, 1, 0] = 1.0
    ctrl = PiecewisePolynomial.polynomial(coef, 0, tf)
    y0 = sc.state_nd()
    ref = integrate_reference(PLANAR, y0, (0.0, tf), lambda t: ctrl(np.array([[t]]))[0, 0], p)
    return y0, ctrl, p, tf, ref.y[:, -1]


def test_rk4_matches_reference_integrator():
    y0, ctrl, p, tf, y_ref = _cubic_descent_and_reference()
    res = integrate(PLANAR, y0[None], t0_nd=0, dt_nd=tf / 1200, n_steps=1200, control=ctrl,
                    params=p)
    np.testing.assert_allclose(res.y_end[0], y_ref, rtol=0, atol=1e-11)


def test_rk4_observed_order_is_four():
    y0, ctrl, p, tf, y_ref = _cubic_descent_and_reference()
    errs = []
    for n in (10, 20, 40, 80):
        res = integrate(PLANAR, y0[None], t0_nd=0, dt_nd=tf / n, n_steps=n, control=ctrl,
                        params=p)
        errs.append(np.max(np.abs(res.y_end[0] - y_ref)))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(orders - 4.0) < 0.2), orders


def _random_planar_batch(rng, n):
    y = np.stack([rng.uniform(1.0, 1.02, n), rng.uniform(-0.02, 0.02, n),
                  rng.uniform(-1, 1, n), rng.uniform(0.5, 1.05, n), rng.uniform(0.6, 1.0, n)], 1)
    coef = np.zeros((n, 2, 4))
    coef[:, 0] = rng.uniform(-0.5, 0.5, (n, 4))
    coef[:, 1, 0] = rng.uniform(0.0, 1.0, n)
    return y, coef


def test_batch_is_bit_identical_to_single_trajectories():
    rng = np.random.default_rng(0)
    n = 100
    y, coef = _random_planar_batch(rng, n)
    p = get_scenario("zhu2007").params()
    dt = rng.uniform(1e-3, 2e-3, n)
    kw = dict(t0_nd=0.0, n_steps=300, params=p, dry_mass_nd=0.5)
    batch = integrate(PLANAR, y, dt_nd=dt, control=PiecewisePolynomial.polynomial(coef, 0, 1),
                      parallel=True, **kw)
    for i in range(0, n, 7):
        single = integrate(PLANAR, y[i:i + 1], dt_nd=dt[i:i + 1], parallel=False,
                           control=PiecewisePolynomial.polynomial(coef[i:i + 1], 0, 1), **kw)
        assert np.array_equal(single.y_end[0], batch.y_end[i])
        assert single.t_end[0] == batch.t_end[i]


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 12))
def test_property_rhs_finite_and_batch_invariant(seed, n):
    rng = np.random.default_rng(seed)
    y, coef = _random_planar_batch(rng, n)
    u = np.stack([rng.uniform(-np.pi, np.pi, n), rng.uniform(0, 1, n)], 1)
    p = get_scenario("zhu2007").params()
    d = dyn.planar_rhs(y, u, p)
    assert np.all(np.isfinite(d))
    for i in range(n):
        np.testing.assert_array_equal(dyn.planar_rhs(y[i:i + 1], u[i:i + 1], p)[0], d[i])
    s3 = get_scenario("peng2012")
    p3 = s3.params()
    y3 = np.tile(s3.state_nd(), (n, 1))
    y3[:, :3] *= rng.uniform(0.99, 1.01, (n, 1))
    y3[:, 3:6] += rng.normal(scale=0.1, size=(n, 3))
    u3 = np.stack([rng.uniform(-1, 1, n), rng.uniform(0, 2 * np.pi, n), rng.uniform(0, 1, n)], 1)
    d3 = dyn.moon3d_rhs(y3, u3, p3)
    assert np.all(np.isfinite(d3))
    for i in range(n):
        np.testing.assert_array_equal(dyn.moon3d_rhs(y3[i:i + 1], u3[i:i + 1], p3)[0], d3[i])


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_property_integration_finite_and_batch_invariant(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 40))
    y, coef = _random_planar_batch(rng, n)
    p = get_scenario("zhu2007").params()
    kw = dict(t0_nd=0.0, dt_nd=2e-3, n_steps=50, params=p, dry_mass_nd=0.5)
    res = integrate(PLANAR, y, control=PiecewisePolynomial.polynomial(coef, 0, 1), **kw)
    assert np.all(np.isfinite(res.y_end))
    i = int(rng.integers(n))
    one = integrate(PLANAR, y[i:i + 1], control=PiecewisePolynomial.polynomial(coef[i:i + 1], 0,
                                                                               1), **kw)
    np.testing.assert_array_equal(one.y_end[0], res.y_end[i])
