"""CasADi pieces shared by the transcriptions and the indirect solvers.

- :func:`casadi`: the module, with NumPy mode on (``casadi.GlobalOptions.setNumpyMode(1)``, as
  DESIGN.md asks, so the shared right-hand sides of :mod:`lunar_env.dynamics` evaluate on
  symbols without notices).
- :func:`rk4_step`: the one classical RK4 step builder (state–costate systems, shooting
  segments), as a ``casadi.Function``.
- :func:`ipopt_options`: ``nlpsol`` options for IPOPT (silent unless asked, exact Hessian).
- :func:`nlp_counts`: objective evaluations and iterations of a solved ``nlpsol``, the two
  counters every :class:`~optimizers.common.result.OptimResult` reports.
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["casadi", "rk4_step", "ipopt_options", "nlp_counts"]


def casadi():
    """The ``casadi`` module with NumPy mode on (imported lazily: CasADi is heavy)."""
    import casadi as ca

    try:
        ca.GlobalOptions.setNumpyMode(1)
    except AttributeError:  # CasADi < 3.7 has no numpy mode and needs none
        pass
    return ca


def rk4_step(rhs: Callable, n_state: int, n_control: int = 0, *, name: str = "rk4_step",
             control_slope: bool = False):
    """One classical RK4 step as a ``casadi.Function`` built on SX symbols.

    Parameters
    ----------
    rhs : callable
        ``rhs(x)`` (``n_control = 0``) or ``rhs(x, u)``, returning the derivative (n_state,) on
        CasADi symbols (e.g. a shared right-hand side of :mod:`lunar_env.dynamics`).
    n_state, n_control : int
    name : str
    control_slope : bool
        False: the control is held over the step, signature ``(x, h)`` or ``(x, u, h)``.
        True: the control is linear in time inside the step, ``u(τ) = u_a + slope·τ``,
        signature ``(x, u_a, slope, tau0, h)`` with τ the time since the segment start.

    Returns
    -------
    casadi.Function
        ``x + h/6 (k1 + 2 k2 + 2 k3 + k4)``.
    """
    ca = casadi()
    x = ca.SX.sym("x", n_state)
    h = ca.SX.sym("h")
    if n_control == 0:
        k1 = rhs(x)
        k2 = rhs(x + h / 2 * k1)
        k3 = rhs(x + h / 2 * k2)
        k4 = rhs(x + h * k3)
        return ca.Function(name, [x, h], [x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])
    u = ca.SX.sym("u", n_control)
    if not control_slope:
        k1 = rhs(x, u)
        k2 = rhs(x + h / 2 * k1, u)
        k3 = rhs(x + h / 2 * k2, u)
        k4 = rhs(x + h * k3, u)
        return ca.Function(name, [x, u, h], [x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])
    slope = ca.SX.sym("slope", n_control)
    tau0 = ca.SX.sym("tau0")
    k1 = rhs(x, u + slope * tau0)
    k2 = rhs(x + h / 2 * k1, u + slope * (tau0 + h / 2))
    k3 = rhs(x + h / 2 * k2, u + slope * (tau0 + h / 2))
    k4 = rhs(x + h * k3, u + slope * (tau0 + h))
    return ca.Function(name, [x, u, slope, tau0, h], [x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])


def ipopt_options(*, verbose: bool = False, tol: float = 1e-10, max_iter: int = 500,
                  max_wall_s: float | None = None, extra: dict | None = None) -> dict:
    """CasADi ``nlpsol`` options for IPOPT: silent unless ``verbose``, exact Hessian."""
    opts = {
        "ipopt.print_level": 5 if verbose else 0,
        "ipopt.sb": "yes",
        "print_time": bool(verbose),
        "ipopt.tol": tol,
        "ipopt.constr_viol_tol": tol,
        "ipopt.acceptable_tol": 1e3 * tol,
        "ipopt.acceptable_constr_viol_tol": 1e3 * tol,
        "ipopt.max_iter": int(max_iter),
        "ipopt.mu_strategy": "adaptive",
        "error_on_fail": False,
    }
    if max_wall_s is not None:
        opts["ipopt.max_wall_time"] = float(max_wall_s)
    if extra:
        opts.update(extra)
    return opts


def nlp_counts(solver) -> tuple[int, int]:
    """``(objective evaluations, iterations)`` of the last solve of a CasADi ``nlpsol``."""
    st = solver.stats()
    return int(st.get("n_call_nlp_f", 0)), int(st.get("iter_count", 0))
