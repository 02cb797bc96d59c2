"""A stacked history of observations and actions: memory for a feed-forward policy.

With ``history: k`` (YAML) or ``--history k`` (``train.py``) the policy's input at decision t
of an episode is its last k inputs and its last k actions, one flat row:

=====================================  ==================================================
columns                                content
=====================================  ==================================================
``[0, k·n_obs)``                       inputs o(t-k+1), …, o(t), oldest first
``[k·n_obs, k·(n_obs + n_act))``       actions a(t-k), …, a(t-1), oldest first
=====================================  ==================================================

``o`` is what the policy would see without a history (the env's observation with the run's
``obs_features`` appended) and ``a`` the action (in the env's [-1, 1] action space) taken after
each input, so a(t-1) is the action that led to o(t). At an episode's first decision there is
no past: every input slot holds o(0) (a lander that was where it is) and every action slot 0.
``k = 1`` is the current input and the previous action.

The same :class:`HistoryStack` builds the rows in training (:class:`HistoryWrapper`, a
``VecEnv`` wrapper over the native batched env, which resets a row's history when its episode
restarts in the same step) and in flight (:class:`agents.laws.SB3Law`, from ``nav.obs`` and the
law's own previous actions, reset per row where ``nav.episode_start`` is true), so a trained
policy flies on exactly the inputs it was trained on. The run's ``config.yml`` records
``history``; loading a run restores it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env.base_vec_env import VecEnvWrapper

from lunar_env.validation import require_integer

__all__ = ["MAX_HISTORY", "HistoryStack", "HistoryWrapper", "history_space", "validate_history"]

#: the longest history (decisions): 256 decisions are 512 s of a pinpoint descent at 2 s
MAX_HISTORY = 256


def validate_history(history: Any) -> int | None:
    """``history`` as a number of decisions, or None (no history) for None.

    Raises
    ------
    ValueError
        Not an integer from 1 to :data:`MAX_HISTORY` (the message names the value and the
        range).
    """
    if history is None:
        return None
    try:
        k = require_integer("history", history)
    except (TypeError, ValueError):
        k = None
    if k is None or not 1 <= k <= MAX_HISTORY:
        raise ValueError(f"history={history!r}: must be an integer from 1 to {MAX_HISTORY} "
                         "(the observations and actions the policy is given), or null for "
                         "none")
    return k


def history_space(obs_space: spaces.Box, action_space: spaces.Box, k: int) -> spaces.Box:
    """The ``Box`` of the stacked rows: ``obs_space``'s bounds k times, then
    ``action_space``'s k times (float32)."""
    low = np.concatenate([np.tile(obs_space.low.ravel(), k), np.tile(action_space.low.ravel(), k)])
    high = np.concatenate([np.tile(obs_space.high.ravel(), k),
                           np.tile(action_space.high.ravel(), k)])
    return spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)


class HistoryStack:
    """The last ``k`` inputs and actions of ``n`` rows (the layout of the module docstring).

    Parameters
    ----------
    n : int
        Rows (landers).
    k : int
        Decisions kept, 1 to :data:`MAX_HISTORY`.
    n_obs, n_act : int
        Width of one input and of one action.
    """

    def __init__(self, n: int, k: int, n_obs: int, n_act: int) -> None:
        self.k = validate_history(k)
        if self.k is None:
            raise ValueError("HistoryStack needs a history length, got None")
        self.n, self.n_obs, self.n_act = int(n), int(n_obs), int(n_act)
        self.obs = np.zeros((self.n, self.k, self.n_obs), dtype=np.float32)
        self.actions = np.zeros((self.n, self.k, self.n_act), dtype=np.float32)

    @property
    def width(self) -> int:
        """Columns of a stacked row, k·(n_obs + n_act)."""
        return self.k * (self.n_obs + self.n_act)

    def start(self, obs: np.ndarray, rows: np.ndarray | None = None) -> None:
        """Start the episodes of ``rows`` (all if None; indices or a boolean mask) at the
        inputs ``obs`` (n, n_obs) (only those rows are read): every input slot holds it, every
        action slot 0."""
        obs = self._check(obs, self.n_obs, "obs")
        idx = slice(None) if rows is None else rows
        self.obs[idx] = obs[idx][:, None, :]
        self.actions[idx] = 0.0

    def push(self, obs: np.ndarray, actions: np.ndarray, rows: np.ndarray | None = None
             ) -> None:
        """Advance ``rows`` (all if None; indices or a boolean mask) by one decision: the
        ``actions`` (n, n_act) taken and the inputs ``obs`` (n, n_obs) they led to; the oldest
        of each is dropped."""
        obs = self._check(obs, self.n_obs, "obs")
        actions = self._check(actions, self.n_act, "actions")
        if rows is None:
            # numpy copies overlapping slices through a buffer: a shift in place is safe
            self.obs[:, :-1] = self.obs[:, 1:]
            self.obs[:, -1] = obs
            self.actions[:, :-1] = self.actions[:, 1:]
            self.actions[:, -1] = actions
            return
        o, a = self.obs[rows], self.actions[rows]
        self.obs[rows] = np.concatenate([o[:, 1:], obs[rows][:, None, :]], axis=1)
        self.actions[rows] = np.concatenate([a[:, 1:], actions[rows][:, None, :]], axis=1)

    def stacked(self, rows: np.ndarray | None = None) -> np.ndarray:
        """The stacked rows (n, k·(n_obs + n_act)) float32 (of ``rows`` only if given)."""
        o = self.obs if rows is None else self.obs[rows]
        a = self.actions if rows is None else self.actions[rows]
        return np.concatenate([o.reshape(len(o), -1), a.reshape(len(a), -1)], axis=1)

    def _check(self, x: np.ndarray, width: int, name: str) -> np.ndarray:
        x = np.asarray(x, dtype=np.float32)
        if x.shape != (self.n, width):
            raise ValueError(f"{name} has shape {x.shape}; expected ({self.n}, {width})")
        return x


