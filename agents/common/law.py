"""The guidance-law contract: everything that flies a lander, behind one batched interface.

A **guidance law** is what a flight computer runs. It knows

- before the flight, the :class:`FlightComputer`: the env id, the *nominal* scenario (vehicle,
  body, targets), the decision interval, the action space, the observation's SI decoding (the
  env's public inverse ``observation_quantities``) and the nominal physical constants;
- at each decision, the :class:`Navigation` of every lander: the observation the env returned
  (an encoding of the navigation solution), the navigation solution itself as a state in the
  env's normalised units, and the mission clock.

It never sees the simulator's true state or true plant. The rollout loop
(:func:`agents.common.rollout.fly`) builds both objects from the env's public navigation output
and hands nothing else to an ordinary law: the navigation solution is the env's public
``navigation_state_nd``. Today it equals the true state (the envs have no navigation errors
yet); the day the env adds them, every law flies on the navigated state without a change here.

A **privileged** law (a teacher that labels with the truth, e.g. a DAgger expert) says so in
its type: it subclasses :class:`PrivilegedLaw`, and the loop passes it the :class:`Truth` as
well. Evaluation tables mark its rows (:func:`law_label`).

One call acts for N landers: ``act(nav)`` returns actions of shape (N, n_act), float32 in the
env's action space. Actions of landers that are no longer flying (``nav.active`` false) are
ignored by the loop, so a costly law may skip them. A law that only labels while another
policy flies (a DAgger teacher) is told the actions flown, ``flown(nav, actions)``, after each
``act``; a law whose memory follows its own commands (a thrust estimate) overrides it.

Writing a new law (flown by ``agents.evaluation.compare.compare`` like any other)::

    import numpy as np
    from agents.common.law import GuidanceLaw

    class ConstantAttitude(GuidanceLaw):
        name = "constant attitude"

        def __init__(self, action):
            self.action = np.asarray(action, dtype=np.float32)

        def act(self, nav):
            return np.broadcast_to(self.action, (nav.n, self.action.size)).copy()
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

__all__ = ["FlightComputer", "Navigation", "Truth", "GuidanceLaw", "PrivilegedLaw",
           "CallableLaw", "ActionSequenceLaw", "law_label", "PRIVILEGED_MARK"]

#: appended to the name of a privileged law in tables and plots
PRIVILEGED_MARK = " [privileged]"


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
    gate_range_m : float or None
        Pinpoint: the range to the target within which the gate counts (None: everywhere).
    constants : dict[str, float]
        The env's nominal ``physical_constants()`` (SI).
    decode : callable
        ``decode(obs (N, n_obs)) -> dict[str, ndarray (N,)]``: the env's inverse of its
        observation, in SI.
    observation_from_state : callable
        ``observation_from_state(state_nd (N, n_state), t_s (N,)) -> obs``: the env's
        observation map (used by laws that predict their own observations).
    """

    env_id: str
    scenario: Any
    dt_s: float
    time_limit_s: float
    action_space: spaces.Box
    gate_range_m: float | None
    constants: dict
    decode: Any
    observation_from_state: Any

    def physical_constants(self) -> dict[str, float]:
        """The nominal SI constants (as the env's ``physical_constants()``)."""
        return dict(self.constants)

    def observation_quantities(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        """SI quantities of observations (as the env's ``observation_quantities``)."""
        return self.decode(obs)

    def at_full_thrust(self, angle_actions: np.ndarray) -> np.ndarray:
        """Actions (N, n_act) of a constant-thrust law's angle channels (N, n_angles): as they
        are on the papers' engine; on an env with a throttle channel (one more channel, the
        last) with it at full thrust (+1), so that the same law flies both engines."""
        a = np.asarray(angle_actions, dtype=np.float32)
        n_act = int(self.action_space.shape[-1])
        if n_act == a.shape[-1]:
            return a
        if n_act != a.shape[-1] + 1:
            raise ValueError(f"angle actions have {a.shape[-1]} channels; the env's action space "
                             f"has {n_act} (angles, or angles and a throttle)")
        return np.concatenate([a, np.ones(a.shape[:-1] + (1,), dtype=np.float32)], axis=-1)

    @classmethod
    def of(cls, env, env_id: str) -> FlightComputer:
        """The flight computer of a lander env (single or native vector), from its public API."""
        core = getattr(env, "unwrapped", env)
        space = getattr(core, "single_action_space", None) or core.action_space
        return cls(env_id=env_id, scenario=core.scenario, dt_s=float(core.dt_s),
                   time_limit_s=float(core.time_limit_s), action_space=space,
                   gate_range_m=core.gate_range_m,
                   constants=dict(core.physical_constants()),
                   decode=core.observation_quantities,
                   observation_from_state=core.observation_from_state)


@dataclass(frozen=True)
class Navigation:
    """The navigation solution of N landers at one decision (what the flight computer knows).

    Attributes
    ----------
    obs : ndarray, shape (N, n_obs), float32
        The observation the env returned (its encoding of the navigation solution).
    state_nd : ndarray, shape (N, n_state), float64
        The navigation solution as a state, in the env's normalised units (planar:
        r, vr, θ, ω, m; pinpoint: Moon-fixed x, y, z, vx, vy, vz, m).
    t_s : ndarray, shape (N,)
        Mission clock: time since the start of each episode (s).
    active : ndarray, shape (N,), bool
        Landers still flying (actions of the others are ignored).
    """

    obs: np.ndarray
    state_nd: np.ndarray
    t_s: np.ndarray
    active: np.ndarray

    @property
    def n(self) -> int:
        """Number of landers."""
        return len(self.t_s)


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


class GuidanceLaw(ABC):
    """Base of every guidance law (see the module docstring for the contract).

    Subclasses set :attr:`name` and implement :meth:`act`; :meth:`reset` is called once per
    batch of flights, before the first decision, with the flight computer and the case ids
    (row i of every later call is case ``case_ids[i]``).
    """

    name: str = "law"
    #: True for a teacher that reads the simulator's truth (see :class:`PrivilegedLaw`)
    privileged: ClassVar[bool] = False

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        """Start new flights of ``len(case_ids)`` landers (default: remember the computer)."""
        self.computer = computer

    @abstractmethod
    def act(self, nav: Navigation) -> np.ndarray:
        """Actions (N, n_act) float32 for the landers of ``nav``."""

    def flown(self, nav: Navigation, actions: np.ndarray) -> None:
        """Told, after :meth:`act`, the actions (N, n_act) actually flown at this decision,
        where another policy flew in place of this law (a DAgger roll-out: the student flies,
        the law labels). Default: nothing. A law whose memory follows the controls it
        commanded (a thrust estimate from the velocity changes they gave) overrides it, so
        that its memory follows the flight whoever flies it."""
        del nav, actions  # a law without memory of its commands has nothing to update


class PrivilegedLaw(GuidanceLaw):
    """A teacher allowed the simulator's truth: :meth:`act_privileged` replaces :meth:`act`."""

    privileged: ClassVar[bool] = True

    def act(self, nav: Navigation) -> np.ndarray:
        raise TypeError(f"{self.name} is a privileged law: it flies only with the truth "
                        "(act_privileged), never on the navigation solution alone")

    @abstractmethod
    def act_privileged(self, nav: Navigation, truth: Truth) -> np.ndarray:
        """Actions (N, n_act) float32, knowing the true states ``truth``."""


class CallableLaw(GuidanceLaw):
    """A law from a function ``fn(nav) -> actions``: a quick way to fly a learnt policy's
    forward pass or a test law without a class.

    Parameters
    ----------
    fn : callable
        ``fn(nav: Navigation) -> ndarray (N, n_act)``.
    name : str
    """

    def __init__(self, fn, name: str = "policy") -> None:
        self.fn = fn
        self.name = name

    def act(self, nav: Navigation) -> np.ndarray:
        return self.fn(nav)


class ActionSequenceLaw(GuidanceLaw):
    """Open-loop replay of per-case action sequences: decision k of case i flies
    ``sequences[i][k]`` (the last action held after a sequence ends).

    Parameters
    ----------
    sequences : list of ndarray, each shape (T_i, n_act)
    name : str
    """

    def __init__(self, sequences: list[np.ndarray], name: str = "open-loop replay") -> None:
        self.sequences = [np.asarray(q, dtype=np.float32) for q in sequences]
        self.name = name
        self._k = 0

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self._ids = np.asarray(case_ids)
        self._k = 0

    def act(self, nav: Navigation) -> np.ndarray:
        k = self._k
        self._k += 1
        return np.stack([self.sequences[c][min(k, len(self.sequences[c]) - 1)]
                         for c in self._ids])


def law_label(law: GuidanceLaw) -> str:
    """The law's name as tables print it: privileged laws are marked."""
    return law.name + (PRIVILEGED_MARK if getattr(law, "privileged", False) else "")
