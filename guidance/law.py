"""The guidance-law contract: everything that flies a lander, behind one batched interface.

A **guidance law** is what a flight computer runs. It acts for N landers at once on what a
lander's flight computer has, at the level a GNC engineer thinks in:

- before the flight, the :class:`FlightComputer`: the *nominal* vehicle and scenario (thrust,
  exhaust velocity, dry mass, the body), whether the engine throttles, the decision interval,
  the guidance frame's number of axes and the env's encoders;
- at each decision, the :class:`Navigation` of every lander: the navigated state in SI in the
  env's **guidance frame** (:attr:`Navigation.frame`: position of the target relative to the
  lander and velocity along the local horizontal axes and the local up, the known non-thrust
  acceleration, the mass estimate, the height), the mission clock, which rows start a new
  episode, the sensor channels the env provides (:attr:`Navigation.sensors`), and for
  model-based laws the navigation solution in the dynamics model's own state
  (:attr:`Navigation.state_nd`).

It never sees the simulator's true state or true plant: the flight loop
(:func:`guidance.flight.fly`) builds both objects from the env's public navigation output. A
teacher that may read the truth says so by its type, :class:`PrivilegedLaw` (a protocol of its
own: it has no ``act``), and tables mark its rows (:func:`law_label`).

A law returns, for every row, a :class:`ThrustCommand` (the thrust direction in the guidance
frame, and the throttle where the engine has one); the env's encoder
(:meth:`FlightComputer.encode`) turns it into the env's actions, so no law branches on the env.
A law that already speaks the env's action space (a policy trained on it, an action replay)
returns the actions themselves, shape (N, n_act). Actions of landers that are no longer flying
(``nav.active`` false) are ignored, so a costly law may skip them.

**Memory.** ``reset(computer, case_ids)`` is called once per batch of landers; after that, row i
starts a new episode wherever ``nav.episode_start[i]`` is true (every row at the first decision,
and a row again after an autoreset of a vector env), as SB3's ``episode_start``: a law with state
resets that row's state there, so it flies an autoresetting vector env.

A law in ten lines (flown by ``python -m guidance.campaign`` once registered, see
:func:`guidance.registry.register_law`)::

    import numpy as np
    from guidance import GuidanceLaw, ThrustCommand

    class VerticalBraking(GuidanceLaw):
        name = "vertical braking"

        def act(self, nav):
            f = nav.frame                      # SI, guidance frame: horizontal axes, then up
            a = -f.v / 20.0 - f.g              # null the velocity in ~20 s against gravity
            throttle = np.linalg.norm(a, axis=1) * f.mass_kg / self.computer.thrust_n
            return ThrustCommand(direction=a, throttle=throttle)
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from guidance.frames import LocalFrame

__all__ = ["FlightComputer", "Navigation", "Truth", "ThrustCommand", "Law", "GuidanceLaw",
           "PrivilegedLaw", "CallableLaw", "ActionSequenceLaw", "law_label", "actions_of",
           "PRIVILEGED_MARK"]

#: appended to the name of a privileged law in tables and plots
PRIVILEGED_MARK = " [privileged]"


@dataclass(frozen=True)
class ThrustCommand:
    """A guidance command for N landers, in the guidance frame of the env
    (:class:`~guidance.frames.LocalFrame`: horizontal axes first, up last).

    Attributes
    ----------
    direction : ndarray, shape (N, d)
        Thrust direction (any positive length: a commanded thrust acceleration in m/s² is
        fine); the encoder normalises it.
    throttle : ndarray, shape (N,), optional
        Fraction of the nominal maximum thrust, in [0, 1] (values outside are clipped); None
        is full thrust. Ignored by an engine without a throttle (the papers' constant-thrust
        engine: its thrust is always full).
    """

    direction: np.ndarray
    throttle: np.ndarray | None = None


@dataclass(frozen=True)
class FlightComputer:
    """What a law knows before the flight (nothing here changes during an episode).

    Attributes
    ----------
    env_id : str
    scenario : Scenario
        The *nominal* scenario the env was built with (vehicle, body, targets, bounds).
    dt_s : float
        Decision interval: each action is held this long (s).
    time_limit_s : float
        Episode time limit (s).
    action_space : gymnasium.spaces.Box
        One lander's action space.
    throttled : bool
        The engine throttles (the action has a throttle channel).
    n_axes : int
        Axes of the guidance frame (2: downrange, up; 3: along-track, cross-track, up).
    target_radius_m : float
        Distance from the body's centre of the terminal surface the guidance frame measures
        height to (the landing surface, or the pinpoint gate sphere through the target) (m).
    thrust_elevation_bounds_rad : (float, float) or None
        Bounds of the thrust's elevation above the local horizontal the vehicle can point
        (None: any direction in the guidance plane).
    gate_range_m : float or None
        Pinpoint: the range to the target within which the gate counts (None: everywhere).
    sensors : tuple of str
        The sensor channels each :class:`Navigation` carries (:attr:`Navigation.sensors`).
    constants : dict[str, float]
        The env's nominal ``physical_constants()`` (SI).
    decode : callable
        ``decode(obs (N, n_obs)) -> dict[str, ndarray (N,)]``: the env's inverse of its
        observation, in SI.
    observation_from_state : callable
        ``observation_from_state(state_nd (N, n_state), t_s (N,)) -> obs``: the env's
        observation map (for laws that predict their own observations).
    frame_of : callable
        ``frame_of(state_nd (N, n_state)) -> LocalFrame``: the guidance frame of navigated
        states (:attr:`Navigation.frame`).
    encoder : callable
        ``encoder(direction (N, d), throttle (N,) or None) -> actions (N, n_act) float32``:
        the env's encoder of a :class:`ThrustCommand`.
    actions_from_controls : callable
        ``actions_from_controls(controls (N, n_control)) -> actions (N, n_act) float32``: the
        env's inverse of its control map, for model-based laws that compute the dynamics
        model's controls (thrust angles in rad, then the throttle).
    controls_from_actions : callable
        ``controls_from_actions(actions (N, n_act)) -> controls (N, n_control)``: the env's
        control map (thrust angles in rad, then the throttle the engine flies), for laws whose
        memory must follow actions another policy flew (a DAgger teacher's thrust estimate).
    """

    env_id: str
    scenario: Any
    dt_s: float
    time_limit_s: float
    action_space: spaces.Box
    throttled: bool
    n_axes: int
    target_radius_m: float
    thrust_elevation_bounds_rad: tuple[float, float] | None
    gate_range_m: float | None
    sensors: tuple[str, ...]
    constants: dict
    decode: Callable
    observation_from_state: Callable
    frame_of: Callable[[np.ndarray], LocalFrame]
    encoder: Callable
    actions_from_controls: Callable
    controls_from_actions: Callable

    # -- the nominal vehicle (what the flight computer was loaded with) ----------------------
    @property
    def thrust_n(self) -> float:
        """Nominal maximum thrust (N)."""
        return float(self.scenario.vehicle.thrust_n)

    @property
    def exhaust_velocity_m_s(self) -> float:
        """Nominal exhaust velocity Isp·g0 (m/s)."""
        return float(self.scenario.vehicle.exhaust_velocity_m_s)

    @property
    def dry_mass_kg(self) -> float:
        """Dry mass (kg): the burn ends there."""
        return float(self.scenario.vehicle.dry_mass_kg)

    @property
    def mu_m3_s2(self) -> float:
        """The body's gravitational parameter (m³/s²)."""
        return float(self.scenario.scaling().mu_m3_s2)

    def physical_constants(self) -> dict[str, float]:
        """The nominal SI constants (as the env's ``physical_constants()``)."""
        return dict(self.constants)

    def observation_quantities(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        """SI quantities of observations (as the env's ``observation_quantities``)."""
        return self.decode(obs)

    def encode(self, command: ThrustCommand) -> np.ndarray:
        """The env's actions (N, n_act) float32 of a :class:`ThrustCommand`."""
        return self.encoder(command.direction, command.throttle)

    @classmethod
    def of(cls, env, env_id: str) -> FlightComputer:
        """The flight computer of a lander env (single or native vector), from its public API
        and its guidance family (:mod:`guidance.families`)."""
        from guidance.families import guidance_family

        core = getattr(env, "unwrapped", env)
        space = getattr(core, "single_action_space", None) or core.action_space
        fam = guidance_family(core.scenario)
        sc = core.scenario
        task = core.task
        return cls(env_id=env_id, scenario=sc, dt_s=float(core.dt_s),
                   time_limit_s=float(core.time_limit_s), action_space=space,
                   throttled=bool(task.throttle_channel), n_axes=fam.n_axes,
                   target_radius_m=fam.target_radius_m(sc),
                   thrust_elevation_bounds_rad=fam.thrust_elevation_bounds_rad(sc),
                   gate_range_m=core.gate_range_m,
                   sensors=("imu",) if hasattr(core, "sensor_readings") else (),
                   constants=dict(core.physical_constants()),
                   decode=core.observation_quantities,
                   observation_from_state=core.observation_from_state,
                   frame_of=fam.frame_function(sc),
                   encoder=fam.encoder(sc, bool(task.throttle_channel)),
                   actions_from_controls=task.actions_from_controls,
                   controls_from_actions=task.controls_from_actions)


@dataclass(frozen=True)
class Navigation:
    """What the flight computer knows of N landers at one decision.

    Attributes
    ----------
    obs : ndarray, shape (N, n_obs), float32
        The observation the env returned (its encoding of the navigation solution).
    state_nd : ndarray, shape (N, n_state), float64
        The navigation solution as a state of the dynamics model, in the env's normalised units
        (planar: r, vr, θ, ω, m; pinpoint: Moon-fixed x, y, z, vx, vy, vz, m), for model-based
        laws; :attr:`frame` is the same solution in SI in the guidance frame.
    t_s : ndarray, shape (N,)
        Mission clock: time since the start of each episode (s).
    active : ndarray, shape (N,), bool
        Landers still flying (actions of the others are ignored).
    episode_start : ndarray, shape (N,), bool
        Rows whose episode starts at this decision (a law with memory resets those rows;
        None: none).
    sensors : mapping of str to ndarray
        The sensor channels the env provides (:attr:`FlightComputer.sensors`), each with a
        leading axis of N rows; empty when the env provides none.
    frame_of : callable
        The flight computer's guidance-frame map (:attr:`FlightComputer.frame_of`).
    """

    obs: np.ndarray
    state_nd: np.ndarray
    t_s: np.ndarray
    active: np.ndarray
    episode_start: np.ndarray | None = None
    sensors: Mapping[str, np.ndarray] = field(default_factory=dict)
    frame_of: Callable[[np.ndarray], LocalFrame] | None = None

    def __post_init__(self) -> None:
        if self.episode_start is None:  # no row starts an episode here
            object.__setattr__(self, "episode_start", np.zeros(len(self.t_s), dtype=bool))

    @property
    def n(self) -> int:
        """Number of landers."""
        return len(self.t_s)

    @cached_property
    def frame(self) -> LocalFrame:
        """The navigated state in SI in the guidance frame (computed on first use).

        Raises
        ------
        ValueError
            A navigated state is not finite.
        """
        if self.frame_of is None:
            raise ValueError("this Navigation has no guidance frame (it was built without a "
                             "flight computer's frame_of)")
        return self.frame_of(self.state_nd)


@dataclass(frozen=True)
class Truth:
    """The simulator's true state, given only to a :class:`PrivilegedLaw`.

    Attributes
    ----------
    state_nd : ndarray, shape (N, n_state)
    t_s : ndarray, shape (N,)
    """

    state_nd: np.ndarray
    t_s: np.ndarray


class Law(ABC):  # noqa: B024  (no abstract method: its subclasses each add theirs)
    """What every law has: a name, and a reset with the flight computer (see the module
    docstring). Fly a :class:`GuidanceLaw` or a :class:`PrivilegedLaw`."""

    name: str = "law"
    #: True for a teacher that reads the simulator's truth (:class:`PrivilegedLaw`)
    privileged: ClassVar[bool] = False

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        """Start flights of ``len(case_ids)`` landers (row i of every later call is case
        ``case_ids[i]``). Default: remember the computer."""
        self.computer = computer


class GuidanceLaw(Law):
    """A law that flies on the navigation solution alone (see the module docstring).

    Subclasses set :attr:`name` and implement :meth:`act`.
    """

    @abstractmethod
    def act(self, nav: Navigation) -> ThrustCommand | np.ndarray:
        """The command of every lander of ``nav``: a :class:`ThrustCommand` in the guidance
        frame, or actions (N, n_act) in the env's action space."""


class PrivilegedLaw(Law):
    """A teacher allowed the simulator's truth: it implements :meth:`act_privileged` (and no
    ``act``); the flight loop hands it the :class:`Truth` with the navigation."""

    privileged: ClassVar[bool] = True

    @abstractmethod
    def act_privileged(self, nav: Navigation, truth: Truth) -> ThrustCommand | np.ndarray:
        """Commands of every lander, knowing the true states ``truth``."""


def actions_of(computer: FlightComputer, command: ThrustCommand | np.ndarray) -> np.ndarray:
    """The env's actions (N, n_act) float32 of a law's output (encoded when it is a
    :class:`ThrustCommand`)."""
    if isinstance(command, ThrustCommand):
        return computer.encode(command)
    return np.asarray(command, dtype=np.float32)


class CallableLaw(GuidanceLaw):
    """A law from a function ``fn(nav) -> commands``: a quick way to fly a learnt policy's
    forward pass or a test law without a class.

    Parameters
    ----------
    fn : callable
        ``fn(nav: Navigation) -> ThrustCommand or ndarray (N, n_act)``.
    name : str
    """

    def __init__(self, fn: Callable[[Navigation], Any], name: str = "policy") -> None:
        self.fn = fn
        self.name = name

    def act(self, nav: Navigation) -> ThrustCommand | np.ndarray:
        return self.fn(nav)


class ActionSequenceLaw(GuidanceLaw):
    """Open-loop replay of per-case action sequences: decision k of an episode of case i flies
    ``sequences[i][k]`` (the last action held after a sequence ends); each row counts its own
    decisions from its episode's start.

    Parameters
    ----------
    sequences : list of ndarray, each shape (T_i, n_act)
    name : str
    """

    def __init__(self, sequences: list[np.ndarray], name: str = "open-loop replay") -> None:
        self.sequences = [np.asarray(q, dtype=np.float32) for q in sequences]
        self.name = name

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self._ids = np.asarray(case_ids)
        self._k = np.zeros(len(self._ids), dtype=np.int64)

    def act(self, nav: Navigation) -> np.ndarray:
        self._k[nav.episode_start] = 0
        out = np.stack([self.sequences[c][min(int(k), len(self.sequences[c]) - 1)]
                        for c, k in zip(self._ids, self._k, strict=True)])
        self._k += 1
        return out


def law_label(law: Law) -> str:
    """The law's name as tables print it: privileged laws are marked."""
    return law.name + (PRIVILEGED_MARK if getattr(law, "privileged", False) else "")
