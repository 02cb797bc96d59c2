"""The errors of an episode: :class:`EpisodeErrors`, drawn once per episode from a stream of
its own (:func:`error_stream`), and the methods by which they act on a lander (its true start,
its plant's parameters, its gimbal angles, its navigation errors)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, fields
from typing import Any

import numba
import numpy as np

from ..validation import InvalidTypeError
from ._random import TRUNCATION_SIGMA
from .model import UncertaintyModel
from .navigation import EPISODE_SALT, _errors, navigation_noise

__all__ = ["EpisodeErrors", "error_stream", "N_NORMALS"]

#: standard normals drawn per episode, in this order: entry position (3), entry velocity (3),
#: thrust, Isp, misalignment (2), wet mass, navigation position bias (3), velocity bias (3)
N_NORMALS = 17
#: spawn key separating the error stream from the env's initial-state stream of the same seed
_ERROR_STREAM_KEY = 0x5EED_E770


def error_stream(seed: int | None) -> np.random.Generator:
    """The error generator of an episode reset with ``seed`` (fresh entropy for None): separate
    from the initial-state stream of the same seed, so the planned starts are those of the
    env without errors."""
    if seed is None:
        return np.random.default_rng()
    return np.random.default_rng(np.random.SeedSequence(int(seed),
                                                        spawn_key=(_ERROR_STREAM_KEY,)))


@numba.njit(cache=True)
def _misaligned(controls, bias, n_angles, out):  # pragma: no cover  (compiled)
    """``controls`` (k, nu) with the gimbal-angle biases ``bias`` (k, >= n_angles) (rad) added to
    their first ``n_angles`` channels, into ``out`` (allocated by the caller): one compiled
    loop instead of a copy, a slice and an in-place add per step."""
    for i in range(controls.shape[0]):
        for j in range(controls.shape[1]):
            out[i, j] = controls[i, j] + bias[i, j] if j < n_angles else controls[i, j]


def sensor_normals(keys: np.ndarray) -> np.ndarray:
    """The sensors' per-episode standard normals (n, 14), truncated at ±4.5, of episodes with
    navigation noise keys ``keys`` (n,): counter-based normals of a key of their own (the
    keys XOR :data:`~lunar_env.uncertainty.navigation.EPISODE_SALT`, counter 0). Columns: the
    terminal sensors' position fraction (3), floor (3), velocity bias (3); the accelerometers'
    bias (3) and scale factor (1); one spare."""
    k = np.ascontiguousarray(keys, dtype=np.uint64) ^ EPISODE_SALT
    return navigation_noise(k, np.zeros(len(k), dtype=np.int64), 14)


def _sensor_draws(model: UncertaintyModel, keys: np.ndarray) -> dict[str, np.ndarray]:
    z = sensor_normals(keys)
    m = model
    return {"sensor_position_fraction": z[:, 0:3] * np.asarray(m.sensor_position_fraction),
            "sensor_position_floor_m": z[:, 3:6] * np.asarray(m.sensor_position_floor_m),
            "sensor_velocity_bias_m_s": z[:, 6:9] * np.asarray(m.sensor_velocity_bias_m_s),
            "imu_bias_m_s2": z[:, 9:12] * m.imu_bias_m_s2,
            "imu_scale": 1.0 + z[:, 12] * m.imu_scale_factor}


@dataclass
class EpisodeErrors:
    """The errors of n episodes (arrays along axis 0), SI.

    Build them with :meth:`draw` (from a model and a generator), :meth:`from_option` (pinned
    by ``reset(options={"errors": ...})``), :meth:`for_reset` (either, as a reset does) or
    :meth:`zeros`. They act on a lander through :meth:`true_start`, :meth:`plant_params`,
    :meth:`misaligned` and :meth:`navigation_errors`.

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
        The inertial solution's navigation bias.
    noise_key : ndarray (n,) uint64
        Key of the per-decision navigation noise
        (:func:`~lunar_env.uncertainty.navigation_noise`); the terminal sensors' and the IMU's
        keys and per-episode draws derive from it (streams of their own).
    sensor_position_fraction : ndarray (n, 3)
        The terminal sensors' position error, a fraction of the altitude (up, downrange,
        crossrange).
    sensor_position_floor_m : ndarray (n, 3)
        Their position error that does not shrink with the altitude (m).
    sensor_velocity_bias_m_s : ndarray (n, 3)
        The velocimeter's bias (m/s).
    imu_bias_m_s2 : ndarray (n, 3)
        The accelerometers' bias along the guidance frame's axes (horizontal..., up) (m/s²).
    imu_scale : ndarray (n,)
        The accelerometers' gain (1 + scale-factor error).
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
    sensor_position_fraction: np.ndarray
    sensor_position_floor_m: np.ndarray
    sensor_velocity_bias_m_s: np.ndarray
    imu_bias_m_s2: np.ndarray
    imu_scale: np.ndarray

    # -- construction ---------------------------------------------------------------------------
    @classmethod
    def zeros(cls, n: int) -> EpisodeErrors:
        """No error for n episodes."""
        z3 = np.zeros((n, 3))
        return cls(z3.copy(), z3.copy(), np.ones(n), np.ones(n), np.zeros((n, 2)), np.zeros(n),
                   z3.copy(), z3.copy(), np.zeros(n, dtype=np.uint64), z3.copy(), z3.copy(),
                   z3.copy(), z3.copy(), np.ones(n))

    @classmethod
    def draw(cls, model: UncertaintyModel, rng: np.random.Generator) -> EpisodeErrors:
        """One episode's errors under ``model`` from ``rng`` (one row). Always consumes the
        same draws (:data:`N_NORMALS` normals truncated at ±:data:`~lunar_env.uncertainty.
        TRUNCATION_SIGMA`, then one 64-bit key) whatever the σ, so every scale of a model sees
        the same standard-normal draws. The sensors' per-episode errors are normals of a
        counter-based stream of that key (:func:`sensor_normals`): a stream of their own, so
        the other draws are those of a model without sensors."""
        z = np.clip(rng.standard_normal(N_NORMALS), -TRUNCATION_SIGMA, TRUNCATION_SIGMA)
        key = rng.integers(0, np.iinfo(np.uint64).max, dtype=np.uint64, endpoint=True)
        m = model
        return cls(
            entry_position_m=(z[0:3] * np.asarray(m.entry_position_m))[None],
            entry_velocity_m_s=(z[3:6] * np.asarray(m.entry_velocity_m_s))[None],
            thrust_scale=np.array([1.0 + z[6] * m.thrust_scale]),
            isp_scale=np.array([1.0 + z[7] * m.isp_scale]),
            misalignment_rad=(z[8:10] * m.misalignment_rad)[None],
            mass_error_kg=np.array([z[10] * m.mass_kg]),
            nav_position_bias_m=(z[11:14] * np.asarray(m.nav_position_bias_m))[None],
            nav_velocity_bias_m_s=(z[14:17] * np.asarray(m.nav_velocity_bias_m_s))[None],
            noise_key=np.array([key], dtype=np.uint64),
            **_sensor_draws(m, np.array([key], dtype=np.uint64)),
        )

    def with_sensor_draws(self, model: UncertaintyModel) -> EpisodeErrors:
        """These errors with the sensors' per-episode errors under ``model`` drawn from each
        row's noise key (:func:`sensor_normals`); a copy."""
        out = self.take(np.arange(len(self.noise_key)))
        for k, v in _sensor_draws(model, self.noise_key).items():
            setattr(out, k, v)
        return out

    @classmethod
    def from_option(cls, value: dict[str, Any], row: int | None = None) -> EpisodeErrors:
        """One episode's errors pinned by ``reset(options={"errors": value})``: a dict of
        fields (SI; absent fields mean no error: scales 1, the rest 0), each a single value
        or, for a vector env (``row`` given), one value per sub-env along a leading axis.

        Raises
        ------
        ValueError
            (or :class:`~lunar_env.validation.InvalidTypeError`) for unknown fields, wrong
            shapes, non-finite values and non-positive scales, naming the field.
        """
        if not isinstance(value, dict):
            raise InvalidTypeError(f"options['errors'] = {value!r} must be a dict of "
                                   "episode-error fields "
                                   f"({', '.join(f.name for f in fields(cls))})")
        e = cls.zeros(1)
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(value) - names)
        if unknown:
            raise ValueError(f"options['errors'] has unknown field(s) "
                             f"{', '.join(map(repr, unknown))}; allowed: "
                             f"{', '.join(sorted(names))}")
        for k, v in value.items():
            target = getattr(e, k)
            arr = np.asarray(v, dtype=np.uint64 if k == "noise_key" else np.float64)
            want = target.shape[1:]
            if row is not None and arr.shape[1:] == want and arr.ndim == len(want) + 1:
                arr = arr[row]
            if arr.shape != want:
                raise ValueError(f"options['errors'][{k!r}] has shape {arr.shape}; expected "
                                 f"{want}" + ("" if row is None else f" or (num_envs, *{want})"))
            if k != "noise_key" and not np.all(np.isfinite(arr)):
                raise ValueError(f"options['errors'][{k!r}] = {v!r} is not finite")
            if k in ("thrust_scale", "isp_scale", "imu_scale") and not arr > 0.0:
                raise ValueError(f"options['errors'][{k!r}] = {v!r} must be > 0 (a scale "
                                 "factor)")
            target[0] = arr
        return e

    @classmethod
    def for_reset(cls, model: UncertaintyModel, rng: np.random.Generator,
                  pinned: dict[str, Any] | None = None, row: int | None = None
                  ) -> EpisodeErrors:
        """The errors of an episode starting now: drawn from ``rng`` (:meth:`draw`), or the
        ``reset(options={"errors": pinned})`` ones (:meth:`from_option`; ``row``: the sub-env
        of a vector env). Drawn even when pinned, so the stream stays where an unpinned
        episode would leave it."""
        drawn = cls.draw(model, rng)
        return drawn if pinned is None else cls.from_option(pinned, row)

    # -- rows -------------------------------------------------------------------------------------
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

    # -- what the errors do -----------------------------------------------------------------------
    def true_start(self, task: Any, y_planned_nd: np.ndarray) -> np.ndarray:
        """The true initial states (k, n_state) of episodes planned to start at
        ``y_planned_nd`` (k, n_state) (normalised) of ``task`` (a
        :class:`~lunar_env.envs.task.LandingTask`), for these k rows: the entry errors and the
        wet-mass error added by the task's
        :meth:`~lunar_env.envs.task.LandingTask.offset_states`.

        Raises
        ------
        ValueError
            If an error puts a start at or below the terminal radius or the dry mass.
        """
        y = task.offset_states(np.atleast_2d(y_planned_nd), self.entry_position_m,
                               self.entry_velocity_m_s, self.mass_error_kg)
        if not (np.all(task.radius_nd(y) > task.r_stop_nd)
                and np.all(y[:, -1] > task.dry_mass_nd)):
            raise ValueError("the entry or mass error of the uncertainty model puts the start at "
                             "or below the terminal radius or the dry mass; reduce its σ")
        return y

    def plant_params(self, params: Any, i: int = 0) -> Any:
        """The true plant of episode ``i``: the nominal model parameters ``params`` (a
        :class:`~lunar_env.dynamics.PlanarParams` or :class:`~lunar_env.dynamics.Moon3DParams`,
        normalised) with ``thrust_nd`` × its thrust scale and ``exhaust_velocity_nd`` (Isp·g0)
        × its Isp scale; the other parameters as they are."""
        return dataclasses.replace(
            params, thrust_nd=params.thrust_nd * float(self.thrust_scale[i]),
            exhaust_velocity_nd=params.exhaust_velocity_nd * float(self.isp_scale[i]))

    def misaligned(self, controls: np.ndarray, n_angles: int, idx: np.ndarray | None = None
                   ) -> np.ndarray:
        """The controls the engine flies: ``controls`` (k, nu) (rad, throttle) commanded to
        episodes ``idx`` (all n if None, then k = n) with their gimbal-angle biases added to
        the first ``n_angles`` channels (the angles; the last, throttle, is kept); a new
        float64 array."""
        bias = self.misalignment_rad if idx is None else self.misalignment_rad[idx]
        controls = np.ascontiguousarray(controls, dtype=np.float64)
        out = np.empty(controls.shape)
        _misaligned(controls, bias, n_angles, out)
        return out

    def navigation_errors(self, model: UncertaintyModel, counters: np.ndarray,
                          altitude_m: np.ndarray, n_axes: int = 3
                          ) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity navigation errors (n, 3) each, along (up, downrange,
        crossrange) (m, m/s), of these n episodes under ``model`` at decision indices
        ``counters`` (n,) and true altitudes ``altitude_m`` (n,) (m): the inertial solution's
        above the terminal sensors' acquisition, theirs below the hand-over, blended between
        (:mod:`~lunar_env.uncertainty.navigation`), in one compiled call of
        :func:`~lunar_env.uncertainty.navigation.navigation_error`. ``n_axes`` = 2 (a planar
        task) leaves the crossrange components 0 and draws no noise for them."""
        return _errors(model.navigation_constants(), self, counters, altitude_m, n_axes)
