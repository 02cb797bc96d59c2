"""Compiled, batched fixed-step RK4 with in-step event location, and a scipy reference.

The fast path: :func:`integrate` propagates a whole batch of trajectories in one call of a
numba kernel (parallel over trajectories, ``cache=True``). Controls are open-loop piecewise
polynomials in time (:class:`PiecewisePolynomial`): a least-squares cubic (paper 000) is one
segment of order 4; an environment step with a held action is one segment of order 1; a spline
through nodes (paper 001) is one cubic segment per knot interval. Align RK4 steps with segment
breaks: a break inside a step costs RK4 its order. Each RK4 step evaluates all its stages (and
the speed-minimum event function) on the segment containing the step's start, so a
piecewise-constant control with breaks on the grid is integrated exactly as a zero-order hold,
the same arithmetic as stepping an environment one held action at a time; a kink of the speed
at a break is not a speed-minimum event.

Events, located inside the step on the RK4 solution itself (root-finding on the partial step
length, not stopping at the next grid point):

- :class:`RadiusCrossing`: r falls through a given radius (touchdown, target altitude). Terminal.
  Also found when the radius dips below and comes back within one step (the minimum of r
  inside the step is located and checked).
- :class:`SpeedMinimum`: the speed relative to the surface reaches a minimum (which includes
  reaching zero): the engine cut-off of a constant-thrust, steer-only lander. Terminal.
- Fuel exhaustion (always on): when m reaches ``dry_mass_nd`` the throttle is forced to zero
  for the rest of the integration and the time is reported in ``t_burnout``.

The reference :func:`integrate_reference` (scipy ``solve_ivp``, DOP853, rtol 1e-12) is for
tests and certification only.
"""

from __future__ import annotations

import math
import types
from dataclasses import dataclass, field

import numba
import numpy as np
from numba import njit

from . import _rk4_template as _tmpl
from . import dynamics as dyn

__all__ = [
    "Model", "PLANAR", "MOON3D", "PiecewisePolynomial", "RadiusCrossing", "SpeedMinimum",
    "Propagation", "integrate", "integrate_prepared", "integrate_reference", "params_rows",
    "STATUS_COMPLETED",
    "STATUS_RADIUS", "STATUS_SPEED_MIN",
]

STATUS_COMPLETED = _tmpl.EVENT_NONE
STATUS_RADIUS = _tmpl.EVENT_RADIUS
STATUS_SPEED_MIN = _tmpl.EVENT_SPEED_MIN

# Below this batch size the serial kernel wins: thread start-up costs more than the work.
_PARALLEL_MIN_BATCH = 32

# Inlined at numba-IR level on the hot path; the rarely called event code is left as calls to
# keep compile time down.
_INLINED: tuple[str, ...] = ()
_HELPER_FUNCTIONS = ("control_in", "segment_at", "rk4_core", "rk4_step", "event_value",
                     "is_after", "locate", "propagate_lane")


def _prange_only() -> dict:
    """numba's parallel options for the batch kernel: the ``prange`` over the rows only. With
    ``parallel=True`` numba also turned the output allocations (``np.zeros``, ``np.full``) into
    parallel loops, each compiled as a gufunc of its own (~4 s of compilation apiece from a
    cold cache) for no speed: the rows' work is the loop. (A new dict each time:
    numba pops the keys.)"""
    return {"prange": True, "comprehension": False, "reduction": False, "inplace_binop": False,
            "setitem": False, "numpy": False, "stencil": False, "fusion": False}


