"""The one flight loop: every law flies here (campaigns, evaluations, imitation, datasets).

:func:`fly` steps a natively batched lander vector env (``gym.make_vec(...,
vectorization_mode="vector_entry_point")``) with a law (:mod:`guidance.law`) until every case
has ended once, and returns the per-case outcome (:class:`Rollout`) read from the env's
``info`` (success, touchdown speed, miss distance, fuel, time) and each case's episode return,
with per-case histories of the recorded cases. Case ``i`` is sub-env ``i``: reset with
``seed + i`` (Gymnasium's vector convention), or pinned by ``reset_options`` (e.g.
``{"state_si": rows}``). :func:`rollout` is :func:`fly` for an evaluation (a
:class:`PolicyResult` with traces), :func:`initial_states` the cases' starts without flying.

:func:`navigation` builds what a law is given from the env's public navigation output, so a
user's loop over a vector env (with autoresets) hands its law the same objects.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any

import numpy as np

from guidance.law import (
    FlightComputer,
    Law,
    Navigation,
    PrivilegedLaw,
    Truth,
    actions_of,
    law_label,
)

if TYPE_CHECKING:
    from lunar_env.uncertainty import EpisodeErrors

__all__ = ["CaseOutcomes", "Rollout", "PolicyResult", "fly", "rollout", "initial_states",
           "make_vec", "navigation", "decide", "vector_info"]


def make_vec(env_id: str, n: int, env_kwargs: dict[str, Any] | None = None):
    """The native vector env of ``env_id`` with ``n`` landers."""
    import gymnasium as gym

    import lunar_env  # noqa: F401  (registers the env ids)

    return gym.make_vec(env_id, num_envs=int(n), vectorization_mode="vector_entry_point",
                        **(env_kwargs or {}))


def vector_info(info: dict, key: str, n: int) -> np.ndarray:
    """``info[key]`` as float array with NaN where Gymnasium's ``info["_" + key]`` mask says the
    value is undefined (e.g. no touchdown speed for a truncated episode)."""
    val = np.asarray(info[key], dtype=np.float64).reshape(n)
    mask = info.get("_" + key)
    if mask is None:
        return val
    return np.where(np.asarray(mask, dtype=bool).reshape(n), val, np.nan)


@dataclass
class CaseOutcomes:
    """What the env's ``info`` says of each case at its end (arrays of length n_cases), and
    what the law's decisions cost: ``n_decisions`` of landers still flying and the law's
    ``policy_wall_s`` (s) over them. ``episode_return`` is each case's sum of the env's rewards
    (unshaped, undiscounted) over its one episode."""

    is_success: np.ndarray
    touchdown_speed_m_s: np.ndarray
    miss_distance_m: np.ndarray
    fuel_used_kg: np.ndarray
    episode_time_s: np.ndarray
    n_decisions: int
    policy_wall_s: float
    episode_return: np.ndarray

    @property
    def us_per_decision(self) -> float:
        """The law's wall time per decision (µs)."""
        return 1e6 * self.policy_wall_s / max(self.n_decisions, 1)


@dataclass
class Rollout(CaseOutcomes):
    """Per-case outcome of :func:`fly` (:class:`CaseOutcomes`) and the recorded histories.

    ``records[i]`` (for the recorded cases) holds ``obs`` (T, n_obs), ``state_nd`` (T, n_state)
    (the simulator's true states), ``navigation_state_nd`` (T, n_state) (the navigation
    solutions the law was given: ``Navigation.state_nd``), ``t_s`` (T,) — the states at which
    an action was taken — and ``action`` (T, n_act); with ``record_final`` also the final true
    state (``state_nd`` and ``t_s`` one longer; the final state is no decision, so
    ``navigation_state_nd`` stays T long).
    ``final_state_nd`` (n, n_state): every case's true state where its episode ended.
    ``episode_errors``: every case's plant and navigation errors (n rows, the env's
    ``episode_errors`` after the reset: unit scales and zeros without an uncertainty model),
    the truth for analysis and privileged teachers.
    """

    records: dict[int, dict[str, np.ndarray]] = field(default_factory=dict)
    final_state_nd: np.ndarray | None = None
    episode_errors: EpisodeErrors | None = None


@dataclass
class PolicyResult(CaseOutcomes):
    """Per-case outcome of one law (:class:`CaseOutcomes`), its table name, the case ids and
    the traced cases' histories (``t_s``, ``state_nd``, ``action``)."""

    name: str = ""
    case_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    traces: dict[int, dict[str, np.ndarray]] = field(default_factory=dict)

    @classmethod
    def from_rollout(cls, name: str, case_ids: np.ndarray, rollout: Rollout,
                     traces: dict[int, dict[str, np.ndarray]]) -> PolicyResult:
        """The result of a law whose flight :func:`fly` returned."""
        outcomes = {f.name: getattr(rollout, f.name) for f in fields(CaseOutcomes)}
        return cls(name=name, case_ids=np.asarray(case_ids), traces=traces, **outcomes)


