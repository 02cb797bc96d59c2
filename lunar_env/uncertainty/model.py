"""The uncertainty model's specification: :class:`UncertaintyModel`, its σ limits and the named
sets (see :mod:`lunar_env.uncertainty` for what each error does in an episode)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields
from typing import Any, NamedTuple

import numpy as np

from ..validation import InvalidTypeError, require_number
from .navigation import blend_weight

__all__ = ["UncertaintyModel", "SIGMA_LIMITS", "NAMED_SETS", "GROUPS", "MODEL_VERSION",
           "get_uncertainty", "resolve_uncertainty"]

#: version of the uncertainty model's meaning (its fields and how an episode draws and applies
#: them); recorded by campaigns, whose stores refuse results of another version. 2: terminal
#: sensors with errors of their own after acquisition, and the IMU (1: navigation errors
#: scaled down below a radar lock altitude).
MODEL_VERSION = 2


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
_FRACTION = _Limit(0.5, "", "a range sensor wrong by half its range has not acquired the "
                   "ground")
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
    "sensor_position_fraction": _FRACTION,
    "sensor_position_noise_fraction": _FRACTION,
    "sensor_position_floor_m": _Limit(1000.0, "m", "a terrain map off by more is another "
                                      "landing site"),
    "sensor_velocity_bias_m_s": _VELOCITY,
    "sensor_velocity_noise_m_s": _VELOCITY,
    "imu_bias_m_s2": _Limit(1.0, "m/s²", "0.1 g: a hundred times a tactical-grade "
                            "accelerometer's bias; more is a failed sensor"),
    "imu_scale_factor": _Limit(0.2, "", "as the engine scales: a positive gain within the "
                               "truncation"),
    "imu_vrw_m_s_sqrt_s": _Limit(1.0, "m/s/√s", "a hundred times a tactical-grade "
                                 "accelerometer's velocity random walk"),
}

#: exclusive upper limit of each 1σ field of :class:`UncertaintyModel` (the field's unit; a
#: vector's limit holds for each component); the reasons are in the class docstring
SIGMA_LIMITS: dict[str, float] = {k: v.value for k, v in _LIMITS.items()}

_VECTORS = ("entry_position_m", "entry_velocity_m_s", "nav_position_bias_m",
            "nav_velocity_bias_m_s", "nav_position_noise_m", "nav_velocity_noise_m_s",
            "sensor_position_fraction", "sensor_position_noise_fraction",
            "sensor_position_floor_m", "sensor_velocity_bias_m_s", "sensor_velocity_noise_m_s")
_SCALARS = ("thrust_scale", "isp_scale", "misalignment_rad", "mass_kg", "imu_bias_m_s2",
            "imu_scale_factor", "imu_vrw_m_s_sqrt_s")

#: the error groups (a named set isolates each, :meth:`UncertaintyModel.only`; a leave-one-out
#: study drops one, :meth:`UncertaintyModel.without`): the state at powered-descent initiation,
#: the engine and the vehicle's mass, navigation before the terminal sensors acquire, and the
#: sensors (the terminal sensors' own errors and the IMU's)
GROUPS: dict[str, tuple[str, ...]] = {
    "entry": ("entry_position_m", "entry_velocity_m_s"),
    "engine": ("thrust_scale", "isp_scale", "misalignment_rad", "mass_kg"),
    "navigation": ("nav_position_bias_m", "nav_velocity_bias_m_s", "nav_position_noise_m",
                   "nav_velocity_noise_m_s"),
    "sensors": ("sensor_position_fraction", "sensor_position_noise_fraction",
                "sensor_position_floor_m", "sensor_velocity_bias_m_s",
                "sensor_velocity_noise_m_s", "imu_bias_m_s2", "imu_scale_factor",
                "imu_vrw_m_s_sqrt_s"),
}


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
        1σ navigation white noise per decision, before the terminal sensors acquire (m, m/s).
    sensor_altitude_m : float
        Altitude (m) at which the terminal sensors (altimeter and velocimeter: a landing radar
        or Doppler lidar, with terrain-relative navigation for the horizontal position)
        acquire the ground (finite, >= 0; the default 0: the lander has none, and navigation
        keeps the inertial solution's errors to the ground).
    sensor_blend_fraction : float
        The navigation filter's hand-over: over the altitudes from ``sensor_altitude_m`` down
        by this fraction of it, the error blends linearly from the inertial solution's to the
        terminal sensors' (:meth:`sensor_weight`); in (0, 1].
    sensor_position_fraction : (float, float, float)
        1σ error per episode of the terminal sensors' position along (up, downrange,
        crossrange), as a fraction of the altitude (a range sensor's error is a fraction of
        its range; the horizontal one is terrain-relative navigation's).
    sensor_position_noise_fraction : (float, float, float)
        1σ noise per decision of the same, as a fraction of the altitude.
    sensor_position_floor_m : (float, float, float)
        1σ error per episode that does not shrink with the altitude (m): the terrain map's.
    sensor_velocity_bias_m_s, sensor_velocity_noise_m_s : (float, float, float)
        1σ error per episode and noise per decision of the velocimeter (m/s).
    imu_bias_m_s2 : float
        1σ accelerometer bias per axis per episode (m/s²).
    imu_scale_factor : float
        1σ accelerometer scale-factor error per episode (relative).
    imu_vrw_m_s_sqrt_s : float
        Accelerometer velocity random walk (m/s/√s): the noise of a decision's mean specific
        force is this over √dt.

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
    ``sensor_position_fraction``,           < 0.5        a range sensor wrong by half its range
    ``sensor_position_noise_fraction``                   has not acquired the ground
    ``sensor_position_floor_m``             < 1000 m     a terrain map off by more is another
                                                         landing site
    ``sensor_velocity_bias_m_s``,           < 100 m/s    as ``entry_velocity_m_s``
    ``sensor_velocity_noise_m_s``
    ``imu_bias_m_s2``                       < 1 m/s²     0.1 g, a hundred times a
                                                         tactical-grade accelerometer's bias
    ``imu_scale_factor``                    < 0.2        a positive gain within the truncation
    ``imu_vrw_m_s_sqrt_s``                  < 1 m/s/√s   a hundred times a tactical-grade
                                                         accelerometer's
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
    sensor_altitude_m: float = 0.0
    sensor_blend_fraction: float = 0.1
    sensor_position_fraction: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sensor_position_noise_fraction: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sensor_position_floor_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sensor_velocity_bias_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sensor_velocity_noise_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    imu_bias_m_s2: float = 0.0
    imu_scale_factor: float = 0.0
    imu_vrw_m_s_sqrt_s: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise InvalidTypeError(f"UncertaintyModel.name = {self.name!r} must be a non-empty "
                                   "string")
        for f in _VECTORS:
            object.__setattr__(self, f, _vec3(f, getattr(self, f)))
        for f in _SCALARS:
            object.__setattr__(self, f, _sigma(f, f, getattr(self, f)))
        r = require_number("UncertaintyModel.sensor_altitude_m", self.sensor_altitude_m)
        if not (math.isfinite(r) and r >= 0.0):
            raise ValueError(f"UncertaintyModel.sensor_altitude_m = {self.sensor_altitude_m!r} "
                             "is not allowed; it must be finite and >= 0 (m; 0: no terminal "
                             "sensors)")
        object.__setattr__(self, "sensor_altitude_m", r)
        b = require_number("UncertaintyModel.sensor_blend_fraction", self.sensor_blend_fraction)
        if not 0.0 < b <= 1.0:
            raise ValueError(f"UncertaintyModel.sensor_blend_fraction = "
                             f"{self.sensor_blend_fraction!r} is not allowed; it must be in "
                             "(0, 1]")
        object.__setattr__(self, "sensor_blend_fraction", b)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> UncertaintyModel:
        """From a dict of fields; ``"base": NAME`` starts from a named set and ``"scale": k``
        multiplies every σ (applied after the other fields). Unknown keys are refused."""
        if not isinstance(d, dict):
            raise InvalidTypeError(f"uncertainty settings {d!r} must be a dict")
        d = dict(d)
        base = d.pop("base", None)
        scale = d.pop("scale", None)
        only = d.pop("only", None)
        without = d.pop("without", None)
        allowed = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - allowed)
        if unknown:
            raise ValueError(f"unknown uncertainty setting(s) {', '.join(map(repr, unknown))}; "
                             f"allowed: base, scale, only, without, "
                             f"{', '.join(sorted(allowed))}")
        model = get_uncertainty(base) if base is not None else cls()
        if d:
            model = model.replace(**({"name": "custom"} | d))
        if only is not None:
            model = model.only(*([only] if isinstance(only, str) else only))
        if without is not None:
            model = model.without(*([without] if isinstance(without, str) else without))
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

    def _zeroed(self, names, label: str) -> UncertaintyModel:
        ch: dict[str, Any] = {f: (0.0, 0.0, 0.0) if f in _VECTORS else 0.0 for f in names}
        return dataclasses.replace(self, name=label, **ch)

    def only(self, *groups: str) -> UncertaintyModel:
        """The errors of ``groups`` (of :data:`GROUPS`) alone, every other σ zero; named
        ``"<name>[only a+b]"``. ``ValueError`` naming an unknown group."""
        _check_groups(groups)
        drop = [f for g, names in GROUPS.items() if g not in groups for f in names]
        return self._zeroed(drop, f"{self.name}[only {'+'.join(groups)}]")

    def without(self, *groups: str) -> UncertaintyModel:
        """Every error but those of ``groups`` (of :data:`GROUPS`; a leave-one-out study);
        named ``"<name>[without a+b]"``. ``ValueError`` naming an unknown group."""
        _check_groups(groups)
        drop = [f for g in groups for f in GROUPS[g]]
        return self._zeroed(drop, f"{self.name}[without {'+'.join(groups)}]")

    def scaled(self, k: float) -> UncertaintyModel:
        """Every σ multiplied by ``k`` >= 0 (the sensors' acquisition altitude and hand-over
        are kept); named ``"<name>×k"``. ``scaled(0)`` has no error at all. A scale that takes a
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
                and all(getattr(self, f) == 0.0 for f in _SCALARS))

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields (lists for the vectors)."""
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v)
                for f in fields(self)}

    def sensor_weight(self, altitude_m: np.ndarray) -> np.ndarray:
        """The weight of the inertial solution's error at ``altitude_m`` (m), shaped as it: 1
        above the terminal sensors' acquisition altitude, 0 below the hand-over band, linear in
        between; the terminal sensors' error has weight 1 − w (the arithmetic of the compiled
        :func:`~lunar_env.uncertainty.navigation.navigation_error`)."""
        return blend_weight(np.asarray(altitude_m, dtype=np.float64), self.sensor_altitude_m,
                            self.sensor_blend_fraction)

    def navigation_constants(self) -> np.ndarray:
        """The navigation part of the model packed for the compiled kernels
        (:func:`~lunar_env.uncertainty.navigation.navigation_error`): float64 (14,) = the
        inertial solution's noise σ of position (3, m) and velocity (3, m/s) along (up,
        downrange, crossrange), the acquisition altitude (m), the hand-over fraction, and the
        terminal sensors' noise: position (3, fraction of the altitude), velocity (3, m/s)."""
        return np.array([*self.nav_position_noise_m, *self.nav_velocity_noise_m_s,
                         self.sensor_altitude_m, self.sensor_blend_fraction,
                         *self.sensor_position_noise_fraction,
                         *self.sensor_velocity_noise_m_s], dtype=np.float64)