def _instantiate(model_name: str, bindings: dict) -> tuple:
    """Compile the template functions with the model's names bound; returns the ``propagate``
    kernels (serial, parallel) followed by the ``propagate_into`` kernels (serial, parallel).

    Each copy gets its own qualified name so numba's on-disk cache keeps them apart. Only the
    two driver functions differ between the serial and the parallel kernel (``prange`` over
    the rows); the per-trajectory step loop (``propagate_lane``) and the helpers it calls are
    compiled once and shared (a second copy costs ~20 s of compilation per model from a cold
    cache).
    """
    def copy(fname: str, ns: dict, kind: str):
        src = getattr(_tmpl, fname)
        qual = f"{model_name}_{kind}_{fname}"
        code = src.__code__.replace(co_name=qual, co_qualname=qual)
        fn = types.FunctionType(code, ns, qual, src.__defaults__)
        fn.__module__ = _tmpl.__name__
        fn.__qualname__ = qual
        return fn

    shared = dict(vars(_tmpl))
    shared.update(bindings)
    for fname in _HELPER_FUNCTIONS:
        fn = copy(fname, shared, "ser")  # the serial kernel's names, as cached before
        shared[fname] = (njit(cache=True, inline="always")(fn) if fname in _INLINED
                         else njit(cache=True)(fn))
    kernels, into = [], []
    for parallel in (False, True):
        ns = dict(shared)
        kind = "par" if parallel else "ser"
        ns["propagate"] = njit(cache=True, parallel=_prange_only() if parallel else False)(
            copy("propagate", ns, kind))
        ns["propagate_into"] = njit(cache=True)(copy("propagate_into", ns, kind))
        kernels.append(ns["propagate"])
        into.append(ns["propagate_into"])
    return (*kernels, *into)


# ---- planar bindings --------------------------------------------------------------------------
_planar_thrust_jit = njit(cache=True, inline="always")(dyn.planar_thrust_terms)
_planar_terms_jit = njit(cache=True, inline="always")(dyn.planar_eom_terms)


@njit(cache=True, inline="always")
def _planar_load(row):
    return (row[0], row[1], row[2], row[3], row[4])


@njit(cache=True, inline="always")
def _planar_prep(u):
    return _planar_thrust_jit(u[0], u[1])


@njit(cache=True, inline="always")
def _planar_deriv_c(y, c, p):
    return _planar_terms_jit(y[0], y[1], y[3], y[4], c[0], c[1], c[2], p[0], p[1])


@njit(cache=True, inline="always")
def _planar_deriv(y, u, p):
    return _planar_deriv_c(y, _planar_prep(u), p)


@njit(cache=True, inline="always")
def _planar_radius(y):
    return y[0]


@njit(cache=True, inline="always")
def _planar_radial_rate(y):
    return y[1]


@njit(cache=True, inline="always")
def _planar_speed_rate(y, dy):
    # relative velocity (v, rω); its derivative (v', v ω + r ω')
    vt = y[0] * y[3]
    return y[1] * dy[1] + vt * (y[1] * y[3] + y[0] * dy[3])


@njit(cache=True, inline="always")
def _planar_mass(y):
    return y[4]


# ---- rotating-Moon bindings -------------------------------------------------------------------
_moon3d_thrust_jit = njit(cache=True, inline="always")(dyn.moon3d_thrust_terms)
_moon3d_terms_jit = njit(cache=True, inline="always")(dyn.moon3d_eom_terms)


@njit(cache=True, inline="always")
def _moon3d_load(row):
    return (row[0], row[1], row[2], row[3], row[4], row[5], row[6])


@njit(cache=True, inline="always")
def _moon3d_prep(u):
    return _moon3d_thrust_jit(u[0], u[1], u[2])


@njit(cache=True, inline="always")
def _moon3d_deriv_c(y, c, p):
    return _moon3d_terms_jit(y[0], y[1], y[2], y[3], y[4], y[5], y[6], c[0], c[1], c[2], c[3],
                             p[0], p[1], p[2], p[3], p[4], p[5])


@njit(cache=True, inline="always")
def _moon3d_deriv(y, u, p):
    return _moon3d_deriv_c(y, _moon3d_prep(u), p)


@njit(cache=True, inline="always")
def _moon3d_radius(y):
    return math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2])


