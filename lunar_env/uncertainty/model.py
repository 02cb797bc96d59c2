"""The uncertainty model's specification: :class:`UncertaintyModel`, its σ limits and the named
sets (see :mod:`lunar_env.uncertainty` for what each error does in an episode)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields
from typing import Any, NamedTuple

import numpy as np

from ..validation import InvalidTypeError, require_number
from .navigation import _weights

__all__ = ["UncertaintyModel", "SIGMA_LIMITS", "NAMED_SETS", "get_uncertainty",
           "resolve_uncertainty", "MODEL_VERSION"]

#: version of what a model's fields mean and how the envs draw and apply them: results flown
#: under another version are other results (a campaign's store records it and refuses to mix
#: them); raised by any change to the draws, their truncation or their effect on an episode
MODEL_VERSION = 1


class _Limit(NamedTuple):
    """An exclusive upper limit of a 1σ field, its unit and the reason for it."""

    value: float
    unit: str
    reason: str


# The limits and their reasons (the table in UncertaintyModel's docstring says the same).
_POSITION = _Limit(50_000.0, "m", "offsets along straight local axes, a model of dispersions "
                   "small next to the Moon's radius; orbit determination gives ~1 km")
_VELOCITY = _Limit(100.0, "m/s", "5 % of a descent's delta-v from lunar orbit, more than any "
                   "lander's propellant margin absorbs")
_ENGINE_SCALE = _Limit(0.2, "", "the engine keeps a positive thrust and Isp within the "
                       "truncation: 1 - 4.5 × 0.2 = 0.1")
_NAV_POSITION = _Limit(50_000.0, "m", "navigation off by more is lost, not in error; offsets "
                       "along straight local axes")
_LIMITS: dict[str, _Limit] = {
    "entry_position_m": _POSITION,
    "entry_velocity_m_s": _VELOCITY,
    "thrust_scale": _ENGINE_SCALE,
    "isp_scale": _ENGINE_SCALE,
    "misalignment_rad": _Limit(0.2, "rad", "a small-angle gimbal bias (11°); more is a broken "
                               "mount"),
    "mass_kg": _Limit(1000.0, "kg", "10 % of a 10 t lander, ten times what propellant gauging "
                      "leaves unknown"),
    "nav_position_bias_m": _NAV_POSITION,
    "nav_velocity_bias_m_s": _VELOCITY,
    "nav_position_noise_m": _NAV_POSITION,
    "nav_velocity_noise_m_s": _VELOCITY,
}

#: exclusive upper limit of each 1σ field of :class:`UncertaintyModel` (the field's unit; a
#: vector's limit holds for each component); the reasons are in the class docstring
SIGMA_LIMITS: dict[str, float] = {k: v.value for k, v in _LIMITS.items()}

_VECTORS = ("entry_position_m", "entry_velocity_m_s", "nav_position_bias_m",
            "nav_velocity_bias_m_s", "nav_position_noise_m", "nav_velocity_noise_m_s")
_SCALARS = ("thrust_scale", "isp_scale", "misalignment_rad", "mass_kg")
_FRACTIONS = ("radar_lock_fraction", "near_ground_position_fraction",
              "near_ground_velocity_fraction")


def _sigma(field: str, label: str, value) -> float:
    """``value`` of the 1σ field ``field`` (``label``: the name in messages, e.g.
    ``entry_position_m[1]``) as a float, within [0, its limit)."""
    v = require_number(f"UncertaintyModel.{label}", value)
    limit = _LIMITS[field]
    if not (math.isfinite(v) and 0.0 <= v < limit.value):
        unit = f" {limit.unit}" if limit.unit else ""
        raise ValueError(f"UncertaintyModel.{label} = {value!r} is not allowed; a 1σ error must "
                         f"be finite, >= 0 and < {limit.value:g}{unit} ({limit.reason})")
    return v


def _vec3(name: str, value) -> tuple[float, float, float]:
    try:
        items = tuple(value)
    except TypeError:
        raise InvalidTypeError(f"UncertaintyModel.{name} = {value!r} is not a sequence of 3 "
                               "numbers (up, downrange, crossrange)") from None
    if len(items) != 3:
        raise ValueError(f"UncertaintyModel.{name} = {value!r} has {len(items)} components; "
                         "3 are required (up, downrange, crossrange)")
    return tuple(_sigma(name, f"{name}[{i}]", v) for i, v in enumerate(items))


@dataclass(frozen=True)
class UncertaintyModel:
    """1σ errors of the plant and of navigation (SI; see :mod:`lunar_env.uncertainty`).

    Attributes
    ----------
    name : str
        Label in reports (``"custom"`` for a user's set).
    entry_position_m, entry_velocity_m_s : (float, float, float)
        Start-state errors along (up, downrange, crossrange) (m, m/s). The planar env has no
        crossrange: its third component is ignored.
    thrust_scale, isp_scale : float
        Relative 1σ errors of the maximum thrust and of the specific impulse.
    misalignment_rad : float
        1σ bias of each gimbal angle (rad), fixed per episode.
    mass_kg : float
        1σ error of the initial wet mass (kg).
    nav_position_bias_m, nav_velocity_bias_m_s : (float, float, float)
        1σ navigation bias per episode, at altitude (m, m/s).
    nav_position_noise_m, nav_velocity_noise_m_s : (float, float, float)
        1σ navigation white noise per decision, at altitude (m, m/s).
    radar_altitude_m : float
        Altitude (m) at which the terminal sensors lock (finite, > 0; no upper limit: an
        altitude above the start means they never lock, as the default 1e9 m).
    radar_lock_fraction : float
        Multiplier of the navigation errors at lock, in [0, 1]; below the lock altitude it
        falls in proportion to the altitude (:meth:`radar_weight`).
    near_ground_position_fraction, near_ground_velocity_fraction : float
        Floors of the position and velocity multipliers (the sensors' accuracy near the
        ground, as fractions of the errors at altitude), in [0, 1].

    Notes
    -----
    Every σ is finite, >= 0 and below its limit (:data:`SIGMA_LIMITS`; for a vector, each
    component), checked here, so that a model that cannot be flown is refused when it is
    built, not at the first reset. The limits are generous on purpose: they refuse what is no
    longer an error of the same descent, and a model 10 × ``stress`` passes them in every
    field but the engine's two scales, whose limit is physical.

    ======================================  ===========  =======================================
    Field                                   Limit (1σ)   Reason
    ======================================  ===========  =======================================
    ``entry_position_m``                    < 50 km      offsets along straight local axes, a
                                                         model of dispersions small next to the
                                                         Moon's radius (at 50 km the axes leave
                                                         the sphere by 0.7 km); orbit
                                                         determination gives ~1 km
    ``entry_velocity_m_s``                  < 100 m/s    5 % of a descent's ~2 km/s delta-v from
                                                         lunar orbit: more than any lander's
                                                         propellant margin absorbs
    ``thrust_scale``, ``isp_scale``         < 0.2        a positive thrust and Isp within the
                                                         truncation (1 - 4.5 × 0.2 = 0.1)
    ``misalignment_rad``                    < 0.2 rad    a small-angle gimbal bias (11°); more
                                                         is a broken mount
    ``mass_kg``                             < 1000 kg    10 % of a 10 t lander, ten times what
                                                         propellant gauging leaves unknown
    ``nav_position_bias_m``,                < 50 km      navigation off by more is lost, not in
    ``nav_position_noise_m``                             error (offsets along local axes, as the
                                                         entry errors)
    ``nav_velocity_bias_m_s``,              < 100 m/s    as ``entry_velocity_m_s``
    ``nav_velocity_noise_m_s``
    ======================================  ===========  =======================================

    A model within the limits may still be refused by a task (the vehicle and the start are
    the scenario's, not the model's): when the task is built, a ``mass_kg`` whose truncated
    draw (±:data:`~lunar_env.uncertainty.TRUNCATION_SIGMA` σ) reaches the dry mass from the
    lightest start; at reset, a draw that puts a start at or below the terminal radius.

    :data:`MODEL_VERSION` numbers what the fields mean and how they are drawn and applied.

    Raises
    ------
    ValueError
        (or :class:`~lunar_env.validation.InvalidTypeError`) naming the field, its value and
        what is allowed.
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
        for f in _SCALARS:
            object.__setattr__(self, f, _sigma(f, f, getattr(self, f)))
        r = require_number("UncertaintyModel.radar_altitude_m", self.radar_altitude_m)
        if not (math.isfinite(r) and r > 0.0):
            raise ValueError(f"UncertaintyModel.radar_altitude_m = {self.radar_altitude_m!r} is "
                             "not allowed; it must be finite and > 0 (m)")
        object.__setattr__(self, "radar_altitude_m", r)
        for name in _FRACTIONS:
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
        kept); named ``"<name>×k"``. ``scaled(0)`` has no error at all. A scale that takes a
        σ to its limit (:data:`SIGMA_LIMITS`) raises ValueError naming the field."""
        k = require_number("scale", k)
        if not (math.isfinite(k) and k >= 0.0):
            raise ValueError(f"scale = {k!r} is not allowed; it must be finite and >= 0")
        ch: dict[str, Any] = {f: tuple(k * v for v in getattr(self, f)) for f in _VECTORS}
        for f in _SCALARS:
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

    def radar_weight(self, altitude_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Navigation error multipliers (position, velocity), each shaped as ``altitude_m``
        (m): 1 above the radar's lock altitude; below it ``radar_lock_fraction`` × altitude /
        lock altitude, never under the near-ground fractions (the arithmetic of the compiled
        :func:`~lunar_env.uncertainty.navigation.navigation_error`)."""
        return _weights(altitude_m, self.radar_altitude_m, self.radar_lock_fraction,
                        self.near_ground_position_fraction, self.near_ground_velocity_fraction)

    def navigation_constants(self) -> np.ndarray:
        """The navigation part of the model packed for the compiled kernels
        (:func:`~lunar_env.uncertainty.navigation.navigation_error`): float64 (10,) = noise σ of
        position (3, m) and velocity (3, m/s) along (up, downrange, crossrange), radar lock
        altitude (m), lock fraction, near-ground position and velocity fractions."""
        return np.array([*self.nav_position_noise_m, *self.nav_velocity_noise_m_s,
                         self.radar_altitude_m, self.radar_lock_fraction,
                         self.near_ground_position_fraction,
                         self.near_ground_velocity_fraction], dtype=np.float64)


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
