"""Plant and navigation errors: the uncertainty model of the landing envs (SI, 1σ).

A GNC engineer judges a guidance law by Monte Carlo campaigns over the errors of the real
world. :class:`UncertaintyModel` is a frozen, validated set of 1σ errors that the envs draw
once per episode (and, for navigation noise, once per decision):

**Entry** (the state at powered-descent initiation): position errors along the local up,
downrange and crossrange axes (m) and velocity errors along the same axes (m/s), added to the
planned start (the scenario's dispersed draw, or the state pinned by ``reset`` options).

**Plant**: thrust scale error (relative, 1σ), specific-impulse scale error (relative),
thrust-direction misalignment (rad, a fixed bias per episode on each gimbal angle: the planar
thrust angle φ; the pinpoint elevation α and azimuth β), and initial wet-mass error (kg). The
flight computer is not told any of them.

**Navigation**: the observation encodes the *navigated* state, the truth plus a bias per
episode and white noise per decision, in position (m) and velocity (m/s) along up, downrange,
crossrange. Before a landing radar acquires the ground, navigation propagates the orbit
determination and is worst at altitude. ``radar_altitude_m`` is where the terminal sensors
(a landing radar or Doppler lidar, with terrain-relative navigation) lock: there the errors
(bias and noise) drop to ``radar_lock_fraction`` of themselves and below it they shrink in
proportion to the altitude (a range sensor's error is a fraction of its range) down to the
floors ``near_ground_position_fraction`` (position) and ``near_ground_velocity_fraction``
(velocity) of themselves. The flight computer's mass estimate
is the planned initial mass minus the propellant it believes burnt, so it misses by the wet
mass error (a constant offset).

Every draw is a standard normal truncated at ±:data:`TRUNCATION_SIGMA` times its σ, so the
plant scale factors stay positive and a single freak draw cannot dominate a campaign's tail.

**Common random numbers.** The errors of an episode come from a stream of their own, seeded by
the episode's reset seed (:func:`error_stream`): case k of a campaign (sub-env k reset with
``seed + k``) sees the same errors whatever the number of landers, the workers or the law
flown, and the same standard-normal draws under every scale of the model
(:meth:`UncertaintyModel.scaled`), so a robustness curve is smooth. The per-decision noise is
a counter-based function of the episode's key and the decision index
(:func:`navigation_noise`), so it too is the same whatever the batch.

Named sets (:data:`NAMED_SETS`): ``none`` (no error at all; the envs are bit for bit those
without the model), ``standard`` and ``stress`` (3 × standard). Build your own the same way::

    from lunar_env.uncertainty import UncertaintyModel, get_uncertainty
    mine = get_uncertainty("standard").replace(thrust_scale=0.05)
    env = gym.make("LunarSoftLanding-v0", uncertainty=mine)      # or uncertainty="standard"
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields
from typing import Any

import numba
import numpy as np
from numba.extending import register_jitable

from .validation import InvalidTypeError, require_number

__all__ = ["UncertaintyModel", "EpisodeErrors", "NAMED_SETS", "get_uncertainty",
           "resolve_uncertainty", "error_stream", "draw_errors", "navigation_noise",
           "radar_weight", "errors_from_option", "episode_errors", "navigation_errors",
           "TRUNCATION_SIGMA", "N_NORMALS"]

#: every error draw is a standard normal truncated at this many σ
TRUNCATION_SIGMA = 4.5
#: standard normals drawn per episode, in this order: entry position (3), entry velocity (3),
#: thrust, Isp, misalignment (2), wet mass, navigation position bias (3), velocity bias (3)
N_NORMALS = 17
#: spawn key separating the error stream from the env's initial-state stream of the same seed
_ERROR_STREAM_KEY = 0x5EED_E770


def _vec3(name: str, value) -> tuple[float, float, float]:
    try:
        items = tuple(value)
    except TypeError:
        raise InvalidTypeError(f"UncertaintyModel.{name} = {value!r} is not a sequence of 3 "
                               "numbers (up, downrange, crossrange)") from None
    if len(items) != 3:
        raise ValueError(f"UncertaintyModel.{name} = {value!r} has {len(items)} components; "
                         "3 are required (up, downrange, crossrange)")
    return tuple(_sigma(f"{name}[{i}]", v) for i, v in enumerate(items))


def _sigma(name: str, value) -> float:
    v = require_number(f"UncertaintyModel.{name}", value)
    if not math.isfinite(v) or v < 0.0:
        raise ValueError(f"UncertaintyModel.{name} = {value!r} is not allowed; a 1σ error must "
                         "be finite and >= 0")
    return v


_VECTORS = ("entry_position_m", "entry_velocity_m_s", "nav_position_bias_m",
            "nav_velocity_bias_m_s", "nav_position_noise_m", "nav_velocity_noise_m_s")
_SCALES = ("thrust_scale", "isp_scale")


@dataclass(frozen=True)
class UncertaintyModel:
    """1σ errors of the plant and of navigation (SI; see the module docstring).

    Attributes
    ----------
    name : str
        Label in reports (``"custom"`` for a user's set).
    entry_position_m, entry_velocity_m_s : (float, float, float)
        Start-state errors along (up, downrange, crossrange) (m, m/s). The planar env has no
        crossrange: its third component is ignored.
    thrust_scale, isp_scale : float
        Relative 1σ errors of the maximum thrust and of the specific impulse (< 0.2).
    misalignment_rad : float
        1σ bias of each gimbal angle (rad), fixed per episode.
    mass_kg : float
        1σ error of the initial wet mass (kg).
    nav_position_bias_m, nav_velocity_bias_m_s : (float, float, float)
        1σ navigation bias per episode, at altitude (m, m/s).
    nav_position_noise_m, nav_velocity_noise_m_s : (float, float, float)
        1σ navigation white noise per decision, at altitude (m, m/s).
    radar_altitude_m : float
        Altitude (m) at which the terminal sensors lock (finite, > 0; no radar: fractions of
        1).
    radar_lock_fraction : float
        Multiplier of the navigation errors at lock, in [0, 1]; below the lock altitude it
        falls in proportion to the altitude (:func:`radar_weight`).
    near_ground_position_fraction, near_ground_velocity_fraction : float
        Floors of the position and velocity multipliers (the sensors' accuracy near the
        ground, as fractions of the errors at altitude), in [0, 1].
    """

    name: str = "custom"
    entry_position_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    entry_velocity_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    thrust_scale: float = 0.0
    isp_scale: float = 0.0
    misalignment_rad: float = 0.0
    mass_kg: float = 0.0
    nav_position_bias_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    nav_velocity_bias_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    nav_position_noise_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    nav_velocity_noise_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radar_altitude_m: float = 1.0e9
    radar_lock_fraction: float = 1.0
    near_ground_position_fraction: float = 1.0
    near_ground_velocity_fraction: float = 1.0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise InvalidTypeError(f"UncertaintyModel.name = {self.name!r} must be a non-empty "
                                   "string")
        for f in _VECTORS:
            object.__setattr__(self, f, _vec3(f, getattr(self, f)))
        for f in ("thrust_scale", "isp_scale", "misalignment_rad", "mass_kg"):
            object.__setattr__(self, f, _sigma(f, getattr(self, f)))
        for f in _SCALES:
            if getattr(self, f) >= 0.2:
                raise ValueError(f"UncertaintyModel.{f} = {getattr(self, f)!r} is not allowed; "
                                 "a relative 1σ error must be < 0.2 (the engine must keep "
                                 "a positive thrust and Isp within the truncation)")
        if self.misalignment_rad >= 0.2:
            raise ValueError(f"UncertaintyModel.misalignment_rad = {self.misalignment_rad!r} is "
                             "not allowed; it must be < 0.2 rad (a small-angle bias)")
        r = require_number("UncertaintyModel.radar_altitude_m", self.radar_altitude_m)
        if not (math.isfinite(r) and r > 0.0):
            raise ValueError(f"UncertaintyModel.radar_altitude_m = {self.radar_altitude_m!r} is "
                             "not allowed; it must be finite and > 0 (m)")
        object.__setattr__(self, "radar_altitude_m", r)
        for name in ("radar_lock_fraction", "near_ground_position_fraction",
                     "near_ground_velocity_fraction"):
            f = require_number(f"UncertaintyModel.{name}", getattr(self, name))
            if not 0.0 <= f <= 1.0:
                raise ValueError(f"UncertaintyModel.{name} = {getattr(self, name)!r} is not "
                                 "allowed; it must be in [0, 1]")
            object.__setattr__(self, name, f)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> UncertaintyModel:
        """From a dict of fields; ``"base": NAME`` starts from a named set and ``"scale": k``
        multiplies every σ (applied after the other fields). Unknown keys are refused."""
        if not isinstance(d, dict):
            raise InvalidTypeError(f"uncertainty settings {d!r} must be a dict")
        d = dict(d)
        base = d.pop("base", None)
        scale = d.pop("scale", None)
        allowed = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - allowed)
        if unknown:
            raise ValueError(f"unknown uncertainty setting(s) {', '.join(map(repr, unknown))}; "
                             f"allowed: base, scale, {', '.join(sorted(allowed))}")
        model = get_uncertainty(base) if base is not None else cls()
        if d:
            model = model.replace(**({"name": "custom"} | d))
        if scale is not None:
            model = model.scaled(scale)
        return model

    def replace(self, **changes: Any) -> UncertaintyModel:
        """A validated copy with ``changes`` (field names as keyword arguments)."""
        allowed = {f.name for f in fields(self)}
        unknown = sorted(set(changes) - allowed)
        if unknown:
            raise ValueError(f"unknown uncertainty setting(s) {', '.join(map(repr, unknown))}; "
                             f"allowed: {', '.join(sorted(allowed))}")
        return dataclasses.replace(self, **changes)

    def scaled(self, k: float) -> UncertaintyModel:
        """Every σ multiplied by ``k`` >= 0 (the radar altitude and the radar's fractions are
        kept); named ``"<name>×k"``. ``scaled(0)`` has no error at all."""
        k = require_number("scale", k)
        if not (math.isfinite(k) and k >= 0.0):
            raise ValueError(f"scale = {k!r} is not allowed; it must be finite and >= 0")
        ch: dict[str, Any] = {f: tuple(k * v for v in getattr(self, f)) for f in _VECTORS}
        for f in ("thrust_scale", "isp_scale", "misalignment_rad", "mass_kg"):
            ch[f] = k * getattr(self, f)
        return dataclasses.replace(self, name=f"{self.name}×{k:g}", **ch)

    @property
    def is_null(self) -> bool:
        """True if every σ is zero (the env then runs exactly as without the model)."""
        return (all(v == 0.0 for f in _VECTORS for v in getattr(self, f))
                and self.thrust_scale == self.isp_scale == self.misalignment_rad
                == self.mass_kg == 0.0)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields (lists for the vectors)."""
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v)
                for f in fields(self)}


