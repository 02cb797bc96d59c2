"""The task contract: what a landing task supplies to the env bases, the step and the renderer.

A *task* owns everything scenario-specific of a landing env: its spaces, the action-to-control
map, the observation map and its inverse, the landing metrics and the initial states.
:class:`~lunar_env.envs.base.LanderEnv`, :class:`~lunar_env.envs.base.LanderVectorEnv`,
:class:`~lunar_env.envs.core.LanderBatch` and :class:`~lunar_env.envs.rendering.Renderer` use
nothing of a task but what :class:`LandingTask` declares here, so a new landing env is a new
subclass that implements every abstract method and sets every declared attribute.

States are normalised (μ = 1, lengths in units of ``length_ref_m``, ...; the model's own state
layout, see :mod:`lunar_env.dynamics`) with shape ``(B, model.n_state)``; everything reported
to users is SI, with the unit in the name.

A task is immutable once constructed (its settings are read by every step; changing one under
a running env would silently change the episode): setting or deleting an attribute afterwards
raises ``AttributeError``. Build a new env for other settings; for another uncertainty model,
:meth:`LandingTask.with_uncertainty` builds a new task from the same arguments.
"""

from __future__ import annotations

import abc
import dataclasses
import inspect
import math
from typing import Any

import numpy as np
from gymnasium import spaces

from ..uncertainty import EpisodeErrors, UncertaintyModel, resolve_uncertainty
from ..validation import require_bool, require_finite_positive, require_integer
from .core import landing_penalty

__all__ = ["LandingTask", "StepSettings", "MIN_DT_S", "fall_steps", "float_array", "box"]

#: the sensors an env can put in its observation (``sensors=(...)``)
SENSORS = ("imu",)
#: bound of the IMU's observation channels (units of the nominal thrust acceleration at the
#: wet mass: up to the wet/dry mass ratio at full thrust)
IMU_OBS_BOUND = 3.0


def check_sensors(sensors) -> tuple[str, ...]:
    """``sensors`` as a tuple of known sensor names (:data:`SENSORS`), each once; ValueError
    naming an unknown or repeated one."""
    if isinstance(sensors, str):
        raise ValueError(f"sensors = {sensors!r} must be a list of names, e.g. ['imu']")
    try:
        out = tuple(sensors)
    except TypeError:
        raise ValueError(f"sensors = {sensors!r} must be a list of names; known: "
                         f"{', '.join(SENSORS)}") from None
    for s in out:
        if s not in SENSORS:
            raise ValueError(f"unknown sensor {s!r}; known sensors: {', '.join(SENSORS)}")
    if len(set(out)) != len(out):
        raise ValueError(f"sensors = {list(out)} names a sensor twice")
    return out





#: Shortest decision interval (s). A choice: a millisecond is faster than any lander's guidance
#: cycle (Apollo's LGC ran its descent guidance every 2 s), a shorter interval only makes
#: episodes of millions of steps, and a subnormal one (5e-324 s) divides the free fall's step
#: count by zero.
MIN_DT_S = 1e-3