def _check_groups(groups) -> None:
    if not groups:
        raise ValueError(f"name at least one error group; groups: {', '.join(GROUPS)}")
    for g in groups:
        if g not in GROUPS:
            raise ValueError(f"unknown error group {g!r}; groups: {', '.join(GROUPS)}")


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
    # The terminal sensors: an altimeter and velocimeter (a landing radar or a Doppler lidar)
    # and terrain-relative navigation for the horizontal position. Their errors are their own
    # once they have acquired: a range sensor's error is a fraction of its range.
    # - Acquisition at 5 km: the Doppler lidar of NASA's NDL class operates "from over five
    #   kilometers altitude" (Amzajerdian et al., NASA NTRS 20160010177; flown on IM-1).
    #   Apollo's landing radar gave altitude from ~12 km (40 000 ft); 5 km is the lidar's.
    sensor_altitude_m=5000.0,
    # - Hand-over over 10 % of the acquisition altitude (500 m, 5–10 s of descent): a choice,
    #   the navigation filter's convergence over a few updates of a new measurement type.
    sensor_blend_fraction=0.1,
    # - Position: the range error 0.1 % of the altitude per episode (5 m at 5 km: IM-1's NDL
    #   matched its reconstructed trajectory to ~5 m, NASA NTRS 20250010290); horizontally,
    #   terrain-relative navigation to 1 % of the altitude (40 m from 4.2 km, Mars 2020's
    #   Lander Vision System requirement); a terrain-map floor of 0.5 m up and 3 m across
    #   (SLIM's vision navigation held its landing point to ~3–4 m, JAXA).
    sensor_position_fraction=(0.001, 0.01, 0.01),
    # - Position noise per decision: that of the navigation solution, not of a raw range. The
    #   filter carries the position on the velocimeter between fixes, so from one decision to
    #   the next it scatters by about the velocity error over the interval (5 cm/s × 2 s =
    #   0.1 m), not by the few metres of a single lidar range: 2e-5 of the altitude up and
    #   5e-5 across (0.1 / 0.25 m at 5 km). Measured: a raw-range scatter (5e-4 / 2e-3 of the
    #   altitude) is amplified by the explicit laws' position gain as t_go -> 0 and lands
    #   Apollo on 15 of the first 100 pinpoint v2 cases instead of 55.
    sensor_position_noise_fraction=(2.0e-5, 5.0e-5, 5.0e-5),
    sensor_position_floor_m=(0.5, 3.0, 3.0),
    # - Velocity: "a few cm/sec" precision of the NDL class (Amzajerdian et al.): 5 cm/s of
    #   bias per episode and of noise per decision, per axis.
    sensor_velocity_bias_m_s=(0.05, 0.05, 0.05),
    sensor_velocity_noise_m_s=(0.05, 0.05, 0.05),
    # The IMU's accelerometers (the specific force every lander measures). Bias 0.001 m/s²
    # (~100 µg): Apollo's mission rules updated the LM's PIPA bias beyond 0.003 ft/s² (Apollo
    # Data Priority memo 69-PA-T-72A, 1969; "accelerometer bias is one of the two most
    # undesirable LM IMU errors" during descent). Scale factor 100 ppm and velocity random walk
    # 3e-4 m/s/√s (0.02 m/s/√h): choices at the level of a tactical-grade unit, an order
    # better than consumer MEMS (~1e-3 m/s/√s).
    imu_bias_m_s2=0.001,
    imu_scale_factor=1.0e-4,
    imu_vrw_m_s_sqrt_s=3.0e-4,
)

#: named uncertainty sets: ``none``, ``standard``, ``stress`` (3 × standard), and one per
#: error group of :data:`GROUPS` with ``standard``'s values of that group alone (``entry``,
#: ``engine``, ``navigation``, ``sensors``)
NAMED_SETS: dict[str, UncertaintyModel] = {
    "none": UncertaintyModel(name="none"),
    "standard": _STANDARD,
    "stress": dataclasses.replace(_STANDARD.scaled(3.0), name="stress"),
    **{g: dataclasses.replace(_STANDARD.only(g), name=g) for g in GROUPS},
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
