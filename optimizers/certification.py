"""One certification call for every solver: replay the answer, compare with the optimum.

:func:`certify` replays a result's control law (``OptimResult.control``) from the problem's
initial state with the adaptive reference integrator (scipy DOP853 on the shared right-hand
side, :func:`lunar_env.integrators.integrate_reference`), judges the replayed final state by the
problem's own terminal and path conditions, and compares the result's fuel and final time with
the problem's certified optimum (:func:`certified_optimum`: Pontryagin for the planar problems,
dense Legendre–Gauss collocation for the pinpoint landing), or with a
``reference`` the caller supplies. Every reproduction reports its solvers through it.

It sits above the families (it dispatches to their certifiers), not in
:mod:`optimizers.common`, which imports nothing above it.

>>> from optimizers.problems import PlanarLandingProblem        # doctest: +SKIP
>>> cert = certify(ASAGA().solve(problem, seed=0), problem)     # doctest: +SKIP
>>> cert.fuel_gap_kg, cert.replay_success                       # doctest: +SKIP
"""

from __future__ import annotations

import math
import weakref
from dataclasses import asdict, dataclass, field

import numpy as np

from .common.result import OptimResult

__all__ = ["Certificate", "certify", "certified_optimum", "replay_reference"]

_CERTIFIED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass
class Certificate:
    """Outcome of :func:`certify`.

    Attributes
    ----------
    replay_terminal_errors : dict of str -> float
        SI terminal errors of the DOP853 replay of the result's control.
    replay_success : bool
        The problem's verdict on the replay (terminal tolerances and path conditions).
    replay_message : str
    replay_path : dict of str -> float
        Path quantities of the replay (e.g. ``min_altitude_m``).
    optimum_fuel_kg, optimum_tf_s : float
        The certified optimum.
    optimum_method : str
    optimum_success : bool
    fuel_gap_kg, fuel_gap_pct, tf_gap_s : float
        Result minus optimum (NaN when either is unknown).
    """

    replay_terminal_errors: dict[str, float]
    replay_success: bool
    replay_message: str
    replay_path: dict[str, float] = field(default_factory=dict)
    optimum_fuel_kg: float = math.nan
    optimum_tf_s: float = math.nan
    optimum_method: str = ""
    optimum_success: bool = False
    fuel_gap_kg: float = math.nan
    fuel_gap_pct: float = math.nan
    tf_gap_s: float = math.nan

    def as_dict(self) -> dict:
        return asdict(self)


def _ocp_of(problem):
    ocp = getattr(problem, "ocp", problem)
    for name in ("model", "params", "initial_state", "terminal_errors", "success_from"):
        if not hasattr(ocp, name):
            raise TypeError(f"certify needs an optimal-control problem (an OCP, or a problem with "
                            f"an .ocp); {type(problem).__name__} has no {name!r}")
    return ocp


def certified_optimum(ocp) -> OptimResult:
    """The problem's optimum by its certifier, computed once per problem object.

    - :class:`~optimizers.problems.planar_ocp.PlanarOCP`: Pontryagin shooting
      (:func:`optimizers.indirect.planar.solve_planar_min_fuel`, errors from a DOP853 replay);
    - :class:`~optimizers.problems.pinpoint.PinpointOCP`: dense Legendre–Gauss collocation
      (N = 40) from the serial strategy's solution
      (:func:`optimizers.transcription.serial.certified_optimum`).

    Raises
    ------
    TypeError
        For a problem with no certifier (pass ``reference=`` to :func:`certify`).
    """
    cached = _CERTIFIED.get(ocp)
    if cached is not None:
        return cached
    # imported here: ``import optimizers`` (which exports certify) stays free of CasADi
    from .problems.pinpoint import PinpointOCP
    from .problems.planar_ocp import PlanarOCP

    if isinstance(ocp, PlanarOCP):
        from .indirect.planar import solve_planar_min_fuel

        ref = solve_planar_min_fuel(ocp, check="reference")
    elif isinstance(ocp, PinpointOCP):
        from .transcription.serial import certified_optimum as dense_optimum

        ref = dense_optimum(ocp)
    else:
        raise TypeError(f"no certifier for {type(ocp).__name__}; pass the optimum as "
                        "certify(..., reference=...)")
    _CERTIFIED[ocp] = ref
    return ref


def replay_reference(result: OptimResult, problem, *, rtol: float = 1e-12,
                     n_samples: int = 401) -> tuple[np.ndarray, np.ndarray]:
    """Replay ``result``'s control from the problem's initial state with DOP853.

    Returns
    -------
    t_nd : ndarray, shape (n_samples,)
    states_nd : ndarray, shape (n_samples, n_state)
    """
    from lunar_env.integrators import integrate_reference

    ocp = _ocp_of(problem)
    if not (math.isfinite(result.tf_s) and result.tf_s > 0):
        raise ValueError(f"the result's tf_s = {result.tf_s!r} must be finite and > 0")
    time_s = ocp.scaling.time_s
    tf_nd = result.tf_s / time_s
    t_eval = np.linspace(0.0, tf_nd, int(n_samples))

    def control(t_nd):
        return result.control_at(min(max(float(t_nd), 0.0), tf_nd) * time_s)

    out = integrate_reference(ocp.model, ocp.initial_state, (0.0, tf_nd), control, ocp.params,
                              rtol=rtol, atol=1e-14, t_eval=t_eval)
    return out.t, out.y.T


def certify(result: OptimResult, problem, *, reference: OptimResult | None = None,
            rtol: float = 1e-12) -> Certificate:
    """Replay ``result`` with the reference integrator and compare it with the optimum.

    Parameters
    ----------
    result : OptimResult
        Any solver's answer; it must carry its control law (``result.control``).
    problem : OCP or Problem with an ``ocp``
        The problem the result solves (its initial state, dynamics and verdict).
    reference : OptimResult, optional
        The optimum to compare with; default :func:`certified_optimum` of the problem.
    rtol : float
        DOP853 relative tolerance of the replay.

    Returns
    -------
    Certificate
    """
    ocp = _ocp_of(problem)
    _, states = replay_reference(result, problem, rtol=rtol)
    errors = ocp.terminal_errors(states[-1])
    path = ocp.path_quantities(states)
    # the problem the user passed judges the replay (a black-box problem may state looser
    # terminal tolerances than its OCP, e.g. [000]'s 0.5 m/s)
    judge = getattr(problem, "replay_verdict", None) or ocp.success_from
    ok, why = judge(errors, path)
    ref = reference if reference is not None else certified_optimum(ocp)
    cert = Certificate(errors, bool(ok), why, path, float(ref.fuel_kg), float(ref.tf_s),
                       ref.algorithm or type(ref).__name__, bool(ref.success))
    if math.isfinite(result.fuel_kg) and math.isfinite(ref.fuel_kg):
        cert.fuel_gap_kg = float(result.fuel_kg - ref.fuel_kg)
        cert.fuel_gap_pct = 100.0 * cert.fuel_gap_kg / ref.fuel_kg if ref.fuel_kg else math.nan
    if math.isfinite(result.tf_s) and math.isfinite(ref.tf_s):
        cert.tf_gap_s = float(result.tf_s - ref.tf_s)
    return cert