@dataclasses.dataclass(frozen=True)
class StepSettings:
    """Validated settings every landing task shares (SI). Build with :meth:`validated`.

    Attributes
    ----------
    dt_s : float
        Decision interval: each action is held this long (s).
    substeps : int
        RK4 steps per env step.
    time_limit_s : float
        Episode time limit (s): truncation at ``t >= time_limit_s``.
    max_fall_s : float
        Longest free fall integrated after the engine stops (s); longer: truncation.
    throttle_channel : bool
        The action has a throttle channel (last), throttle = (a + 1) / 2.
    success_speed_m_s : float
        Largest touchdown (or gate) speed of a success (m/s).
    cutoff_speed_m_s : float
        Speed minima at or below this cut the engine off (m/s); 0: the engine never cuts off
        at a speed minimum (a throttleable engine: stopping is the guidance law's business).
    success_miss_m : float
        Largest miss distance of a success (m); ``inf`` for a task without a target.
    """

    dt_s: float
    substeps: int
    time_limit_s: float
    max_fall_s: float
    throttle_channel: bool
    success_speed_m_s: float
    cutoff_speed_m_s: float
    success_miss_m: float

    @classmethod
    def validated(cls, *, dt_s: float, substeps: int, time_limit_s: float | None,
                  max_fall_s: float | None, throttle_channel: bool, success_speed_m_s: float,
                  cutoff_speed_m_s: float | None, default_time_limit_s: float,
                  success_miss_m: float | None = None) -> StepSettings:
        """Settings from the env's keyword arguments, checked and with defaults resolved.

        ``time_limit_s=None`` means ``default_time_limit_s`` (s); ``max_fall_s=None`` the time
        limit; ``success_miss_m=None`` no miss criterion (``inf``); ``cutoff_speed_m_s=None``
        no engine cut-off at a speed minimum (stored as 0). ``substeps`` must be an
        integer >= 1 (1.7 is refused, not truncated), ``throttle_channel`` a bool (the string
        ``"no"`` is refused, not read as True), the times, speeds and ``success_miss_m``
        finite and > 0, ``dt_s >= MIN_DT_S`` (:data:`MIN_DT_S`) and ``time_limit_s >= dt_s``.

        Raises
        ------
        ValueError
            (or :class:`~lunar_env.validation.InvalidTypeError`) naming the setting and its
            value.
        """
        dt_s = require_finite_positive("dt_s", dt_s)
        if dt_s < MIN_DT_S:
            raise ValueError(f"dt_s = {dt_s!r} is not allowed; a decision interval must be "
                             f">= {MIN_DT_S:g} s")
        success_speed_m_s = require_finite_positive("success_speed_m_s", success_speed_m_s)
        cutoff_speed_m_s = 0.0 if cutoff_speed_m_s is None else \
            require_finite_positive("cutoff_speed_m_s", cutoff_speed_m_s)
        miss = math.inf if success_miss_m is None else \
            require_finite_positive("success_miss_m", success_miss_m)
        substeps = require_integer("substeps", substeps, minimum=1)
        throttle_channel = require_bool("throttle_channel", throttle_channel)
        if time_limit_s is not None:
            time_limit_s = require_finite_positive("time_limit_s", time_limit_s)
        if max_fall_s is not None:
            max_fall_s = require_finite_positive("max_fall_s", max_fall_s)
        limit = float(time_limit_s if time_limit_s is not None else default_time_limit_s)
        if not limit >= dt_s:
            raise ValueError(f"time_limit_s = {limit!r} must be >= dt_s = {dt_s!r}")
        return cls(dt_s=float(dt_s), substeps=int(substeps), time_limit_s=limit,
                   max_fall_s=float(max_fall_s if max_fall_s is not None else limit),
                   throttle_channel=bool(throttle_channel),
                   success_speed_m_s=float(success_speed_m_s),
                   cutoff_speed_m_s=float(cutoff_speed_m_s), success_miss_m=float(miss))


def float_array(a) -> np.ndarray:
    """``a`` as a C-contiguous float32 or float64 array for the compiled maps (float32 actions
    are kept: the kernels widen each value to float64 exactly, so results do not change, and
    one conversion call is saved per step)."""
    if type(a) is not np.ndarray:
        a = np.asarray(a)
    if a.dtype != np.float32 and a.dtype != np.float64:
        a = a.astype(np.float64)
    return a if a.flags.c_contiguous else np.ascontiguousarray(a)


def fall_steps(max_fall_s: float, h_s: float) -> int:
    """Number of RK4 steps of length ``h_s`` (s) covering ``max_fall_s`` (s)."""
    return max(1, int(math.ceil(max_fall_s / h_s - 1e-9)))


