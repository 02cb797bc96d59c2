"""Node-angle + least-squares polynomial parameterisation ([000] §3, eq. 9–10)."""

import numpy as np
import pytest

from optimizers.parameterisations import NodePolynomial


@pytest.mark.parametrize("n_nodes,degree", [(10, 3), (10, 5), (4, 3), (7, 1)])
def test_fit_is_exact_for_a_polynomial_of_the_degree(n_nodes, degree):
    rng = np.random.default_rng(n_nodes * 10 + degree)
    p = NodePolynomial(n_nodes, degree)
    a = rng.normal(size=(5, degree + 1))
    s = p.node_fractions
    nodes = a @ (s[None, :] ** np.arange(degree + 1)[:, None])
    np.testing.assert_allclose(p.fit(nodes), a, atol=1e-10)


def test_least_squares_is_the_normal_equation_solution():
    rng = np.random.default_rng(1)
    p = NodePolynomial(10, 3)
    nodes = rng.uniform(0, 1.5, size=(8, 10))
    V = p.node_fractions[:, None] ** np.arange(4)[None, :]
    expect = np.linalg.solve(V.T @ V, V.T @ nodes.T).T
    np.testing.assert_allclose(p.fit(nodes), expect, atol=1e-12)


def test_control_evaluates_the_fit_in_time_with_full_throttle():
    p = NodePolynomial(10, 3)
    tf = np.array([0.5, 0.7])
    s = p.node_fractions
    nodes = np.stack([0.1 + 0.3 * s**3, 1.0 - s + 0.2 * s**2])  # exact cubics
    ctrl = p.control(nodes, 0.0, tf)
    t = p.node_times(0.0, tf)
    u = ctrl(t)
    np.testing.assert_allclose(u[..., 0], nodes, atol=1e-12)
    np.testing.assert_allclose(u[..., 1], 1.0)
    np.testing.assert_allclose(p.evaluate(nodes, s), nodes, atol=1e-12)


def test_bad_sizes_raise():
    with pytest.raises(ValueError, match="degree"):
        NodePolynomial(3, 3)
    with pytest.raises(ValueError, match="n_nodes"):
        NodePolynomial(1, 0)
    with pytest.raises(ValueError, match="n_nodes = 10"):
        NodePolynomial(10, 3).fit(np.zeros((2, 9)))