# -------------------------------------------------------------------------------------------
# Named sets
# -------------------------------------------------------------------------------------------
#
# The public powered-descent Monte Carlo set we start from (1σ: thrust 2 %, Isp 1 %,
# misalignment 0.2°, wet mass 100 kg, position 20–30 m, velocity 2–3 m/s) is for a terminal
# descent with its navigation sensors on. Scaled to a lunar descent from 15 km:
_STANDARD = UncertaintyModel(
    name="standard",
    # Orbit determination from Earth tracking delivers the powered-descent-initiation state
    # to about a kilometre downrange (Apollo's landing-site offsets were of this order), a few
    # hundred metres in altitude and crossrange, and ~1 m/s in velocity: kilometres and metres
    # per second, not the reference's terminal-phase metres.
    entry_position_m=(300.0, 1000.0, 500.0),
    entry_velocity_m_s=(1.0, 1.5, 1.0),
    # Engine items are properties of the engine, not of the body: kept as published.
    thrust_scale=0.02,
    isp_scale=0.01,
    misalignment_rad=math.radians(0.2),
    # 100 kg is ~5 % of the reference's ~2 t vehicle; a 600 kg lander that has flown to the
    # Moon knows its mass from its propellant gauging to ~1 %: 6 kg.
    mass_kg=6.0,
    # Before the landing radar, navigation propagates the orbit solution with the IMU: worse
    # than the reference's radar-aided 20–30 m / 2–3 m/s in position, better in velocity
    # (accelerometers integrate well over minutes).
    nav_position_bias_m=(100.0, 200.0, 200.0),
    nav_velocity_bias_m_s=(0.5, 0.5, 0.5),
    nav_position_noise_m=(10.0, 10.0, 10.0),
    nav_velocity_noise_m_s=(0.1, 0.1, 0.1),
    # The terminal sensors (a landing radar or Doppler lidar, with terrain-relative
    # navigation) lock at 3 km and measure range to a fraction of itself: the errors drop at
    # lock to 5 % of the pre-radar ones (100 m -> 5 m up at 3 km, 0.17 % of the range; the
    # Doppler lidar flown on IM-1 matched its reconstructed trajectory to ~5 m and 0.5 m/s,
    # NASA NTRS 20250010290) and then shrink with the altitude, to floors of 1 % in position
    # (1 m up, 2 m across) and 20 % in velocity (0.5 -> 0.1 m/s, the Doppler's resolution).
    # Two earlier versions were measured and replaced (docs/notes/issue-29.md): errors
    # shrinking to 10 % at the surface (10 m of altitude error at touchdown: a constant-thrust
    # engine that cuts off at its believed zero altitude falls 10 m and lands at 5.7 m/s,
    # over the 5 m/s limit), and a linear blend from 100 % at lock to 1 % at the surface,
    # which still left ~70 m of altitude error at the pinpoint env's 2 km gate, where a 5 m/s
    # gate speed needs a few metres: every law failed every case on it.
    radar_altitude_m=3000.0,
    radar_lock_fraction=0.05,
    near_ground_position_fraction=0.01,
    near_ground_velocity_fraction=0.2,
)