class _FrozenAfterInit(abc.ABCMeta):
    """Freezes an instance once its whole ``__init__`` (subclass included) has run, and keeps
    the arguments it was built with (for :meth:`LandingTask.with_uncertainty`)."""

    def __call__(cls, *args: Any, **kwargs: Any) -> Any:
        obj = super().__call__(*args, **kwargs)
        obj._add_sensor_channels()
        object.__setattr__(obj, "_init_arguments", (args, dict(kwargs)))
        object.__setattr__(obj, "_frozen", True)
        return obj


class LandingTask(metaclass=_FrozenAfterInit):
    """Contract of a landing task (see the module docstring); subclasses implement it.

    The constructor sets the shared constants below from a scenario and validated
    :class:`StepSettings`; the subclass then sets ``r_stop_nd``, ``action_space``,
    ``observation_space`` and whatever its own methods need.

    Attributes
    ----------
    model : lunar_env.integrators model
        Dynamics model (class attribute): ``n_state``, ``n_control`` and the compiled RHS.
    has_target : bool
        True for a pinpoint task: a miss distance is part of the verdict and the info.
    n_axes : int
        Spatial axes of the state: 2 (planar: up, downrange) or 3 (+ crossrange).
    charge_propellant_on_failure : bool
        A failed landing is also charged the propellant left (pinpoint v1/v2).
    gate_range_m : float or None
        Great-circle distance from the target (m) within which the terminal gate counts; None:
        the terminal radius ``r_stop_nd`` counts everywhere (then :meth:`stop_radius` and
        :meth:`below_gate_in_zone` are never called by the step, which saves their cost).
    scenario : object
        The frozen scenario flown (vehicle, body, initial state and its dispersion).
    settings : StepSettings
        The validated shared settings; ``dt_s`` ... ``success_miss_m`` read from it.
    scaling : lunar_env.Scaling
        SI <-> normalised conversion of the scenario.
    params, params_array :
        Normalised model parameters (dataclass, and the flat array the kernel takes).
    dt_nd, h_nd : float
        Env step and RK4 step, normalised time.
    n_fall : int
        RK4 steps of the longest free fall (``max_fall_s``).
    dry_mass_nd : float
        Dry mass (normalised): the burn ends there.
    r_stop_nd : float
        Terminal radius (normalised): the surface (planar) or the gate sphere (pinpoint).
    mass_ref_kg, time_ref_s, length_ref_m, velocity_ref_m_s : float
        Normalisation units (kg, s, m, m/s).
    propellant_ref_kg : float
        Propellant capacity of the vehicle (kg): the fuel reward's unit.
    prop_nominal_nd : float
        Nominal propellant load (normalised mass): the observation's full fraction.
    uncertainty : lunar_env.uncertainty.UncertaintyModel
        The plant and navigation errors drawn per episode (the ``none`` set by default).
    action_space, observation_space : gymnasium.spaces.Box
        float32 spaces of one lander.
    """

    model: Any
    has_target: bool = False
    #: spatial axes of the state (2: planar, up and downrange; 3: up, downrange, crossrange)
    n_axes: int = 3
    charge_propellant_on_failure: bool = False
    gate_range_m: float | None = None
    #: what the terminal radius ``r_stop_nd`` is, for messages
    stop_name: str = "the terminal radius"
    #: keys the task adds to every ``info`` at touchdown (:meth:`touchdown_info`), after the
    #: shared ones (:data:`~lunar_env.envs.core.INFO_KEYS`); each is defined only where a
    #: lander touched down
    extra_info_keys: tuple[str, ...] = ()
    r_stop_nd: float
    action_space: spaces.Box
    observation_space: spaces.Box

    def __init__(self, scenario: Any, settings: StepSettings,
                 uncertainty: UncertaintyModel | str | dict | None = None,
                 sensors: tuple[str, ...] | list[str] = ()) -> None:
        self.sensors = check_sensors(sensors)
        self.uncertainty = resolve_uncertainty(uncertainty)
        # the navigation model packed once for the compiled navigation kernels
        self._nav_consts = self.uncertainty.navigation_constants()
        self.scenario = scenario
        self.settings = settings
        self.scaling = s = scenario.scaling()
        self.params = scenario.params(s)
        self.params_array = self.params.as_array()
        self.dt_nd = float(s.time_nd(settings.dt_s))
        self.h_nd = self.dt_nd / settings.substeps
        self.n_fall = fall_steps(settings.max_fall_s, settings.dt_s / settings.substeps)
        self.dry_mass_nd = float(s.mass_nd(scenario.vehicle.dry_mass_kg))
        self.mass_ref_kg = s.mass_kg
        self.time_ref_s = s.time_s
        self.length_ref_m = s.length_m
        self.velocity_ref_m_s = s.velocity_m_s
        self.propellant_ref_kg = scenario.vehicle.mass_kg - scenario.vehicle.dry_mass_kg
        self.prop_nominal_nd = float(s.mass_nd(scenario.vehicle.mass_kg)) - self.dry_mass_nd
        self._check_mass_error()

    def _check_mass_error(self) -> None:
        """Refuse an uncertainty model whose wet-mass error can start a lander at or below its
        dry mass: the draws are truncated at ±TRUNCATION_SIGMA σ, so the worst is known when
        the task is built, and a campaign would otherwise fail at the reset of that case."""
        from ..uncertainty import TRUNCATION_SIGMA

        sigma = float(self.uncertainty.mass_kg)
        vehicle = self.scenario.vehicle
        lightest = vehicle.mass_kg + min(0.0, float(self.scenario.dispersion.mass_kg[0]))
        margin = lightest - vehicle.dry_mass_kg
        if TRUNCATION_SIGMA * sigma >= margin:
            raise ValueError(
                f"UncertaintyModel.mass_kg = {sigma:g} kg (1σ) is not allowed for "
                f"{self.scenario.name}: at its ±{TRUNCATION_SIGMA:g}σ truncation it removes "
                f"{TRUNCATION_SIGMA * sigma:g} kg from the lightest start, {lightest:g} kg, whose "
                f"propellant above the dry mass is {margin:g} kg; allowed: mass_kg < "
                f"{margin / TRUNCATION_SIGMA:.4g} kg")

    def __setattr__(self, name: str, value: Any) -> None:
        if self.__dict__.get("_frozen", False):
            raise AttributeError(f"cannot set {type(self).__name__}.{name}: a task is frozen "
                                 "after construction; make a new env with the setting instead")
        object.__setattr__(self, name, value)

    def __delattr__(self, name: str) -> None:
        raise AttributeError(f"cannot delete {type(self).__name__}.{name}: a task is frozen")

    def with_uncertainty(self, uncertainty: UncertaintyModel | str | dict | None
                         ) -> LandingTask:
        """A new task of this class built with this task's arguments but ``uncertainty``
        (anything the ``uncertainty`` argument takes); this task is left as it was.

        Raises
        ------
        TypeError
            If the subclass's constructor has no ``uncertainty`` argument.
        """
        cls = type(self)
        signature = inspect.signature(cls.__init__)  # (self, ...): the metaclass hides cls's
        if "uncertainty" not in signature.parameters:
            raise TypeError(f"{cls.__name__}() takes no 'uncertainty' argument; a landing task's "
                            "constructor must take one to be rebuilt under another model")
        args, kwargs = self._init_arguments
        bound = signature.bind(self, *args, **kwargs)
        bound.arguments["uncertainty"] = uncertainty
        return cls(*bound.args[1:], **bound.kwargs)

    # -- settings (read-only views of ``settings``) ------------------------------------------------
    @property
    def dt_s(self) -> float:
        """Decision interval (s)."""
        return self.settings.dt_s

    @property
    def substeps(self) -> int:
        """RK4 steps per env step."""
        return self.settings.substeps

    @property
    def time_limit_s(self) -> float:
        """Episode time limit (s)."""
        return self.settings.time_limit_s

    @property
    def max_fall_s(self) -> float:
        """Longest free fall integrated (s)."""
        return self.settings.max_fall_s

    @property
    def throttle_channel(self) -> bool:
        """The action has a throttle channel."""
        return self.settings.throttle_channel

    @property
    def success_speed_m_s(self) -> float:
        """Largest touchdown (gate) speed of a success (m/s)."""
        return self.settings.success_speed_m_s

    @property
    def cutoff_speed_m_s(self) -> float:
        """Speed minima at or below this cut the engine off (m/s); 0: no cut-off."""
        return self.settings.cutoff_speed_m_s

    @property
    def engine_cutoff(self) -> bool:
        """The engine cuts off at a speed minimum (the integrator's ``SpeedMinimum`` event is
        armed): the steer-only, constant-thrust vehicles of the papers. False for a
        throttleable engine, which burns until the law throttles it or the propellant runs
        out."""
        return self.settings.cutoff_speed_m_s > 0.0

    @property
    def success_miss_m(self) -> float:
        """Largest miss distance of a success (m); inf without a target."""
        return self.settings.success_miss_m

    # -- maps -----------------------------------------------------------------------------------
    @abc.abstractmethod
    def controls_from_actions(self, a: np.ndarray) -> np.ndarray:
        """Controls (B, model.n_control) (rad, throttle in [0, 1]) of validated finite actions
        ``a`` (B, n_act) (clipped to [-1, 1] here)."""

    @abc.abstractmethod
    def actions_from_controls(self, u: np.ndarray) -> np.ndarray:
        """Actions (B, n_act) float32 of model controls ``u`` (B, model.n_control) (thrust
        angles in rad, then the throttle in [0, 1]): the inverse of
        :meth:`controls_from_actions` within the action bounds (angles beyond them clip to
        ±1; without a throttle channel the throttle is left out)."""

    def _add_sensor_channels(self) -> None:
        """After the subclass built its observation space: the sensor channels' columns
        appended to it (the IMU's specific force in units of the nominal thrust acceleration
        at the wet mass, within ±:data:`IMU_OBS_BOUND`)."""
        self.n_base_obs = int(self.observation_space.shape[0])
        if "imu" in self.sensors:
            v = self.scenario.vehicle
            self.imu_ref_m_s2 = float(v.thrust_n / v.mass_kg)
            low = np.concatenate([self.observation_space.low, [-IMU_OBS_BOUND] * self.n_axes])
            high = np.concatenate([self.observation_space.high, [IMU_OBS_BOUND] * self.n_axes])
            self.observation_space = box(low, high)

    def with_sensor_channels(self, obs: np.ndarray, readings: dict[str, np.ndarray]
                             ) -> np.ndarray:
        """Observations (B, n_base_obs) with the sensor channels of ``readings``
        (:meth:`~lunar_env.envs.core.LanderBatch.sensor_readings`) appended, float32."""
        if "imu" not in self.sensors:
            return obs
        imu = np.clip(readings["imu"] / self.imu_ref_m_s2, -IMU_OBS_BOUND, IMU_OBS_BOUND)
        return np.concatenate([obs, imu.astype(np.float32)], axis=1)

    def observation_of_states(self, y: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Observations (B, n_obs) float32 of states ``y`` (B, n_state) at times ``t_s`` (B,)
        (s) with the sensor channels of a lander that has flown no step from them, read by
        an ideal sensor: zero specific force (what a step returns at an episode's first
        decision, less the sensor's own errors)."""
        obs = self.observation(y, t_s)
        if not self.sensors:
            return obs
        return self.with_sensor_channels(obs, {"imu": np.zeros((len(obs), self.n_axes))})

    def observation_rows(self, obs: np.ndarray) -> np.ndarray:
        """Observations as float64 rows (B, width): the env's (B, n_obs) or only the task's
        own columns (B, n_base_obs), e.g. a shaping potential's slice; a single observation
        is one row.

        Raises
        ------
        ValueError
            The last dimension is neither width.
        """
        o = np.asarray(obs, dtype=np.float64)
        o = o.reshape(1, -1) if o.ndim == 1 else o.reshape(-1, o.shape[-1])
        widths = {int(self.observation_space.shape[0]), int(self.n_base_obs)}
        if o.shape[1] not in widths:
            raise ValueError(f"observations of width {o.shape[1]}: this env's are "
                             f"{self.observation_space.shape[0]} wide ({self.n_base_obs} without "
                             "the sensor channels)")
        return o

    def sensor_quantities(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        """SI quantities of the sensor channels of observations (B, n_obs): ``imu_m_s2`` (B,
        n_axes), the measured specific force (m/s²; exact inside the bounds); none for rows of
        the task's own columns only."""
        o = self.observation_rows(obs)
        if "imu" not in self.sensors or o.shape[1] == self.n_base_obs:
            return {}
        return {"imu_m_s2": o[:, self.n_base_obs:self.n_base_obs + self.n_axes]
                * self.imu_ref_m_s2}

    @abc.abstractmethod
    def observation(self, y: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Observations (B, n_obs) float32 of states ``y`` (B, n_state) at times ``t_s`` (B,)
        (s), scaled and clipped to the observation space."""

    @abc.abstractmethod
    def observation_quantities(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        """SI quantities encoded in observations (B, n_obs): the inverse of
        :meth:`observation` (exact inside its bounds); each value has shape (B,)."""

    @abc.abstractmethod
    def physical_constants(self) -> dict[str, float]:
        """SI constants of the lander and the body that policies may use (derived features);
        each key carries its unit."""

    @abc.abstractmethod
    def offset_states(self, y: np.ndarray, dpos_m: np.ndarray, dvel_m_s: np.ndarray,
                      dmass_kg: np.ndarray) -> np.ndarray:
        """States ``y`` (B, n_state) displaced by position errors ``dpos_m`` (B, 3) and
        velocity errors ``dvel_m_s`` (B, 3) along the local (up, downrange, crossrange) axes (m,
        m/s; a planar task ignores crossrange) and mass errors ``dmass_kg`` (B,) (kg); a new
        array. Downrange is the direction of the scenario's initial motion."""

    def navigation_states(self, y: np.ndarray, errors: EpisodeErrors,
                          counters: np.ndarray, mass_belief_kg: np.ndarray) -> np.ndarray:
        """The navigated states (B, n_state) of true states ``y`` (B, n_state) under
        ``uncertainty``: each lander's navigation errors
        (:meth:`~lunar_env.uncertainty.EpisodeErrors.navigation_errors` of its episode
        ``errors`` (B rows) at decision indices ``counters`` (B,) and its true
        :meth:`altitude_m`) and its flight computer's mass error ``mass_belief_kg`` (B,) (kg)
        applied by :meth:`offset_states`; a new array.

        This default composes those public methods; a task may override it with a fused
        compiled kernel (calling :func:`~lunar_env.uncertainty.navigation.standard_normals`
        and :func:`~lunar_env.uncertainty.navigation.navigation_error` with
        :meth:`_navigation_inputs`) that must give the same arrays bit for bit (the planar and
        pinpoint tasks do: the env steps call this once per decision).
        """
        dpos, dvel = errors.navigation_errors(self.uncertainty, counters, self.altitude_m(y),
                                              self.n_axes)
        return self.offset_states(y, dpos, dvel, mass_belief_kg)

    def _navigation_inputs(self, y: np.ndarray, errors: EpisodeErrors,
                           counters: np.ndarray, mass_belief_kg: np.ndarray) -> tuple:
        """The leading arguments of a task's fused navigation kernel, in its order: (states,
        noise keys, decision indices, the inertial position and velocity biases, the terminal
        sensors' position fractions, floors and velocity biases, the packed navigation model,
        mass errors), as C-contiguous arrays of the kernel's dtypes."""
        return (np.ascontiguousarray(y, dtype=np.float64), errors.noise_key,
                np.ascontiguousarray(counters, dtype=np.int64), errors.nav_position_bias_m,
                errors.nav_velocity_bias_m_s, errors.sensor_position_fraction,
                errors.sensor_position_floor_m, errors.sensor_velocity_bias_m_s,
                self._nav_consts, np.ascontiguousarray(mass_belief_kg, dtype=np.float64))

    @abc.abstractmethod
    def radius_nd(self, y: np.ndarray) -> np.ndarray:
        """Distance from the body's centre (normalised), shape (B,)."""

    # -- geometry and verdict -------------------------------------------------------------------
    @abc.abstractmethod
    def speed_m_s(self, y: np.ndarray) -> np.ndarray:
        """Speed relative to the surface (m/s), shape (B,): the engine cut-off watches it."""

    @abc.abstractmethod
    def altitude_m(self, y: np.ndarray) -> np.ndarray:
        """Altitude (m) reported in ``info["altitude_m"]``, shape (B,)."""

    @abc.abstractmethod
    def landing_metrics(self, y: np.ndarray, touched_down: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray | None]:
        """Terminal speed (m/s) and miss distance (m; None without a target), each (B,), of
        landers whose episode ends at states ``y``; ``touched_down`` (B,) bool says which
        reached the terminal radius (the others are charged an estimate)."""

    def terminal_penalty(self, y: np.ndarray, speed_m_s: np.ndarray,
                         miss_m: np.ndarray | None, touched_down: np.ndarray) -> np.ndarray:
        """The landing-quality term (B,) subtracted from the last reward of episodes ending at
        states ``y`` (B, n_state), with :meth:`landing_metrics`' ``speed_m_s`` and ``miss_m``;
        ``touched_down`` (B,) as there. Default :func:`~lunar_env.envs.core.landing_penalty`
        of the speed (and the miss)."""
        return landing_penalty(speed_m_s, miss_m)

    def landed_within_limits(self, y: np.ndarray, speed_m_s: np.ndarray,
                             miss_m: np.ndarray | None) -> np.ndarray:
        """(B,) bool: the landing at states ``y`` (B, n_state) with :meth:`landing_metrics`'
        ``speed_m_s`` and ``miss_m`` meets the success limits (the step also requires a
        touchdown). Default: speed <= ``success_speed_m_s`` and miss <= ``success_miss_m``."""
        ok = speed_m_s <= self.success_speed_m_s
        if miss_m is not None:
            ok &= miss_m <= self.success_miss_m
        return ok

    def touchdown_info(self, y: np.ndarray) -> dict[str, np.ndarray]:
        """The :attr:`extra_info_keys` quantities (each (B,), SI) of landers that touched down
        at states ``y`` (B, n_state); default none."""
        return {}

    def success_thresholds(self) -> dict[str, float]:
        """The task's own landing verdict's limits (SI): ``speed_m_s`` (largest touchdown or
        gate speed of a success) and, for a task with a target, ``miss_m``."""
        out = {"speed_m_s": float(self.success_speed_m_s)}
        if self.has_target:
            out["miss_m"] = float(self.success_miss_m)
        return out

    def stop_radius(self, y: np.ndarray) -> np.ndarray:
        """Terminal radius (normalised) of each lander (B,) for the coming step. Called only
        when ``gate_range_m`` is not None; this default is ``r_stop_nd`` everywhere."""
        return np.full(len(y), self.r_stop_nd)

    def below_gate_in_zone(self, y: np.ndarray) -> np.ndarray:
        """(B,) bool: the lander ended the step where the gate counts but under it (its episode
        ends there). Called only when ``gate_range_m`` is not None; this default: none."""
        return np.zeros(len(y), dtype=bool)

    # -- episodes and rendering -----------------------------------------------------------------
    @abc.abstractmethod
    def initial_state(self, rng: np.random.Generator, options: dict | None) -> np.ndarray:
        """Normalised initial state (n_state,): drawn from the scenario's dispersion with
        ``rng``, or pinned by ``options`` (``state_nd``, ``state_si``, ``nominal``).

        Raises
        ------
        ValueError
            If the state is not finite, starts below ``r_stop_nd`` or without propellant.
        """

    def check_start(self, y: np.ndarray, source: str, given_si=None) -> np.ndarray:
        """``y``, a normalised start (n_state,), if it is one a landing can begin from; else
        ValueError naming ``source`` (e.g. ``"options['state_nd']"``), the value and the range
        allowed (normalised and SI; SI only where the user gave the SI row ``given_si``).

        Every start is checked the same way, pinned or drawn from the dispersion:

        - n_state finite numbers;
        - the distance from the body's centre above the terminal radius ``r_stop_nd``
          (:attr:`stop_name`: the surface, or the gate sphere);
        - the mass above the dry mass and at most the full tank: the vehicle's wet mass plus
          the dispersion's largest mass offset (:meth:`full_mass_nd`);
        - the speed relative to the surface below the escape speed at that distance
          (``sqrt(2 μ / r)``): a start bound to the body. (An unbound start is no landing, and
          its integration is not meaningful: at tens of thousands of times the orbital speed,
          an RK4 step turns the state into inf and NaN.)

        The mass is the last state component of both models (:mod:`lunar_env.dynamics`).
        """
        n = self.model.n_state
        nd = given_si is None
        shown = _fmt_state(y if nd else given_si)
        if y.shape != (n,) or not np.isfinite(y).all():
            raise ValueError(f"{source} = {shown} must be {n} finite numbers")
        r = float(self.radius_nd(y[None])[0])
        if not r > self.r_stop_nd:
            raise ValueError(
                f"{source} = {shown} starts at distance {self._length(r, nd)} from the "
                f"centre, not above {self.stop_name}; allowed: above "
                f"{self._length(self.r_stop_nd, nd)}")
        m = float(y[-1])
        full = self.full_mass_nd()
        if not self.dry_mass_nd < m <= full:
            raise ValueError(
                f"{source} = {shown} has mass {self._mass(m, nd)}; allowed: above the "
                f"dry mass {self._mass(self.dry_mass_nd, nd)}, at most the full tank "
                f"{self._mass(full, nd)}")
        v = float(self.speed_m_s(y[None])[0])
        v_esc = math.sqrt(2.0 / r) * self.velocity_ref_m_s
        if not v < v_esc:
            raise ValueError(
                f"{source} = {shown} has speed {v:.6g} m/s relative to the surface; "
                f"allowed: below the escape speed {v_esc:.6g} m/s at its distance (a start "
                "bound to the body)")
        return y

    def full_mass_nd(self) -> float:
        """The heaviest start (normalised mass): the vehicle's wet mass plus the largest mass
        offset of the scenario's dispersion (if positive)."""
        extra = max(0.0, float(self.scenario.dispersion.mass_kg[1]))
        return float(self.scaling.mass_nd(self.scenario.vehicle.mass_kg + extra))

    def _length(self, r_nd: float, nd: bool) -> str:
        si = f"{r_nd * self.length_ref_m:.9g} m"
        return f"{r_nd:.9g} (normalised; {si})" if nd else si

    def _mass(self, m_nd: float, nd: bool) -> str:
        si = f"{m_nd * self.mass_ref_kg:.6g} kg"
        return f"{m_nd:.9g} (normalised; {si})" if nd else si

    @abc.abstractmethod
    def track(self, ys: np.ndarray) -> dict:
        """What the renderer draws of states ``ys`` (T, n_state): at least ``downrange_km``
        and ``altitude_km`` (T,)."""


def _fmt_state(y) -> str:
    """A state row for an error message (at most 8 numbers, 7 significant digits)."""
    y = np.asarray(y).reshape(-1)
    items = ", ".join(f"{v:.7g}" for v in y[:8]) + (", ..." if y.size > 8 else "")
    return f"[{items}]"


def box(low, high) -> spaces.Box:
    """float32 Box from bound lists."""
    return spaces.Box(np.asarray(low, dtype=np.float32), np.asarray(high, dtype=np.float32),
                      dtype=np.float32)