@njit(cache=True, inline="always")
def _moon3d_radial_rate(y):
    # r·V has the sign of dr/dt
    return y[0] * y[3] + y[1] * y[4] + y[2] * y[5]


@njit(cache=True, inline="always")
def _moon3d_speed_rate(y, dy):
    return y[3] * dy[3] + y[4] * dy[4] + y[5] * dy[5]


@njit(cache=True, inline="always")
def _moon3d_mass(y):
    return y[6]


@dataclass(frozen=True)
class Model:
    """A dynamics model as the integrators see it.

    Attributes
    ----------
    name : str
    n_state, n_control : int
    state_names, control_names : tuple of str
    rhs : callable
        Batched NumPy right-hand side ``rhs(state, control, params)``.
    """

    name: str
    n_state: int
    n_control: int
    state_names: tuple[str, ...]
    control_names: tuple[str, ...]
    rhs: object
    _bindings: dict = field(repr=False, compare=False)
    _kernels: list = field(default_factory=list, repr=False, compare=False)

    def kernel(self, parallel: bool):
        """Compiled propagate kernel (compiled or loaded from cache on first use)."""
        if not self._kernels:
            self._kernels.extend(_instantiate(self.name, self._bindings))
        return self._kernels[1 if parallel else 0]

    def kernel_into(self, parallel: bool):
        """Compiled ``propagate_into`` kernel: results copied into the caller's arrays."""
        if not self._kernels:
            self._kernels.extend(_instantiate(self.name, self._bindings))
        return self._kernels[3 if parallel else 2]


PLANAR = Model(
    "planar", 5, 2, dyn.PLANAR_STATE_NAMES, ("phi", "throttle"), dyn.planar_rhs,
    dict(LOAD=_planar_load, DERIV=_planar_deriv, PREP=_planar_prep, DERIV_C=_planar_deriv_c,
         RADIUS=_planar_radius, RADIAL_RATE=_planar_radial_rate,
         SPEED_RATE=_planar_speed_rate, MASS=_planar_mass,
         UZERO=(0.0, 0.0)),
)
MOON3D = Model(
    "moon3d", 7, 3, dyn.MOON3D_STATE_NAMES, ("alpha", "beta", "throttle"), dyn.moon3d_rhs,
    dict(LOAD=_moon3d_load, DERIV=_moon3d_deriv, PREP=_moon3d_prep, DERIV_C=_moon3d_deriv_c,
         RADIUS=_moon3d_radius, RADIAL_RATE=_moon3d_radial_rate,
         SPEED_RATE=_moon3d_speed_rate, MASS=_moon3d_mass,
         UZERO=(0.0, 0.0, 0.0)),
)


