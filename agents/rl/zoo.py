"""RL Baselines3 Zoo support: the Zoo files generated from the shipped hyperparameters, and the
``vec_env_wrapper`` that gives the Zoo the project's native vector env.

The project's YAML (``agents/hyperparams/<algo>.yml``) is data (no ``eval``) with keys of its
own (``obs_features``, ``reward_shaping``, ``curriculum``, ...). The Zoo evaluates
``policy_kwargs`` strings and knows none of those keys, so this module *generates* the Zoo's
files from the same source::

    python -m agents.rl.zoo            # (re)write agents/hyperparams/zoo/<algo>[_quick].yml
    python -m agents.rl.zoo --check    # exit 1 if a shipped Zoo file is out of date

    python -m rl_zoo3.train --algo ppo --env LunarSoftLanding-v0 --gym-packages lunar_env \\
        --conf-file agents/hyperparams/zoo/ppo.yml

Translation of an entry (:func:`zoo_entry`):

- ``policy_kwargs`` becomes the Zoo's Python string (``activation_fn: tanh`` ->
  ``nn.Tanh``, ``optimizer_class: adam`` -> ``th.optim.Adam``);
- ``obs_features``, ``reward_shaping``, ``curriculum`` and ``history`` become keyword arguments
  of the ``vec_env_wrapper`` :func:`lunar_vec_env`, which replaces the Zoo's ``DummyVecEnv`` by the
  natively batched env and wraps it exactly as ``python train.py`` does
  (:func:`agents.rl.training.make_training_env`);
- everything else the Zoo understands (``n_envs``, ``n_timesteps``, ``policy``, ``normalize``,
  ``env_kwargs``, ``lin_<x>`` schedules, ``noise_type``, algorithm arguments) is copied;
- ``select_checkpoint``, ``seed_race``, ``critic_warmup_steps``, ``added_action_init`` and
  ``initial_action`` (run-level features of ``python train.py``: checkpoint selection, a race
  of two seeds, a held actor, a widened or biased action head) have no Zoo counterpart and are
  left out; the file's header names them.

Profiles (``<env id>@quick``) are merged into ``<algo>_quick.yml`` (the Zoo reads one entry per
env id). ``recurrent-ppo`` is the Zoo's ``ppo_lstm`` (sb3-contrib's ``RecurrentPPO``; the Zoo
builds sb3-contrib's own ``MlpLstmPolicy``, which computes what
:class:`agents.common.recurrent.SequenceLstmPolicy` does, more slowly):
``python -m rl_zoo3.train --algo ppo_lstm --conf-file agents/hyperparams/zoo/recurrent-ppo.yml``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml
from stable_baselines3.common.vec_env import VecEnvWrapper

from agents.hyperparams import ALGOS, PROFILE_SEPARATOR, default_hyperparams_path, load_hyperparams

__all__ = ["lunar_vec_env", "TrainingOnly", "zoo_entry", "zoo_hyperparams", "render_zoo_yaml",
           "zoo_path",
           "ZOO_PROFILES", "LEFT_OUT_KEYS", "ZOO_ALGO_NAMES", "main"]

#: profiles for which a Zoo file is generated (None: the base entries)
ZOO_PROFILES: tuple[str | None, ...] = (None, "quick")
#: run-level keys of ``python train.py`` the Zoo has no counterpart for
LEFT_OUT_KEYS = ("select_checkpoint", "seed_race", "critic_warmup_steps", "added_action_init",
                 "initial_action")
#: keys handed to :func:`lunar_vec_env`
_WRAPPER_KEYS = ("obs_features", "reward_shaping", "curriculum", "history")
#: the Zoo's name of an algorithm whose name here differs (``--algo`` of ``rl_zoo3.train``)
ZOO_ALGO_NAMES = {"recurrent-ppo": "ppo_lstm"}
_WRAPPER = "agents.rl.zoo.lunar_vec_env"
_ACTIVATIONS = {"tanh": "nn.Tanh", "relu": "nn.ReLU", "elu": "nn.ELU",
                "leaky_relu": "nn.LeakyReLU", "gelu": "nn.GELU", "silu": "nn.SiLU"}
_OPTIMIZERS = {"adam": "th.optim.Adam", "adamw": "th.optim.AdamW",
               "rmsprop": "th.optim.RMSprop", "sgd": "th.optim.SGD"}


# ----------------------------------------------------------------------------- the wrapper


def _monitor_file(venv) -> str | None:
    """The monitor CSV path of the Zoo's first sub-env (None for an evaluation env, which the Zoo
    builds without a log directory)."""
    from stable_baselines3.common.monitor import Monitor

    env = venv.envs[0]
    while env is not None:
        if isinstance(env, Monitor):
            writer = env.results_writer
            return None if writer is None else writer.file_handler.name
        env = getattr(env, "env", None)
    return None


def lunar_vec_env(venv, *, native: bool = True, obs_features: list[str] | None = None,
                  reward_shaping: dict[str, Any] | None = None,
                  curriculum: dict[str, Any] | None = None, gamma: float = 0.99,
                  total_timesteps: int = 0, history: int | None = None):
    """The Zoo's ``vec_env_wrapper``: swap its ``DummyVecEnv`` for the native batched env.

    The Zoo calls ``lunar_vec_env(venv, **kwargs)`` on the ``DummyVecEnv`` of ``n_envs``
    single envs it built (with ``env_kwargs`` and the run's seed). This function reads the env
    id, its constructor arguments, ``n_envs`` and the seed from it, closes it, and returns the
    training env ``python train.py`` would build (:func:`agents.rl.training.make_training_env`):
    the native vector env with the curriculum, the reward shaping, the observation features and
    the stacked history, under a ``VecMonitor`` that writes the Zoo's monitor CSV
    (``<log dir>/native.monitor.csv``).

    The Zoo applies the same wrapper to its evaluation env (and ``rl_zoo3.enjoy`` to its test
    env), which it builds without a monitor file: those get the features and the history only
    (curriculum starts and shaping are training devices; evaluation measures the env's own
    episodes and rewards; :class:`TrainingOnly` stands in for each, keeping the chain's depth).
    ``total_timesteps`` (the curriculum's annealing length) is the entry's
    ``n_timesteps``: a Zoo ``-n`` override does not change it.

    Parameters
    ----------
    venv : stable_baselines3 DummyVecEnv
        The Zoo's env of a ``lunar_env`` id.
    native : bool
        False keeps the ``DummyVecEnv`` (allowed only without features, shaping and
        curriculum, which need the native batch); for speed comparisons.
    obs_features, reward_shaping, curriculum, gamma, total_timesteps, history
        As in :func:`agents.rl.training.make_training_env`.

    Raises
    ------
    ValueError
        ``native=False`` with features, shaping or a curriculum, or ``venv`` is not a
        ``DummyVecEnv`` of a ``lunar_env`` id.
    """
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

    from agents.rl.training import _is_native_env, make_training_env

    if not isinstance(venv, DummyVecEnv):
        raise ValueError(f"lunar_vec_env wraps the Zoo's DummyVecEnv (--vec-env dummy), got "
                         f"{type(venv).__name__}")
    if not native:
        if obs_features or reward_shaping or curriculum or history:
            raise ValueError("native=False: obs_features, reward_shaping, curriculum and history "
                             "need the native vector env; drop them or set native: true")
        return venv
    spec = venv.envs[0].spec
    if spec is None or not _is_native_env(spec.id):
        raise ValueError(f"lunar_vec_env needs a lunar_env id, got "
                         f"{getattr(spec, 'id', None)!r}")
    env_kwargs = dict(spec.kwargs)
    env_kwargs.pop("render_mode", None)
    seed = venv._seeds[0]
    monitor = _monitor_file(venv)
    n_envs = venv.num_envs
    venv.close()
    if monitor is None:
        return _evaluation_env(spec.id, n_envs, seed, env_kwargs, obs_features,
                               n_inactive=int(bool(curriculum)) + int(bool(reward_shaping)),
                               history=history)
    out = make_training_env(
        spec.id, n_envs, seed, env_kwargs=env_kwargs,
        curriculum=dict(curriculum) if curriculum else None,
        total_timesteps=int(total_timesteps), progress=False,
        obs_features=list(obs_features) if obs_features else None,
        reward_shaping=dict(reward_shaping) if reward_shaping else None,
        gamma=float(gamma), history=history)
    if isinstance(out, VecMonitor):
        out = VecMonitor(out.venv, filename=str(Path(monitor).parent / "native"))
    return out


class TrainingOnly(VecEnvWrapper):
    """Stands in an evaluation env for a training-only wrapper (curriculum, reward shaping):
    passes everything through, so that the evaluation env's wrapper chain has the training
    env's depth (SB3's ``sync_envs_normalization`` walks both chains side by side)."""

    def reset(self):
        """The wrapped env's reset."""
        return self.venv.reset()

    def step_wait(self):
        """The wrapped env's step."""
        return self.venv.step_wait()


def _evaluation_env(env_id: str, n_envs: int, seed: int | None, env_kwargs: dict[str, Any],
                    obs_features: list[str] | None, n_inactive: int,
                    history: int | None = None):
    """The native env with the observation features and the history, without the training
    devices."""
    from stable_baselines3.common.vec_env import VecMonitor

    from agents.common.vec_env import make_sb3_vec_env

    venv = make_sb3_vec_env(env_id, n_envs, seed=seed, **env_kwargs)
    for _ in range(n_inactive):
        venv = TrainingOnly(venv)
    if obs_features:
        from agents.features import ObsFeatureWrapper

        venv = ObsFeatureWrapper(venv, list(obs_features))
    if history:
        from agents.features.history import HistoryWrapper

        venv = HistoryWrapper(venv, int(history))
    return VecMonitor(venv)


# ----------------------------------------------------------------------------- the generator


def _policy_kwargs_string(pk: Mapping[str, Any]) -> str:
    """The Zoo's ``policy_kwargs`` string for a project mapping (names -> Python objects)."""

    def lit(v: Any) -> str:
        if isinstance(v, Mapping):
            return "dict(" + ", ".join(f"{k}={lit(x)}" for k, x in v.items()) + ")"
        if isinstance(v, list | tuple):
            return "[" + ", ".join(lit(x) for x in v) + "]"
        if isinstance(v, bool) or v is None or isinstance(v, int | float):
            return repr(v)
        raise ValueError(f"policy_kwargs value {v!r}: expected a number, list or mapping")

    items = []
    for k, v in pk.items():
        if k == "activation_fn":
            if v not in _ACTIVATIONS:
                raise ValueError(f"policy_kwargs.activation_fn={v!r}; allowed: "
                                 f"{sorted(_ACTIVATIONS)}")
            items.append(f"{k}={_ACTIVATIONS[v]}")
        elif k == "optimizer_class":
            if v not in _OPTIMIZERS:
                raise ValueError(f"policy_kwargs.optimizer_class={v!r}; allowed: "
                                 f"{sorted(_OPTIMIZERS)}")
            items.append(f"{k}={_OPTIMIZERS[v]}")
        else:
            items.append(f"{k}={lit(v)}")
    return "dict(" + ", ".join(items) + ")"


def zoo_entry(hp: Mapping[str, Any]) -> dict[str, Any]:
    """One env id's Zoo hyperparameters from the project's (see the module docstring)."""
    out: dict[str, Any] = {}
    wrapper: dict[str, Any] = {}
    if hp.get("error_curriculum"):
        raise ValueError("error_curriculum is not available in RL Zoo files (its evaluation env "
                         "chain has no stand-in for it); train that entry with python train.py")
    norm = hp.get("normalize")
    if isinstance(norm, Mapping) and "update" in norm:
        raise ValueError("normalize.update is not a VecNormalize argument, and the Zoo cannot "
                         "keep loaded statistics fixed; train that entry with python train.py")
    for k, v in hp.items():
        if k in LEFT_OUT_KEYS:
            continue
        if k in _WRAPPER_KEYS:
            if v:
                wrapper[k] = v
        elif k == "policy_kwargs" and v is not None:
            out[k] = _policy_kwargs_string(v)
        else:
            out[k] = v
    if "reward_shaping" in wrapper:
        wrapper["gamma"] = float(hp.get("gamma", 0.99))
    if "curriculum" in wrapper:
        wrapper["total_timesteps"] = int(float(hp["n_timesteps"]))
    out["vec_env_wrapper"] = [{_WRAPPER: wrapper}]
    return out


def zoo_hyperparams(algo: str, profile: str | None = None,
                    source: str | Path | None = None) -> dict[str, dict[str, Any]]:
    """The Zoo file's content for ``algo``: one entry per env id of the project's file (merged
    with ``profile`` where the env id has one; env ids without it are left out)."""
    path = Path(source) if source is not None else default_hyperparams_path(algo)
    with path.open(encoding="utf-8") as fh:
        data = yaml.safe_load(fh)
    ids = [k for k in data if PROFILE_SEPARATOR not in str(k)]
    out: dict[str, dict[str, Any]] = {}
    for env_id in ids:
        if profile is not None and f"{env_id}{PROFILE_SEPARATOR}{profile}" not in data:
            continue
        out[env_id] = zoo_entry(load_hyperparams(path, env_id, profile))
    return out


def zoo_path(algo: str, profile: str | None = None) -> Path:
    """Where the Zoo file of ``algo`` (and ``profile``) is shipped."""
    name = algo if profile is None else f"{algo}_{profile}"
    return default_hyperparams_path(algo).parent / "zoo" / f"{name}.yml"


def render_zoo_yaml(algo: str, profile: str | None = None) -> str:
    """The text of the generated Zoo file (header comment + YAML)."""
    src = f"agents/hyperparams/{algo}.yml" + (f" (profile @{profile})" if profile else "")
    head = (f"# GENERATED by `python -m agents.rl.zoo` from {src}: do not edit; edit the source\n"
            "# and regenerate (tests/agents/rl/test_zoo.py fails when this file is stale).\n"
            f"# RL Baselines3 Zoo: python -m rl_zoo3.train --algo {ZOO_ALGO_NAMES.get(algo, algo)}"
            " --env <id> "
            "--gym-packages lunar_env \\\n"
            f"#   --conf-file agents/hyperparams/zoo/{zoo_path(algo, profile).name}\n"
            f"# Left out (run features of `python train.py` only): {', '.join(LEFT_OUT_KEYS)}.\n")
    body = yaml.safe_dump(zoo_hyperparams(algo, profile), sort_keys=False, width=100,
                          default_flow_style=None)
    return head + body


def main(argv: list[str] | None = None) -> int:
    """``python -m agents.rl.zoo [--check]``: write (or check) the generated Zoo files."""
    p = argparse.ArgumentParser(prog="python -m agents.rl.zoo",
                                description="Generate the RL Baselines3 Zoo hyperparameter files "
                                            "from agents/hyperparams/<algo>.yml.")
    p.add_argument("--check", action="store_true",
                   help="only check that the shipped files are up to date (exit 1 if not)")
    args = p.parse_args(argv)
    from agents.common.runs import write_text_atomic

    stale = []
    for algo in ALGOS:
        for profile in ZOO_PROFILES:
            path = zoo_path(algo, profile)
            text = render_zoo_yaml(algo, profile)
            current = path.read_text(encoding="utf-8") if path.exists() else None
            if current == text:
                continue
            if args.check:
                stale.append(str(path))
            else:
                path.parent.mkdir(parents=True, exist_ok=True)
                write_text_atomic(path, text)
                print(f"Written: {path}")
    if stale:
        print("Out of date (run python -m agents.rl.zoo): " + ", ".join(stale), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