#: named uncertainty sets: ``none``, ``standard``, ``stress`` (3 × standard)
NAMED_SETS: dict[str, UncertaintyModel] = {
    "none": UncertaintyModel(name="none"),
    "standard": _STANDARD,
    "stress": dataclasses.replace(_STANDARD.scaled(3.0), name="stress"),
}


def get_uncertainty(name: str) -> UncertaintyModel:
    """The named set ``name`` (``none``, ``standard``, ``stress``)."""
    if not isinstance(name, str) or name not in NAMED_SETS:
        raise ValueError(f"unknown uncertainty set {name!r}; named sets: "
                         f"{', '.join(NAMED_SETS)} (or pass an UncertaintyModel or a dict)")
    return NAMED_SETS[name]


def resolve_uncertainty(value) -> UncertaintyModel:
    """An env's ``uncertainty`` argument as a model: None or a name, a model, or a dict of
    fields (:meth:`UncertaintyModel.from_dict`)."""
    if value is None:
        return NAMED_SETS["none"]
    if isinstance(value, UncertaintyModel):
        return value
    if isinstance(value, str):
        return get_uncertainty(value)
    if isinstance(value, dict):
        return UncertaintyModel.from_dict(value)
    raise InvalidTypeError(f"uncertainty = {value!r} is not allowed; pass a set name "
                           f"({', '.join(NAMED_SETS)}), an UncertaintyModel or a dict of its "
                           "fields")