@dataclass(frozen=True)
class PiecewisePolynomial:
    """Open-loop control law u(t), one per trajectory of a batch.

    Attributes
    ----------
    breaks : ndarray, shape (batch, n_seg + 1)
        Segment boundaries in normalised time, increasing. Times before the first or after the
        last break extrapolate the first or last segment.
    coefs : ndarray, shape (batch, n_seg, n_control, order)
        Ascending-power coefficients in τ = t − breaks[:, k] of each control channel. The last
        channel is the throttle.
    """

    breaks: np.ndarray
    coefs: np.ndarray

    def __post_init__(self) -> None:
        b = _kernel_array(self.breaks)
        c = _kernel_array(self.coefs)
        if b.ndim != 2 or c.ndim != 4 or c.shape[0] != b.shape[0] or c.shape[1] != b.shape[1] - 1:
            raise ValueError(
                f"breaks shape {b.shape} and coefs shape {c.shape} do not match; expected "
                "(batch, n_seg+1) and (batch, n_seg, n_control, order)")
        if not (np.all(np.isfinite(b)) and np.all(np.isfinite(c))):
            raise ValueError("control breaks and coefficients must be finite")
        object.__setattr__(self, "breaks", b)
        object.__setattr__(self, "coefs", c)

    @classmethod
    def constant(cls, values: np.ndarray, t0: np.ndarray, t1: np.ndarray) -> PiecewisePolynomial:
        """Hold ``values`` (batch, n_control) over [t0, t1] (each shape (batch,))."""
        v = np.asarray(values, dtype=np.float64)
        breaks = np.stack([np.asarray(t0, float) * np.ones(len(v)),
                           np.asarray(t1, float) * np.ones(len(v))], axis=1)
        return cls(breaks, v[:, None, :, None])

    @classmethod
    def polynomial(cls, coefs: np.ndarray, t0: np.ndarray, t1: np.ndarray) -> PiecewisePolynomial:
        """One polynomial per trajectory; ``coefs`` (batch, n_control, order), τ = t − t0."""
        c = np.asarray(coefs, dtype=np.float64)
        breaks = np.stack([np.broadcast_to(np.asarray(t0, float), c.shape[:1]),
                           np.broadcast_to(np.asarray(t1, float), c.shape[:1])], axis=1)
        return cls(breaks, c[:, None])

    @property
    def batch(self) -> int:
        return self.breaks.shape[0]

    @property
    def n_control(self) -> int:
        return self.coefs.shape[2]

    def __call__(self, t: np.ndarray) -> np.ndarray:
        """Evaluate at times ``t`` of shape (batch, n_t); returns (batch, n_t, n_control)."""
        t = np.atleast_2d(np.asarray(t, dtype=np.float64))
        t = np.broadcast_to(t, (self.batch, t.shape[-1]))
        n_seg = self.coefs.shape[1]
        k = np.empty(t.shape, dtype=np.int64)
        for b in range(self.batch):
            k[b] = np.clip(np.searchsorted(self.breaks[b], t[b], side="right") - 1, 0, n_seg - 1)
        tau = t - np.take_along_axis(self.breaks, k, axis=1)
        c = self.coefs[np.arange(self.batch)[:, None], k]  # (batch, n_t, n_control, order)
        out = c[..., -1]
        for q in range(c.shape[-1] - 2, -1, -1):
            out = out * tau[..., None] + c[..., q]
        return out


@dataclass(frozen=True)
class RadiusCrossing:
    """Terminal event: the radius falls through ``radius_nd`` (scalar or shape (batch,))."""

    radius_nd: float | np.ndarray
    terminal: bool = True
    direction: int = -1


@dataclass(frozen=True)
class SpeedMinimum:
    """Terminal event: the speed relative to the surface reaches a minimum (or zero)."""

    terminal: bool = True
    direction: int = 1


@dataclass(frozen=True)
class Propagation:
    """Result of :func:`integrate` (normalised units).

    Attributes
    ----------
    y_end : ndarray, shape (batch, n_state)
        State at the end (last grid point, or the terminal event).
    t_end : ndarray, shape (batch,)
    status : ndarray of int, shape (batch,)
        0 reached the last step; 1 radius crossing; 2 speed minimum.
    t_burnout : ndarray, shape (batch,)
        Time fuel ran out (NaN if it did not).
    states : ndarray, shape (batch, n_steps + 1, n_state) or None
        Recorded grid states when ``record=True``; the entry ``n_records - 1`` is the end state
        and later entries repeat it.
    times : ndarray, shape (batch, n_steps + 1) or None
        Times of ``states``.
    n_records : ndarray of int, shape (batch,)
    """

    y_end: np.ndarray
    t_end: np.ndarray
    status: np.ndarray
    t_burnout: np.ndarray
    states: np.ndarray | None
    times: np.ndarray | None
    n_records: np.ndarray