def navigation(core, computer: FlightComputer, obs: np.ndarray, active: np.ndarray,
               episode_start: np.ndarray, privileged: bool = False
               ) -> tuple[Navigation, Truth | None]:
    """What a law is given at one decision of the native vector env ``core``: the navigation
    solution the env gives its flight computer (its public ``navigation_state_nd``, clock and
    sensor channels) as a :class:`~guidance.law.Navigation`, and the simulator's truth for a
    privileged law only (None otherwise).

    Parameters
    ----------
    core : LanderVectorEnv
        The unwrapped native vector env.
    computer : FlightComputer
        Its flight computer (:meth:`FlightComputer.of`).
    obs : ndarray, shape (N, n_obs)
        The observations the env returned.
    active, episode_start : ndarray, shape (N,), bool
        Landers still flying; rows whose episode starts at this decision.
    privileged : bool
        Also return the :class:`~guidance.law.Truth`.
    """
    t_s = np.asarray(core.t_s, dtype=np.float64)
    sensors = core.sensor_readings() if computer.sensors else {}
    nav = Navigation(obs=obs, state_nd=np.asarray(core.navigation_state_nd), t_s=t_s,
                     active=np.array(active, dtype=bool), episode_start=np.array(
                         episode_start, dtype=bool), sensors=sensors,
                     frame_of=computer.frame_of)
    return nav, (Truth(state_nd=np.asarray(core.state_nd), t_s=t_s) if privileged else None)


def decide(law: Law, nav: Navigation, truth: Truth | None = None) -> np.ndarray:
    """The env's actions (N, n_act) float32 of ``law`` at one decision: its commands, encoded
    by the flight computer where they are :class:`~guidance.law.ThrustCommand` s. A
    :class:`~guidance.law.PrivilegedLaw` is asked with the ``truth`` (required).

    Raises
    ------
    FloatingPointError
        The law returned non-finite actions.
    """
    if isinstance(law, PrivilegedLaw):
        if truth is None:
            raise ValueError(f"{law_label(law)} is a privileged law: it needs the truth")
        out = law.act_privileged(nav, truth)
    else:
        out = law.act(nav)
    action = actions_of(law.computer, out)
    if not np.all(np.isfinite(action)):
        raise FloatingPointError(f"{law_label(law)} produced non-finite actions")
    return action