# -------------------------------------------------------------------------------------------
# Draws
# -------------------------------------------------------------------------------------------


def error_stream(seed: int | None) -> np.random.Generator:
    """The error generator of an episode reset with ``seed`` (fresh entropy for None): separate
    from the initial-state stream of the same seed, so the planned starts are those of the
    env without errors."""
    if seed is None:
        return np.random.default_rng()
    return np.random.default_rng(np.random.SeedSequence(int(seed),
                                                        spawn_key=(_ERROR_STREAM_KEY,)))


@dataclass
class EpisodeErrors:
    """The errors of n episodes (arrays along axis 0), SI.

    Attributes
    ----------
    entry_position_m, entry_velocity_m_s : ndarray (n, 3)
        Start-state errors along (up, downrange, crossrange).
    thrust_scale, isp_scale : ndarray (n,)
        True / nominal thrust and Isp.
    misalignment_rad : ndarray (n, 2)
        Bias of each gimbal angle (planar: the first is φ's).
    mass_error_kg : ndarray (n,)
        True minus planned initial mass.
    nav_position_bias_m, nav_velocity_bias_m_s : ndarray (n, 3)
        Navigation bias at altitude.
    noise_key : ndarray (n,) uint64
        Key of the per-decision navigation noise (:func:`navigation_noise`).
    """

    entry_position_m: np.ndarray
    entry_velocity_m_s: np.ndarray
    thrust_scale: np.ndarray
    isp_scale: np.ndarray
    misalignment_rad: np.ndarray
    mass_error_kg: np.ndarray
    nav_position_bias_m: np.ndarray
    nav_velocity_bias_m_s: np.ndarray
    noise_key: np.ndarray

    @classmethod
    def zeros(cls, n: int) -> EpisodeErrors:
        """No error for n episodes."""
        z3 = np.zeros((n, 3))
        return cls(z3.copy(), z3.copy(), np.ones(n), np.ones(n), np.zeros((n, 2)), np.zeros(n),
                   z3.copy(), z3.copy(), np.zeros(n, dtype=np.uint64))

    def set_row(self, i: int, other: EpisodeErrors) -> None:
        """Row i from the one-row ``other``."""
        for f in fields(self):
            getattr(self, f.name)[i] = getattr(other, f.name)[0]

    def take(self, idx) -> EpisodeErrors:
        """Rows ``idx`` (copies)."""
        return EpisodeErrors(*(np.array(getattr(self, f.name)[idx]) for f in fields(self)))

    def as_dict(self) -> dict[str, np.ndarray]:
        """Field name -> array."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


def draw_errors(model: UncertaintyModel, rng: np.random.Generator) -> EpisodeErrors:
    """One episode's errors from ``rng`` (one row). Always consumes the same draws
    (:data:`N_NORMALS` normals, then one 64-bit key) whatever the σ, so every scale of a model
    sees the same standard-normal draws."""
    z = np.clip(rng.standard_normal(N_NORMALS), -TRUNCATION_SIGMA, TRUNCATION_SIGMA)
    key = rng.integers(0, np.iinfo(np.uint64).max, dtype=np.uint64, endpoint=True)
    m = model
    return EpisodeErrors(
        entry_position_m=(z[0:3] * np.asarray(m.entry_position_m))[None],
        entry_velocity_m_s=(z[3:6] * np.asarray(m.entry_velocity_m_s))[None],
        thrust_scale=np.array([1.0 + z[6] * m.thrust_scale]),
        isp_scale=np.array([1.0 + z[7] * m.isp_scale]),
        misalignment_rad=(z[8:10] * m.misalignment_rad)[None],
        mass_error_kg=np.array([z[10] * m.mass_kg]),
        nav_position_bias_m=(z[11:14] * np.asarray(m.nav_position_bias_m))[None],
        nav_velocity_bias_m_s=(z[14:17] * np.asarray(m.nav_velocity_bias_m_s))[None],
        noise_key=np.array([key], dtype=np.uint64),
    )


# -------------------------------------------------------------------------------------------
# Per-decision navigation noise: counter-based, so it does not depend on the batch
# -------------------------------------------------------------------------------------------

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)


@numba.njit(cache=True)
def _splitmix64(x):  # pragma: no cover  (compiled)
    z = x + _GOLDEN
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    return z ^ (z >> _S31)


_S32 = np.uint64(32)
_LOW32 = np.uint64(0xFFFFFFFF)
_TWO32_INV = 1.0 / 4294967296.0


# Acklam's rational approximation of the normal quantile (relative error < 1.2e-9): the
# central 95 % of draws cost a dozen flops and no transcendental function, which is what keeps
# per-decision noise for thousands of landers cheap next to the integration.
_A = (-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
      1.383577518672690e+02, -3.066479806614716e+01, 2.506628277459239e+00)
_B = (-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
      6.680131188771972e+01, -1.328068155288572e+01)
_C = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
      -2.549732539343734e+00, 4.374664141464968e+00, 2.938163982698783e+00)
_D = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
      3.754408661907416e+00)
_P_LOW = 0.02425

# The compiled noise runs with NumPy's error model: under the default (Python's) every division
# tests its divisor for zero and may raise, a branch that keeps LLVM from vectorising the loops
# (measured: the hash and central-quantile passes run 4-8x faster without it). No divisor here
# can be zero (the quantile's denominators are > 0.3 on their branches, the units are
# positive), so the results are the same to the bit.
_FAST = {"error_model": "numpy"}


@register_jitable(**_FAST)
def _is_tail(p):
    """p lies in a tail of Acklam's algorithm (:func:`_normal_tail`, else
    :func:`_normal_central`)."""
    return p < _P_LOW or p > 1.0 - _P_LOW


@register_jitable(**_FAST)
def _normal_central(p):
    """Φ⁻¹(p) for p in [_P_LOW, 1 - _P_LOW] (Acklam's central rational function)."""
    q = p - 0.5
    r = q * q
    return (((((_A[0] * r + _A[1]) * r + _A[2]) * r + _A[3]) * r + _A[4]) * r + _A[5]) * q \
        / (((((_B[0] * r + _B[1]) * r + _B[2]) * r + _B[3]) * r + _B[4]) * r + 1.0)


@register_jitable(**_FAST)
def _normal_tail(p):
    """Φ⁻¹(p) for p in (0, _P_LOW) or (1 - _P_LOW, 1) (Acklam's tails)."""
    q = math.sqrt(-2.0 * math.log(p if p < 0.5 else 1.0 - p))
    x = ((((( _C[0] * q + _C[1]) * q + _C[2]) * q + _C[3]) * q + _C[4]) * q + _C[5]) \
        / ((((_D[0] * q + _D[1]) * q + _D[2]) * q + _D[3]) * q + 1.0)
    return x if p < 0.5 else -x


@register_jitable(**_FAST)
def _normal_quantile(p):
    """Φ⁻¹(p) for p in (0, 1) (Acklam's algorithm)."""
    return _normal_tail(p) if _is_tail(p) else _normal_central(p)


@register_jitable(**_FAST)
def _truncate(z):
    """A standard normal truncated at ±TRUNCATION_SIGMA."""
    return min(max(z, -TRUNCATION_SIGMA), TRUNCATION_SIGMA)


@register_jitable(**_FAST)
def _standard_normals(keys, counters, z):
    """The navigation noise's standard normals into ``z`` (m, n), component-major (component
    j of lander i at ``z[j, i]``), for noise keys ``keys`` (n,) uint64 at decision indices
    ``counters`` (n,) int64.

    Two normals per 64-bit hash: lander i's hash for components (j, j + 1) (j even) is
    splitmix64(base_i + j + 1) with base_i = splitmix64(key_i ^ splitmix64(counter_i)); each
    32-bit half (high for j, low for j + 1) is a uniform (k + ½)/2³² in (0, 1), mapped through
    the normal quantile (:func:`_normal_quantile`) and truncated at ±TRUNCATION_SIGMA.

    Computed in passes over the whole batch, not per lander, so that LLVM vectorises them: the
    hashes and uniforms, then the central rational function for every draw, then the ~5 % of
    draws in a tail (whose logarithm, if-converted into the vectorised pass, would be paid by
    every draw). Each draw goes through exactly the arithmetic of :func:`_normal_quantile`.
    """
    m, n = z.shape
    base = np.empty(n, dtype=np.uint64)
    for i in range(n):
        base[i] = _splitmix64(keys[i] ^ _splitmix64(np.uint64(counters[i])))
    for j in range(0, m, 2):
        zj = z[j]
        inc = np.uint64(j + 1)
        if j + 1 < m:
            zk = z[j + 1]
            for i in range(n):
                h = _splitmix64(base[i] + inc)
                zj[i] = (np.float64(h >> _S32) + 0.5) * _TWO32_INV
                zk[i] = (np.float64(h & _LOW32) + 0.5) * _TWO32_INV
        else:
            for i in range(n):
                zj[i] = (np.float64(_splitmix64(base[i] + inc) >> _S32) + 0.5) * _TWO32_INV
    u = z.reshape(-1)
    # the tails are found before the central pass overwrites the uniforms
    tails = np.empty(u.shape[0], dtype=np.int64)
    n_tail = 0
    for k in range(u.shape[0]):
        if _is_tail(u[k]):
            tails[n_tail] = k
            n_tail += 1
    p_tail = np.empty(n_tail)
    for t in range(n_tail):
        p_tail[t] = u[tails[t]]
    for k in range(u.shape[0]):
        u[k] = _truncate(_normal_central(u[k]))
    for t in range(n_tail):
        u[tails[t]] = _truncate(_normal_tail(p_tail[t]))


@numba.njit(cache=True, **_FAST)
def _noise_kernel(keys, counters, out):  # pragma: no cover  (compiled)
    """:func:`_standard_normals` into ``out`` (n, m), lander-major."""
    n, m = out.shape
    z = np.empty((m, n))
    _standard_normals(keys, counters, z)
    for i in range(n):
        for j in range(m):
            out[i, j] = z[j, i]


def navigation_noise(keys: np.ndarray, counters: np.ndarray, n_components: int = 6
                     ) -> np.ndarray:
    """Standard normals (n, n_components), truncated at ±4.5, of episodes with noise keys
    ``keys`` (n,) uint64 at decision indices ``counters`` (n,): a pure function of (key,
    counter, component), so a lander's noise does not depend on the batch it flies in, and
    component j is the same whatever ``n_components``. The navigation errors read them
    interleaved: (position up, velocity up, position downrange, velocity downrange, position
    crossrange, velocity crossrange)."""
    out = np.empty((len(keys), int(n_components)))
    _noise_kernel(np.ascontiguousarray(keys, dtype=np.uint64),
                  np.ascontiguousarray(counters, dtype=np.int64), out)
    return out


# inlined into the compiled callers (numba IR inlining): a call to a helper compiled in
# another module is not inlined by LLVM, and pays a reference count increment and decrement per
# array argument, per lander (measured: ~130 ns per lander for the navigation errors' row)
@register_jitable(inline="always")
def _shrink(altitude_m, radar_altitude_m, lock_fraction, floor):
    """The terminal sensors' multiplier of a navigation error at ``altitude_m`` (scalars or
    arrays): 1 above the lock altitude, ``lock_fraction`` × altitude / lock altitude below it,
    never under ``floor``."""
    h = np.maximum(altitude_m / radar_altitude_m, 0.0)
    above = h > 1.0
    return above * 1.0 + (1.0 - above) * np.maximum(lock_fraction * h, floor)


def _navigation_constants(model: UncertaintyModel) -> np.ndarray:
    """The navigation part of ``model`` packed for the compiled kernels
    (:func:`_navigation_error_row`): float64 (10,) = noise σ of position (3, m) and velocity
    (3, m/s), radar lock altitude (m), lock fraction, near-ground position and velocity
    fractions."""
    m = model
    return np.array([*m.nav_position_noise_m, *m.nav_velocity_noise_m_s, m.radar_altitude_m,
                     m.radar_lock_fraction, m.near_ground_position_fraction,
                     m.near_ground_velocity_fraction], dtype=np.float64)


@register_jitable(inline="always", **_FAST)
def _navigation_error_row(z, i, altitude_m, bias_p, bias_v, c, n_axes):
    """Lander i's navigation errors (position up, downrange, crossrange (m), velocity up,
    downrange, crossrange (m/s)) as a 6-tuple, at true altitude ``altitude_m``: (bias + σ ·
    noise) × the radar weight (:func:`_shrink`). ``z``: the decision's normals as
    :func:`_standard_normals` lays them out (interleaved position/velocity per axis, see
    :func:`navigation_noise`); ``bias_p``, ``bias_v`` (n, 3) the episodes' biases; ``c``:
    :func:`_navigation_constants`. ``n_axes`` = 2 leaves the crossrange errors 0 (``z`` then
    needs only 4 rows). Compiled callers only: the per-lander step of every navigation kernel,
    so that the model is written once."""
    wp = _shrink(altitude_m, c[6], c[7], c[8])
    wv = _shrink(altitude_m, c[6], c[7], c[9])
    p0 = wp * (bias_p[i, 0] + z[0, i] * c[0])
    v0 = wv * (bias_v[i, 0] + z[1, i] * c[3])
    p1 = wp * (bias_p[i, 1] + z[2, i] * c[1])
    v1 = wv * (bias_v[i, 1] + z[3, i] * c[4])
    p2 = 0.0
    v2 = 0.0
    if n_axes > 2:
        p2 = wp * (bias_p[i, 2] + z[4, i] * c[2])
        v2 = wv * (bias_v[i, 2] + z[5, i] * c[5])
    return p0, p1, p2, v0, v1, v2


@numba.njit(cache=True, **_FAST)
def _navigation_errors_kernel(keys, counters, altitude_m, bias_p, bias_v, c, n_axes, dpos, dvel
                              ):  # pragma: no cover  (compiled)
    z = np.empty((2 * n_axes, keys.shape[0]))
    _standard_normals(keys, counters, z)
    for i in range(keys.shape[0]):
        e = _navigation_error_row(z, i, altitude_m[i], bias_p, bias_v, c, n_axes)
        for j in range(3):
            dpos[i, j] = e[j]
            dvel[i, j] = e[3 + j]


def navigation_errors(model: UncertaintyModel, errors: EpisodeErrors, counters: np.ndarray,
                      altitude_m: np.ndarray, n_axes: int = 3
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity navigation errors (n, 3) each, along (up, downrange, crossrange)
    (m, m/s), of episodes with ``errors`` at decision indices ``counters`` (n,) and true
    altitudes ``altitude_m`` (n,): (bias + σ_noise · :func:`navigation_noise`) ×
    :func:`radar_weight`, in one compiled call. ``n_axes`` = 2 (a planar task) leaves the
    crossrange components 0 and draws no noise for them."""
    n = len(counters)
    dpos = np.empty((n, 3))
    dvel = np.empty((n, 3))
    _navigation_errors_kernel(np.ascontiguousarray(errors.noise_key, dtype=np.uint64),
                              np.ascontiguousarray(counters, dtype=np.int64),
                              np.ascontiguousarray(altitude_m, dtype=np.float64),
                              errors.nav_position_bias_m, errors.nav_velocity_bias_m_s,
                              _navigation_constants(model), int(n_axes), dpos, dvel)
    return dpos, dvel


def radar_weight(model: UncertaintyModel, altitude_m: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Navigation error multipliers (position, velocity) at ``altitude_m`` (n,) each: 1 above
    the radar's lock altitude; below it ``radar_lock_fraction`` × altitude / lock altitude,
    never under the near-ground fractions."""
    h = np.asarray(altitude_m, dtype=np.float64)
    return (_shrink(h, model.radar_altitude_m, model.radar_lock_fraction,
                    model.near_ground_position_fraction),
            _shrink(h, model.radar_altitude_m, model.radar_lock_fraction,
                    model.near_ground_velocity_fraction))


def episode_errors(model: UncertaintyModel, rng: np.random.Generator, pinned=None,
                   row: int | None = None) -> EpisodeErrors:
    """The errors of an episode starting now: drawn from ``rng`` (:func:`draw_errors`), or the
    ``reset(options={"errors": pinned})`` ones (:func:`errors_from_option`; ``row``: the
    sub-env of a vector env). Drawn even when pinned, so the stream stays where an unpinned
    episode would leave it."""
    drawn = draw_errors(model, rng)
    return drawn if pinned is None else errors_from_option(pinned, row)


def errors_from_option(value, row: int | None = None) -> EpisodeErrors:
    """One episode's errors pinned by ``reset(options={"errors": value})``: a dict of
    :class:`EpisodeErrors` fields (SI; absent fields mean no error: scales 1, the rest 0), each
    a single value or, for a vector env (``row`` given), one value per sub-env along a leading
    axis. Unknown fields, non-finite values and non-positive scales are refused."""
    if not isinstance(value, dict):
        raise InvalidTypeError(f"options['errors'] = {value!r} must be a dict of episode-error "
                               f"fields ({', '.join(f.name for f in fields(EpisodeErrors))})")
    e = EpisodeErrors.zeros(1)
    names = {f.name for f in fields(EpisodeErrors)}
    unknown = sorted(set(value) - names)
    if unknown:
        raise ValueError(f"options['errors'] has unknown field(s) {', '.join(map(repr, unknown))};"
                         f" allowed: {', '.join(sorted(names))}")
    for k, v in value.items():
        target = getattr(e, k)
        arr = np.asarray(v, dtype=np.uint64 if k == "noise_key" else np.float64)
        want = target.shape[1:]
        if row is not None and arr.shape[1:] == want and arr.ndim == len(want) + 1:
            arr = arr[row]
        if arr.shape != want:
            raise ValueError(f"options['errors'][{k!r}] has shape {arr.shape}; expected {want}"
                             + ("" if row is None else f" or (num_envs, *{want})"))
        if k != "noise_key" and not np.all(np.isfinite(arr)):
            raise ValueError(f"options['errors'][{k!r}] = {v!r} is not finite")
        if k in ("thrust_scale", "isp_scale") and not arr > 0.0:
            raise ValueError(f"options['errors'][{k!r}] = {v!r} must be > 0 (a scale factor)")
        target[0] = arr
    return e
