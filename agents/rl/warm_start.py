"""Start a run from another run's policy (``--init-from``) when the two differ in their
inputs or action channels.

A warm-started policy must first compute exactly what the loaded one did, so that training
starts from its landings, not from a perturbed copy of them. Every function here widens a
loaded state dict or its ``VecNormalize`` statistics so that the added parts are silent: added
input columns and action rows get zero weights, added inputs are normalised to the scale of
the columns they repeat.

The input changes a run may make against the policy it starts from (:func:`input_map`):

- the sensor channels ``sensors=("imu",)`` added to a policy trained without them;
- a history (``history: k``) added to a policy trained without one, or a longer history than
  the loaded policy's: the loaded policy's inputs become the newest slots, every older slot
  and action slot it did not see gets zero weights.

Anything else (other derived features, another env, a shorter history) is refused by name.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["InputMap", "input_map", "widen_action_head", "widen_input_layer",
           "load_widened_vecnormalize"]


def widen_action_head(weights: dict, target: dict, added: Any, source: str) -> dict:
    """``weights`` (a loaded PPO policy's state dict) for a policy with more action channels.

    ``added`` (the ``added_action_init`` hyperparameter) is a mapping ``{action: [...],
    log_std: [...]}`` with one entry per channel ``target`` has and the loaded policy lacks:
    the constant action in [-1, 1] the channel starts at, and optionally its exploration log σ
    (default: this run's ``log_std_init``, as for every channel of ``--init-from``). Example:
    ``{action: [1.0], log_std: [-6.0]}`` for a pinpoint policy trained without a throttle
    channel and continued with one (``throttle_channel: true``; action 1 is full thrust). The
    added rows of the action head get zero weights and that action as bias, so the widened
    policy's mean flies exactly as the loaded one did; the loaded channels are copied.

    Raises ValueError when the heads differ and ``added`` does not say how to fill them, when
    it is given for heads that already match, or when a value is malformed."""
    import torch

    key_w, key_b = "action_net.weight", "action_net.bias"
    if key_w not in weights or key_w not in target:
        if added is not None:
            raise ValueError(f"added_action_init={added!r}: only for PPO policies (an "
                             f"'{key_w}' head); --init-from {source} has none")
        return weights
    n_old, n_new = weights[key_w].shape[0], target[key_w].shape[0]
    if n_old == n_new:
        if added is not None:
            raise ValueError(f"added_action_init={added!r}: --init-from {source} already has "
                             f"this env's {n_new} action channels; drop the key")
        return weights
    n_add = n_new - n_old
    if n_old > n_new or added is None:
        raise ValueError(
            f"--init-from {source} has {n_old} action channels, this env {n_new}"
            + ("" if n_old > n_new else
               f"; set added_action_init to {{action: [...], log_std: [...]}} with {n_add} "
               "value(s) each: the constant action(s) in [-1, 1] the added channel(s) start at "
               "(e.g. 1.0: a throttle channel at full thrust) and, optionally, their log σ"))
    if not isinstance(added, dict) or set(added) - {"action", "log_std"} or "action" not in added:
        raise ValueError(f"added_action_init={added!r}: must be a mapping with 'action' and "
                         "optionally 'log_std'")

    def values(key: str, bound: float) -> np.ndarray:
        v = np.asarray(added[key], dtype=np.float64).reshape(-1)
        if len(v) != n_add or not np.all(np.isfinite(v)) or np.any(np.abs(v) > bound):
            raise ValueError(f"added_action_init.{key}={added[key]!r}: needs {n_add} finite "
                             f"value(s) in [-{bound:g}, {bound:g}], one per channel --init-from "
                             f"{source} lacks")
        return v

    out = dict(weights)
    w, b = weights[key_w], weights[key_b]
    out[key_w] = torch.cat([w, torch.zeros(n_add, w.shape[1], dtype=w.dtype)])
    out[key_b] = torch.cat([b, torch.as_tensor(values("action", 1.0), dtype=b.dtype)])
    if added.get("log_std") is not None:
        log_std = target["log_std"].clone()
        log_std[n_old:] = torch.as_tensor(values("log_std", 20.0), dtype=log_std.dtype)
        out["log_std"] = log_std
    return out


@dataclass(frozen=True)
class InputMap:
    """Where each input column of a run comes from in the policy it starts from.

    ``weights[j]`` is the loaded input column whose first-layer weights column j takes, or -1
    for a column the loaded policy never saw (zero weights). ``stats[j]`` is the loaded column
    whose normalisation statistics column j takes, or -1 for mean 0 and variance 1: a history
    slot older than the loaded policy's oldest repeats the statistics of the nearest slot it
    had (the same quantity a few decisions earlier), while its weights stay zero. ``added``
    says what was added, for the run's console."""

    weights: np.ndarray
    stats: np.ndarray
    added: str


def _slot_map(n_base: int, n_sensor_old: int, n_sensor_new: int, n_obs_new: int) -> np.ndarray:
    """Loaded column (or -1) of each column of one input o(t): the env's own columns, then
    its sensor channels, then the derived features."""
    cols = np.arange(n_obs_new)
    out = np.where(cols < n_base, cols, cols - (n_sensor_new - n_sensor_old))
    sensors = (cols >= n_base) & (cols < n_base + n_sensor_new)
    if n_sensor_old == 0:
        out[sensors] = -1
    return out


def input_map(init_config: dict[str, Any], config: dict[str, Any], venv, init_width: int,
              source: str) -> InputMap | None:
    """How this run's inputs take the inputs of the ``--init-from`` policy ``source``, or None
    when the widths match (nothing to widen).

    ``init_config`` and ``config`` are the two runs' hyperparameters (``config.yml``: their
    ``env_kwargs``, ``obs_features`` and ``history``), ``venv`` this run's training env (before
    ``VecNormalize``) and ``init_width`` the loaded policy's input width.

    Raises
    ------
    ValueError
        The inputs differ other than by the sensor channels of ``sensors=("imu",)`` or a
        longer history (the message names both widths and what may differ).
    """
    from agents.common.vec_env import LanderSB3VecEnv
    from agents.features.history import HistoryWrapper
    from agents.rl.callbacks import find_wrapper

    width = int(venv.observation_space.shape[0])
    if width == init_width:
        return None
    refuse = ValueError(
        f"--init-from {source} takes {init_width} inputs, this run {width}: only the sensor "
        "channels of sensors=('imu',) and a history (or a longer one) can be added to a policy "
        "trained without them; train with the initial policy's env, obs_features and env_kwargs "
        "otherwise")
    native_wrapper = find_wrapper(venv, LanderSB3VecEnv)
    if native_wrapper is None:
        raise refuse
    native = native_wrapper.native
    old_sensors = tuple((init_config.get("env_kwargs") or {}).get("sensors") or ())
    new_sensors = tuple((config.get("env_kwargs") or {}).get("sensors") or ())
    if (old_sensors and old_sensors != new_sensors) or (
            list(init_config.get("obs_features") or []) != list(config.get("obs_features") or [])):
        raise refuse
    n_base = int(native.task.n_base_obs)
    n_sensor_new = int(native.single_observation_space.shape[0]) - n_base
    n_sensor_old = n_sensor_new if old_sensors else 0
    hist = find_wrapper(venv, HistoryWrapper)
    k = None if hist is None else hist.k
    n_obs_new = width if hist is None else hist.stack.n_obs
    n_act = int(venv.action_space.shape[0])
    n_obs_old = n_obs_new - (n_sensor_new - n_sensor_old)
    k0 = init_config.get("history")
    old_width = n_obs_old if k0 is None else int(k0) * (n_obs_old + n_act)
    if old_width != init_width or (k0 is not None and (k is None or int(k0) > k)):
        raise refuse
    one = _slot_map(n_base, n_sensor_old, n_sensor_new, n_obs_new)
    added = []
    if n_sensor_new != n_sensor_old:
        added.append(f"{n_sensor_new} sensor input(s) at column {n_base}")
    if k is None:
        return InputMap(one, one.copy(), " and ".join(added))
    k0 = 0 if k0 is None else int(k0)
    # a policy without a history saw one input slot and no action slot
    obs_w, obs_s = _stacked_slots(one, n_obs_old, 0, k, max(k0, 1))
    act_w, act_s = _stacked_slots(np.arange(n_act), n_act, k0 * n_obs_old, k, k0)
    added.append(f"a history of {k} decision{'s' if k > 1 else ''}"
                 + (f" (from {k0})" if k0 else ""))
    return InputMap(np.concatenate([obs_w, act_w]), np.concatenate([obs_s, act_s]),
                    " and ".join(added))


def _stacked_slots(one: np.ndarray, stride: int, offset: int, k: int, k_old: int
                   ) -> tuple[np.ndarray, np.ndarray]:
    """``(weights, stats)`` maps (module :class:`InputMap`) of k slots, oldest first, of
    which the loaded policy had the newest ``k_old`` (0: none), each ``stride`` columns wide
    from its column ``offset``; ``one`` maps one slot's columns to the loaded slot's (-1: new).
    A slot older than the loaded ones takes the statistics of the oldest loaded slot."""
    width = len(one)
    if k_old == 0:
        none = np.full(k * width, -1)
        return none, none.copy()
    weights, stats = [], []
    for s in range(k):
        age = k - 1 - s
        slot = k_old - 1 - min(age, k_old - 1)
        mapped = np.where(one >= 0, offset + slot * stride + one, -1)
        weights.append(mapped if age < k_old else np.full(width, -1))
        stats.append(mapped)
    return np.concatenate(weights), np.concatenate(stats)


def widen_input_layer(weights: dict, target: dict, columns: InputMap) -> dict:
    """``weights`` (a loaded policy's state dict) for this run's inputs: every first-layer
    weight matrix (the one whose input width grows to ``len(columns.weights)`` in ``target``)
    takes the loaded columns ``columns.weights`` names and zeros where it says -1, so the
    widened policy and critic compute exactly what the loaded ones did until training gives
    the new inputs a weight."""
    import torch

    n_new = len(columns.weights)
    take = torch.as_tensor(np.maximum(columns.weights, 0))
    keep = torch.as_tensor(columns.weights >= 0)
    out = dict(weights)
    for key, w in weights.items():
        t = target.get(key)
        if t is None or w.ndim != 2 or tuple(t.shape) != (w.shape[0], n_new) or w.shape[1] == n_new:
            continue
        out[key] = torch.where(keep[None, :], w[:, take], torch.zeros((), dtype=w.dtype))
    return out


def load_widened_vecnormalize(path: str | Path, venv, columns: InputMap):
    """The ``VecNormalize`` statistics at ``path`` over ``venv``, whose inputs take the loaded
    columns ``columns.stats`` names; a column it marks -1 gets mean 0 and variance 1 (the IMU
    channels are fed in units of the full thrust acceleration, within ±3; the actions in
    [-1, 1])."""
    import pickle

    from stable_baselines3.common.running_mean_std import RunningMeanStd

    with open(path, "rb") as fh:
        vn = pickle.load(fh)  # noqa: S301  (the run's own statistics file)
    rms = vn.obs_rms
    src = columns.stats
    wide = RunningMeanStd(shape=(len(src),))
    wide.mean = np.where(src >= 0, rms.mean[np.maximum(src, 0)], 0.0)
    wide.var = np.where(src >= 0, rms.var[np.maximum(src, 0)], 1.0)
    wide.count = rms.count
    vn.obs_rms = wide
    vn.observation_space = venv.observation_space  # set_venv checks it against the env's
    vn.set_venv(venv)
    return vn
