"""Hyperparameters in the RL Baselines3 Zoo layout, read without evaluating any string.

The files ``ppo.yml``, ``sac.yml``, ``td3.yml`` and ``recurrent-ppo.yml`` in this package are
keyed by env id, one tuned entry per id, exactly like
``rl-baselines3-zoo/hyperparams/<algo>.yml``::

    LunarSoftLanding-v0:
      n_envs: 16
      n_timesteps: !!float 2e6
      policy: MlpPolicy
      normalize: {norm_obs: true, norm_reward: true, gamma: 0.999}
      learning_rate: lin_3e-4
      policy_kwargs:
        net_arch: {pi: [64, 64], vf: [64, 64]}
        activation_fn: tanh

A *profile* of an entry is a second key ``<env id>@<profile>`` (for example
``LunarSoftLanding-v0@quick``, the few-thousand-step configuration CI runs end to end). It holds
only the values that differ: it is merged over the env id's entry.

Differences from the Zoo (decision: YAML is data, never code): the Zoo writes ``policy_kwargs``
as a Python string passed to ``eval``; here it must be a mapping, and the few values that name
Python objects are given by name and resolved from a fixed table:

- ``policy_kwargs.activation_fn``: ``tanh``, ``relu``, ``elu``, ``leaky_relu``, ``gelu``,
  ``silu``;
- ``policy_kwargs.optimizer_class``: ``adam``, ``adamw``, ``rmsprop``, ``sgd``;
- ``learning_rate`` / ``clip_range``: a number, or ``lin_<number>`` for a schedule decaying
  linearly from the number to 0 (the Zoo's spelling);
- ``normalize``: ``true``/``false`` or a mapping of ``VecNormalize`` keyword arguments, plus
  our ``update: false``, which keeps the statistics where they start (those of ``--init-from``
  or of the checkpoint) instead of updating them every step;
- ``noise_type`` (``normal`` or ``ornstein-uhlenbeck``) and ``noise_std`` for SAC/TD3 action
  noise, as in the Zoo.

Keys that are not algorithm arguments (``n_envs``, ``n_timesteps``, ``policy``, ``normalize``,
``noise_type``, ``noise_std``, ``env_kwargs``, ``curriculum``, ``obs_features``,
``reward_shaping``, ``history``, ...: :data:`RUN_KEYS`) are taken out before the
algorithm is built. ``history: k`` gives the policy the last k observations and actions
(:mod:`agents.features.history`); a recurrent policy (``recurrent-ppo``) keeps its own memory
and its ``policy_kwargs`` hold sb3-contrib's ``lstm_hidden_size``, ``n_lstm_layers``,
``shared_lstm`` and ``enable_critic_lstm``. ``curriculum`` is a mapping of
:class:`agents.rl.curriculum.OptimalStartCurriculum` arguments (``start_prob``,
``anneal_fraction``, ``n_trajectories``, ...), or absent. ``added_action_init``
(``{action: [...], log_std: [...]}``) says how a run started by ``--init-from`` fills the action
channels its initial policy lacks, e.g. a throttle channel
(:func:`agents.rl.warm_start.widen_action_head`). ``initial_action`` (one number in [-1, 1]
per action channel) is the mean action a new PPO run starts from
(:func:`agents.rl.training.set_initial_action`).
"""

from __future__ import annotations

import copy
import importlib.resources
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from agents.common.runs import ALGO_NAMES, algo_class

__all__ = [
    "ALGOS", "PROFILE_SEPARATOR", "RUN_KEYS", "apply_overrides",
    "default_hyperparams_path",
    "load_hyperparams",
    "parse_override", "resolve_algo_kwargs", "linear_schedule",
]

ALGOS = ALGO_NAMES
PROFILE_SEPARATOR = "@"
#: keys consumed by the training script itself, not passed to the algorithm constructor
RUN_KEYS = ("n_envs", "n_timesteps", "policy", "normalize", "noise_type", "noise_std",
            "env_kwargs", "curriculum", "error_curriculum", "obs_features", "reward_shaping",
            "critic_warmup_steps", "added_action_init",
            "select_checkpoint", "seed_race", "history", "initial_action")

_ACTIVATIONS = {"tanh": "Tanh", "relu": "ReLU", "elu": "ELU", "leaky_relu": "LeakyReLU",
                "gelu": "GELU", "silu": "SiLU"}
_OPTIMIZERS = {"adam": "Adam", "adamw": "AdamW", "rmsprop": "RMSprop", "sgd": "SGD"}


def default_hyperparams_path(algo: str) -> Path:
    """Path of the YAML file shipped for ``algo`` (one of :data:`ALGOS`)."""
    algo = algo.lower()
    if algo not in ALGOS:
        raise ValueError(f"algo={algo!r} is not supported; choose one of {ALGOS}")
    return Path(str(importlib.resources.files(__package__) / f"{algo}.yml"))