def fly(env_id: str, law: Law, n: int, *,
        seed: int | None = None, env_kwargs: dict[str, Any] | None = None,
        reset_options: dict[str, Any] | None = None, record: Iterable[int] = (),
        record_final: bool = False, max_steps: int | None = None) -> Rollout:
    """Fly ``law`` on ``n`` cases until each has ended once.

    The law is reset with the env's :class:`~guidance.law.FlightComputer` and case ids
    ``0..n-1``, then asked once per decision with the landers' :class:`~guidance.law.
    Navigation` (every row's ``episode_start`` true at the first decision; for a
    :class:`~guidance.law.PrivilegedLaw` also the :class:`~guidance.law.Truth`), and its
    commands encoded by the flight computer (:func:`decide`).

    Parameters
    ----------
    env_id : str
    law : Law
    n : int
    seed : int, optional
        Case i is sub-env i seeded ``seed + i``.
    env_kwargs : dict, optional
    reset_options : dict, optional
        Passed to ``reset`` (``state_si`` / ``state_nd`` rows pin each case's start).
    record : iterable of int
        Cases whose observation, true state, navigation solution, time and action histories
        are kept.
    record_final : bool
        Also record each recorded case's final state (before the autoreset).
    max_steps : int, optional
        Safety bound on vector steps (default: the env's time limit / dt + 10).

    Raises
    ------
    FloatingPointError
        The law returned non-finite actions.
    RuntimeError
        Cases still flying after ``max_steps``.
    """
    if int(n) < 1:
        raise ValueError(f"n = {n!r} must be >= 1")
    n = int(n)
    rec = sorted({int(i) for i in record if 0 <= int(i) < n})
    venv = make_vec(env_id, n, env_kwargs)
    try:
        obs, _ = venv.reset(seed=seed, options=reset_options)
        core = venv.unwrapped
        # each case's first (and only flown) episode: read before any autoreset redraws a row
        errors = core.episode_errors
        computer = FlightComputer.of(core, env_id)
        law.reset(computer, np.arange(n))
        name = law_label(law)
        privileged = isinstance(law, PrivilegedLaw)
        if max_steps is None:
            max_steps = int(math.ceil(core.time_limit_s / core.dt_s)) + 10
        active = np.ones(n, dtype=bool)
        success = np.zeros(n, dtype=bool)
        speed = np.full(n, np.nan)
        miss = np.full(n, np.nan)
        fuel = np.full(n, np.nan)
        t_end = np.full(n, np.nan)
        final = np.full(core.state_nd.shape, np.nan)
        ret = np.zeros(n)
        hist = {i: {"obs": [], "state_nd": [], "navigation_state_nd": [], "t_s": [],
                    "action": []} for i in rec}
        wall = 0.0
        n_dec = 0
        start = np.ones(n, dtype=bool)
        for _ in range(max_steps):
            nav, truth = navigation(core, computer, obs, active, start, privileged)
            start = np.zeros(n, dtype=bool)
            if rec:
                states, times = core.state_nd, core.t_s
                for i in rec:
                    if active[i]:
                        hist[i]["obs"].append(np.array(obs[i], copy=True))
                        hist[i]["state_nd"].append(np.array(states[i], copy=True))
                        hist[i]["navigation_state_nd"].append(np.array(nav.state_nd[i],
                                                                       copy=True))
                        hist[i]["t_s"].append(float(times[i]))
            t0 = time.perf_counter()
            action = decide(law, nav, truth)
            wall += time.perf_counter() - t0
            n_dec += int(active.sum())
            for i in rec:
                if active[i]:
                    hist[i]["action"].append(np.array(action[i], copy=True))
            obs, reward, term, trunc, info = venv.step(action)
            ret += np.where(active, np.asarray(reward, dtype=np.float64), 0.0)
            ended = (np.asarray(term) | np.asarray(trunc)) & active
            if ended.any():
                e = np.flatnonzero(ended)
                success[e] = np.asarray(info["is_success"])[e]
                speed[e] = vector_info(info, "touchdown_speed_m_s", n)[e]
                if "miss_distance_m" in info:
                    miss[e] = vector_info(info, "miss_distance_m", n)[e]
                fuel[e] = np.asarray(info["fuel_used_kg"], dtype=np.float64)[e]
                t_end[e] = np.asarray(info["time_s"], dtype=np.float64)[e]
                final[e] = core.state_nd[e]  # the final states: autoreset comes on the next step
                if record_final:
                    states = core.state_nd
                    for i in e:
                        if i in hist:
                            hist[i]["t_s"].append(float(info["time_s"][i]))
                            hist[i]["state_nd"].append(np.array(states[i], copy=True))
                active &= ~ended
            if not active.any():
                break
        else:
            raise RuntimeError(f"{name}: {int(active.sum())} cases did not end within "
                               f"{max_steps} steps")
    finally:
        venv.close()
    records = {i: {k: np.asarray(v, dtype=np.float32 if k == "obs" else np.float64)
                   for k, v in h.items()} for i, h in hist.items()}
    return Rollout(success, speed, miss, fuel, t_end, n_dec, wall, ret, records, final, errors)


def initial_states(env_id: str, n: int, seed: int, env_kwargs: dict[str, Any] | None = None
                   ) -> np.ndarray:
    """The normalised initial states (n, n_state) of cases ``0..n-1`` for ``seed``."""
    venv = make_vec(env_id, n, env_kwargs)
    try:
        venv.reset(seed=seed)
        return np.array(venv.unwrapped.state_nd, dtype=np.float64, copy=True)
    finally:
        venv.close()


def rollout(env_id: str, law: Law, n: int, seed: int,
            env_kwargs: dict[str, Any] | None = None, trace_cases: int = 3,
            max_steps: int | None = None) -> PolicyResult:
    """Fly ``law`` from cases ``0..n-1`` (one batched vector env) until every case ended
    (:func:`fly`), tracing the first ``trace_cases`` cases' true states and actions for plots.

    Parameters
    ----------
    env_id : str
    law : Law
    n : int
        Number of cases.
    seed : int
        Seed of the case set (case i = sub-env seeded ``seed + i``).
    env_kwargs : dict, optional
        Passed to the env (must match those a learned policy was trained with).
    trace_cases : int
        Cases whose state and action histories are kept.
    max_steps : int, optional
        Safety bound on the number of vector steps (default: the env's time limit / dt + 10).
    """
    out = fly(env_id, law, n, seed=seed, env_kwargs=env_kwargs, record=range(trace_cases),
              record_final=True, max_steps=max_steps)
    traces = {i: {"t_s": r["t_s"], "state_nd": r["state_nd"], "action": r["action"]}
              for i, r in out.records.items()}
    return PolicyResult.from_rollout(law_label(law), np.arange(n), out, traces)