class HistoryWrapper(VecEnvWrapper):
    """Give a policy the last ``k`` observations and actions of each sub-env
    (:class:`HistoryStack`, the layout of the module docstring).

    :param venv: a VecEnv with a flat ``Box`` observation and action space and SB3's same-step
        reset (a finished sub-env returns its next episode's first observation, the last one in
        ``info["terminal_observation"]``), e.g. the native lander env
        (:class:`agents.common.vec_env.LanderSB3VecEnv`) under its feature and curriculum
        wrappers.
    :param k: decisions kept, 1 to :data:`MAX_HISTORY`.

    A sub-env whose episode ends starts a fresh history at its next episode's first
    observation in the same step; ``info["terminal_observation"]`` becomes the stacked row of
    the ended episode (its history advanced by the last action), so value bootstrapping on
    truncation sees what the policy would have seen. The actions recorded are those passed to
    ``step`` (SB3 clips them to the action space first, as ``predict`` does in flight).
    """

    def __init__(self, venv, k: int) -> None:
        k_ok = validate_history(k)
        if k_ok is None:
            raise ValueError("HistoryWrapper needs a history length, got None")
        obs_space, act_space = venv.observation_space, venv.action_space
        if not (isinstance(obs_space, spaces.Box) and isinstance(act_space, spaces.Box)
                and len(obs_space.shape) == 1 and len(act_space.shape) == 1):
            raise TypeError(f"HistoryWrapper needs flat Box observation and action spaces, got "
                            f"{obs_space} and {act_space}")
        super().__init__(venv, observation_space=history_space(obs_space, act_space, k_ok))
        self.k = k_ok
        self.stack = HistoryStack(venv.num_envs, k_ok, obs_space.shape[0], act_space.shape[0])
        self._actions = np.zeros((venv.num_envs, act_space.shape[0]), dtype=np.float32)

    def reset(self) -> np.ndarray:
        obs = self.venv.reset()
        self.stack.start(obs)
        return self.stack.stacked()

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions, dtype=np.float32).reshape(self._actions.shape)
        self.venv.step_async(actions)

    def step_wait(self):
        obs, rew, done, infos = self.venv.step_wait()
        done = np.asarray(done, dtype=bool)
        if done.any():
            ended = np.flatnonzero(done)
            # the ended episodes' final rows, built on a copy of their histories
            final = HistoryStack(len(ended), self.k, self.stack.n_obs, self.stack.n_act)
            final.obs[:], final.actions[:] = self.stack.obs[ended], self.stack.actions[ended]
            last = np.stack([np.asarray(infos[i].get("terminal_observation", obs[i]),
                                        dtype=np.float32) for i in ended])
            final.push(last, self._actions[ended])
            rows = final.stacked()
            for j, i in enumerate(ended):
                if "terminal_observation" in infos[i]:
                    infos[i]["terminal_observation"] = rows[j]
        if done.any():
            self.stack.push(obs, self._actions, rows=~done)
            self.stack.start(obs, rows=done)
        else:
            self.stack.push(obs, self._actions)
        return self.stack.stacked(), rew, done, infos