def load_hyperparams(path: str | Path, env_id: str, profile: str | None = None) -> dict[str, Any]:
    """Read the entry for ``env_id`` (merged with its ``profile``) from a Zoo-style YAML file.

    Parameters
    ----------
    path : str or Path
        YAML file keyed by env id.
    env_id : str
        Gymnasium id, e.g. ``"LunarSoftLanding-v0"``.
    profile : str, optional
        Name of a profile entry ``<env_id>@<profile>`` merged over the base entry; ``None`` or
        ``"default"`` selects the base entry alone.

    Returns
    -------
    dict
        A fresh copy of the hyperparameters (still plain YAML data; see
        :func:`resolve_algo_kwargs`).

    Raises
    ------
    ValueError
        If the file is not a mapping of mappings, the env id or profile has no entry, or a
        ``policy_kwargs`` value is a string (the Zoo's ``eval`` form, which is refused).
    """
    path = Path(path)
    with path.open(encoding="utf-8") as fh:
        data = yaml.safe_load(fh)
    if not isinstance(data, Mapping):
        raise ValueError(f"{path}: expected a mapping of env id -> hyperparameters, "
                         f"got {type(data).__name__}")
    base_ids = sorted(k for k in data if PROFILE_SEPARATOR not in str(k))
    if env_id not in data:
        raise ValueError(f"{path}: no entry for env id {env_id!r}; entries: {base_ids}")
    hp = _as_mapping(data[env_id], f"{path}:{env_id}")
    if profile not in (None, "", "default"):
        key = f"{env_id}{PROFILE_SEPARATOR}{profile}"
        if key not in data:
            profiles = sorted(k for k in data if str(k).startswith(env_id + PROFILE_SEPARATOR))
            raise ValueError(f"{path}: no profile {profile!r} for {env_id!r} (key {key!r}); "
                             f"available: {profiles or 'none'}")
        hp = _merge(hp, _as_mapping(data[key], f"{path}:{key}"))
    pk = hp.get("policy_kwargs")
    if pk is not None and not isinstance(pk, Mapping):
        raise ValueError(
            f"{path}:{env_id}: policy_kwargs must be a YAML mapping (e.g. "
            f"'policy_kwargs: {{net_arch: [64, 64], activation_fn: tanh}}'), got {pk!r}; "
            "Python expressions are not evaluated")
    return copy.deepcopy(dict(hp))


def _as_mapping(value: Any, where: str) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ValueError(f"{where}: expected a mapping of hyperparameters, got {value!r}")
    return dict(value)