def params_rows(params, n: int) -> np.ndarray:
    """Model parameters of ``n`` trajectories as the kernels take them: a C-contiguous float64
    array (n, n_params).

    ``params``: a parameter dataclass (:class:`~lunar_env.dynamics.PlanarParams`,
    :class:`~lunar_env.dynamics.Moon3DParams`), its ``as_array()`` (n_params,) (the same for
    every trajectory), or one row per trajectory (n, n_params) (e.g. a plant error per lander).
    """
    p = params.as_array() if hasattr(params, "as_array") else np.asarray(params, np.float64)
    if p.ndim == 1:
        return _kernel_array(np.broadcast_to(p, (int(n), p.shape[0])))
    if p.ndim != 2 or p.shape[0] != n:
        raise ValueError(f"params have shape {p.shape}; expected (n_params,) or ({n}, n_params)")
    return _kernel_array(p)


def _kernel_array(a) -> np.ndarray:
    """``a`` as a C-contiguous, *writable* float64 array (a copy only when needed). Why
    writable: numba compiles a separate specialisation of a kernel for every combination of
    read-only inputs (a broadcast view of one trajectory is read-only), each costing the
    kernel's full compilation (~10 s for the RK4 kernels) on a fresh machine."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    return a if a.flags.writeable else a.copy()


def integrate(model: Model, y0_nd: np.ndarray, *, t0_nd, dt_nd, n_steps: int,
              control: PiecewisePolynomial, params, dry_mass_nd: float = 0.0,
              events: tuple = (), record: bool = False,
              parallel: bool | None = None) -> Propagation:
    """Propagate a batch with fixed-step RK4 (compiled), locating events inside steps.

    Parameters
    ----------
    model : Model
        :data:`PLANAR` or :data:`MOON3D`.
    y0_nd : ndarray, shape (batch, n_state)
        Initial states, normalised.
    t0_nd, dt_nd : float or ndarray, shape (batch,)
        Start time and step length per trajectory (a free final time tf over n steps is
        ``dt_nd = tf / n``).
    n_steps : int
        Number of RK4 steps (the same for every trajectory).
    control : PiecewisePolynomial
        Open-loop control of the same batch size.
    params : PlanarParams or Moon3DParams, or ndarray (batch, n_params)
        Model parameters, the same for every trajectory or one row each (see
        :func:`params_rows`).
    dry_mass_nd : float
        Mass at which fuel is exhausted and the burn ends.
    events : tuple of RadiusCrossing / SpeedMinimum
    record : bool
        Keep every grid state (memory: batch × (n_steps+1) × n_state × 8 bytes).
    parallel : bool, optional
        Force the parallel or serial kernel (default: parallel for larger batches).

    Raises
    ------
    ValueError
        On shape mismatch, non-finite input or a non-positive step.
    """
    y0 = _kernel_array(np.atleast_2d(y0_nd))
    n_traj = y0.shape[0]
    if y0.shape[1] != model.n_state:
        raise ValueError(f"y0 has {y0.shape[1]} components; model {model.name!r} needs "
                         f"{model.n_state}")
    if not np.all(np.isfinite(y0)):
        raise ValueError("all components of the initial state y0 must be finite")
    if control.batch != n_traj or control.n_control != model.n_control:
        raise ValueError(f"control is for batch {control.batch} × {control.n_control} channels;"
                         f" expected {n_traj} × {model.n_control}")
    n_steps = int(n_steps)
    if n_steps < 1:
        raise ValueError(f"n_steps = {n_steps} must be >= 1")
    t0 = _kernel_array(np.broadcast_to(np.asarray(t0_nd, float), (n_traj,)))
    dt = _kernel_array(np.broadcast_to(np.asarray(dt_nd, float), (n_traj,)))
    if not (np.all(np.isfinite(dt)) and np.all(dt > 0)):
        raise ValueError(f"dt_nd must be finite and > 0, got {dt_nd!r}")
    r_stop = np.full(n_traj, np.nan)
    speed = False
    for ev in events:
        if isinstance(ev, RadiusCrossing):
            r_stop = np.ascontiguousarray(
                np.broadcast_to(np.asarray(ev.radius_nd, float), (n_traj,)).copy())
        elif isinstance(ev, SpeedMinimum):
            speed = True
        else:
            raise TypeError(f"unknown event {ev!r}; use RadiusCrossing or SpeedMinimum")
    if parallel is None:
        parallel = n_traj >= _PARALLEL_MIN_BATCH and numba.config.NUMBA_NUM_THREADS > 1
    p = params_rows(params, n_traj)
    y_end, t_end, status, t_burn, n_rec, traj = model.kernel(parallel)(
        y0, t0, dt, n_steps, control.breaks, control.coefs, p, float(dry_mass_nd), r_stop,
        speed, bool(record))
    times = None
    states = None
    if record:
        states = traj
        times = t0[:, None] + dt[:, None] * np.arange(n_steps + 1)[None, :]
        last = np.arange(n_steps + 1)[None, :] >= (n_rec - 1)[:, None]
        times = np.where(last, t_end[:, None], times)
    return Propagation(y_end, t_end, status, t_burn, states, times, n_rec)


def integrate_prepared(model: Model, y0_nd: np.ndarray, t0_nd: np.ndarray, dt_nd: np.ndarray,
                       n_steps: int, breaks: np.ndarray, coefs: np.ndarray,
                       params_array: np.ndarray, dry_mass_nd: float, r_stop_nd: np.ndarray,
                       stop_at_speed_min: bool, parallel: bool = False,
                       out: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Lean fast path of :func:`integrate` for callers that step often (environments).

    Same compiled kernel and results as :func:`integrate`, without its input validation and
    object construction (which cost ~25 µs per call, ten times the kernel for one lander). The
    caller guarantees what :func:`integrate` would check: C-contiguous float64 arrays of the
    right shapes, ``y0_nd`` (B, n_state) finite, ``t0_nd``/``dt_nd``/``r_stop_nd`` (B,)
    (``r_stop_nd`` NaN disables the radius event), ``dt_nd > 0``, ``breaks`` (B, n_seg+1) and
    ``coefs`` (B, n_seg, n_control, order) as in :class:`PiecewisePolynomial`, ``params_array``
    (B, n_params) one row per trajectory (:func:`params_rows`). No recording.

    ``out``: optional arrays ``(y_end (B, n_state), t_end (B,), status (B,) int64,
    t_burnout (B,))``, C-contiguous, not overlapping the inputs, that receive the results (and
    are returned): for a few trajectories, new result arrays cost several times the
    integration itself.

    Returns
    -------
    y_end, t_end, status, t_burnout
        As the fields of :class:`Propagation` of the same name.
    """
    if out is not None:
        model.kernel_into(parallel)(y0_nd, t0_nd, dt_nd, n_steps, breaks, coefs, params_array,
                                    dry_mass_nd, r_stop_nd, stop_at_speed_min, *out)
        return out
    y_end, t_end, status, t_burn, _, _ = model.kernel(parallel)(
        y0_nd, t0_nd, dt_nd, n_steps, breaks, coefs, params_array, dry_mass_nd, r_stop_nd,
        stop_at_speed_min, False)
    return y_end, t_end, status, t_burn


def integrate_reference(model: Model, y0_nd: np.ndarray, t_span_nd: tuple[float, float],
                        control_fn, params, *, rtol: float = 1e-12, atol: float = 1e-14,
                        t_eval=None, events=None, dense_output: bool = False):
    """Adaptive high-accuracy reference (scipy ``solve_ivp``, DOP853). Tests only.

    ``control_fn(t) -> ndarray (n_control,)``. Returns scipy's ``OdeResult``.
    """
    from scipy.integrate import solve_ivp

    def f(t, y):
        return model.rhs(y[None, :], np.asarray(control_fn(t), float)[None, :], params)[0]

    return solve_ivp(f, t_span_nd, np.asarray(y0_nd, float), method="DOP853", rtol=rtol,
                     atol=atol, t_eval=t_eval, events=events, dense_output=dense_output)