def _merge(base: Mapping[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    """Recursive merge: mappings merge key by key, anything else in ``over`` replaces."""
    out = dict(copy.deepcopy(base))
    for k, v in over.items():
        if isinstance(v, Mapping) and isinstance(out.get(k), Mapping):
            out[k] = _merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def parse_override(text: str) -> tuple[str, Any]:
    """Parse one ``key=value`` command-line override; the value is read as YAML.

    ``"n_steps=512"`` -> ``("n_steps", 512)``; ``"policy_kwargs={net_arch: [32, 32]}"`` ->
    a mapping. Dotted keys set nested values: ``"policy_kwargs.activation_fn=relu"``.
    """
    if "=" not in text:
        raise ValueError(f"hyperparameter override {text!r} must look like key=value")
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key:
        raise ValueError(f"hyperparameter override {text!r} has an empty key")
    return key, yaml.safe_load(raw)


def apply_overrides(hp: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """Return ``hp`` with ``overrides`` applied (dotted keys address nested mappings)."""
    out = copy.deepcopy(dict(hp))
    for key, value in overrides.items():
        parts = key.split(".")
        node = out
        for p in parts[:-1]:
            nxt = node.get(p)
            if not isinstance(nxt, dict):
                nxt = {}
                node[p] = nxt
            node = nxt
        node[parts[-1]] = copy.deepcopy(value)
    return out


def linear_schedule(initial_value: float):
    """SB3 schedule decaying linearly from ``initial_value`` (progress 1) to 0 (progress 0)."""
    initial_value = float(initial_value)

    def schedule(progress_remaining: float) -> float:
        return progress_remaining * initial_value

    schedule.initial_value = initial_value  # type: ignore[attr-defined]
    return schedule


def _schedule_or_float(name: str, value: Any):
    if isinstance(value, bool):
        raise ValueError(f"{name}={value!r}: expected a number or 'lin_<number>'")
    if isinstance(value, int | float):
        return float(value)
    if isinstance(value, str):
        if value.startswith("lin_"):
            try:
                return linear_schedule(float(value[4:]))
            except ValueError:
                pass
        else:
            try:
                return float(value)
            except ValueError:
                pass
    raise ValueError(f"{name}={value!r}: expected a number or 'lin_<number>' (e.g. lin_3e-4)")


def _resolve_policy_kwargs(pk: Mapping[str, Any]) -> dict[str, Any]:
    import torch

    out = dict(copy.deepcopy(pk))
    if "activation_fn" in out:
        name = out["activation_fn"]
        if name not in _ACTIVATIONS:
            raise ValueError(f"policy_kwargs.activation_fn={name!r}; allowed: "
                             f"{sorted(_ACTIVATIONS)}")
        out["activation_fn"] = getattr(torch.nn, _ACTIVATIONS[name])
    if "optimizer_class" in out:
        name = out["optimizer_class"]
        if name not in _OPTIMIZERS:
            raise ValueError(f"policy_kwargs.optimizer_class={name!r}; allowed: "
                             f"{sorted(_OPTIMIZERS)}")
        out["optimizer_class"] = getattr(torch.optim, _OPTIMIZERS[name])
    if "net_arch" in out:
        na = out["net_arch"]
        ok = (isinstance(na, list) and all(isinstance(n, int) for n in na)) or (
            isinstance(na, Mapping) and all(
                isinstance(v, list) and all(isinstance(n, int) for n in v) for v in na.values()))
        if not ok:
            raise ValueError(f"policy_kwargs.net_arch={na!r}: expected a list of layer sizes or "
                             "a mapping like {pi: [64, 64], vf: [64, 64]}")
        if isinstance(na, Mapping):
            out["net_arch"] = {k: list(v) for k, v in na.items()}
    for k, v in out.items():
        if isinstance(v, str) and k not in ("activation_fn", "optimizer_class"):
            raise ValueError(f"policy_kwargs.{k}={v!r}: strings are not evaluated; give a number, "
                             "list or mapping")
    return out


def _check_keys(hp: Mapping[str, Any], algo: str) -> None:
    import inspect

    if algo not in ALGOS:
        raise ValueError(f"algo={algo!r} is not supported; choose one of {ALGOS}")
    cls = algo_class(algo)
    params = set(inspect.signature(cls.__init__).parameters)
    allowed = (params - {"self", "env", "_init_setup_model"}) | set(RUN_KEYS)
    unknown = sorted(map(str, set(hp) - allowed))
    if unknown:
        raise ValueError(f"{algo} hyperparameters: unknown key(s) {unknown}; allowed: the run "
                         f"keys {list(RUN_KEYS)} and the arguments of {cls.__name__}")


def resolve_algo_kwargs(hp: Mapping[str, Any], algo: str, n_actions: int | None = None
                        ) -> dict[str, Any]:
    """Turn YAML hyperparameters into keyword arguments for the SB3 algorithm constructor.

    Run keys (:data:`RUN_KEYS`) are dropped; schedules, activation and optimizer names and
    action noise are resolved to Python objects.

    Parameters
    ----------
    hp : mapping
        Output of :func:`load_hyperparams` (after overrides).
    algo : str
        One of :data:`ALGOS`.
    n_actions : int, optional
        Action dimension, needed only when ``noise_type`` is set.

    Raises
    ------
    ValueError
        A key is neither a run key nor an argument of the algorithm's constructor (refused
        here, before a run directory is made, rather than when the algorithm is built).
    """
    algo = algo.lower()
    _check_keys(hp, algo)
    out: dict[str, Any] = {k: copy.deepcopy(v) for k, v in hp.items() if k not in RUN_KEYS}
    for key in ("learning_rate", "clip_range", "clip_range_vf"):
        if key in out and out[key] is not None:
            out[key] = _schedule_or_float(key, out[key])
    if "policy_kwargs" in out:
        pk = out["policy_kwargs"]
        if not isinstance(pk, Mapping):
            raise ValueError(f"policy_kwargs={pk!r}: must be a mapping; strings are not evaluated")
        out["policy_kwargs"] = _resolve_policy_kwargs(pk)
    noise_type = hp.get("noise_type")
    if noise_type is not None:
        if algo in ("ppo", "recurrent-ppo"):
            raise ValueError(f"noise_type is for off-policy algorithms (sac, td3), not {algo}")
        if n_actions is None:
            raise ValueError("n_actions is required to build action noise")
        import numpy as np
        from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise

        std = float(hp.get("noise_std", 0.1))
        cls = {"normal": NormalActionNoise, "ornstein-uhlenbeck": OrnsteinUhlenbeckActionNoise}
        if noise_type not in cls:
            raise ValueError(f"noise_type={noise_type!r}; allowed: {sorted(cls)}")
        out["action_noise"] = cls[noise_type](mean=np.zeros(n_actions),
                                              sigma=std * np.ones(n_actions))
    return out
