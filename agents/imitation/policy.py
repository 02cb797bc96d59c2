"""The cloned policy: an SB3 PPO model built for an env, its inputs, mean actions, and the
supervised fit of its actor on (observation, action) pairs.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from agents.common.actor import actor_parameters

# ----------------------------------------------------------------------------- model


def _policy_kwargs(pk: dict[str, Any]) -> dict[str, Any]:
    from agents.hyperparams import resolve_algo_kwargs

    return resolve_algo_kwargs({"policy_kwargs": pk}, "ppo")["policy_kwargs"]


def build_model(env_id: str, env_kwargs: dict[str, Any] | None, policy_kwargs: dict[str, Any],
                seed: int, device: str = "cpu", obs_features: list[str] | None = None,
                standardize_inputs: np.ndarray | bool | None = None,
                history: int | None = None):
    """A fresh SB3 PPO model (MlpPolicy) on a one-lander SB3 vec env of ``env_id``.

    Only its policy is trained here; the PPO wrapper makes the saved zip loadable by
    ``PPO.load`` and fine-tunable. ``obs_features`` (:mod:`agents.features`) widen its input
    as in RL training, and a ``history`` of k decisions stacks the last k inputs and actions
    (:class:`agents.features.history.HistoryWrapper`); the run's ``config.yml`` records both,
    so :class:`agents.laws.SB3Law` and ``train.py --init-from`` apply the same inputs.

    ``standardize_inputs``: an array of policy inputs (N, n_in) whose statistics the policy
    standardises its inputs with (:class:`agents.features.StandardizedInputs`), or True for
    placeholder statistics that a loaded state dict replaces.
    """
    from stable_baselines3 import PPO

    from agents.common.vec_env import make_sb3_vec_env

    venv = make_sb3_vec_env(env_id, 1, seed=seed, **(env_kwargs or {}))
    if obs_features:
        from agents.features import ObsFeatureWrapper

        venv = ObsFeatureWrapper(venv, obs_features)
    if history is not None:
        from agents.features.history import HistoryWrapper

        venv = HistoryWrapper(venv, history)
    pk = _policy_kwargs(policy_kwargs)
    if standardize_inputs is not None and standardize_inputs is not False:
        from agents.features import StandardizedInputs, standardized_inputs_kwargs

        if isinstance(standardize_inputs, np.ndarray):
            pk.update(standardized_inputs_kwargs(standardize_inputs))
        else:
            pk["features_extractor_class"] = StandardizedInputs
    return PPO("MlpPolicy", venv, policy_kwargs=pk, seed=seed, device=device, verbose=0)


def policy_inputs(env_id: str, env_kwargs: dict[str, Any] | None,
                  obs_features: list[str] | None):
    """``f(obs) -> policy input``: the env observation with the ``obs_features`` appended
    (identity without features). Datasets and DAgger labels store the env's raw
    observations; the features are applied when fitting and acting."""
    from agents.features import augment_observation, feature_constants, validate_features

    names = validate_features(obs_features)
    if not names:
        return lambda obs: np.asarray(obs, dtype=np.float32)
    from agents.imitation.flights import make_env

    env = make_env(env_id, env_kwargs)
    consts = feature_constants(env)
    return lambda obs: augment_observation(np.asarray(obs), consts, names)


def load_learner(policy_file: str | Path, env_id: str, env_kwargs: dict[str, Any] | None,
                 obs_features: list[str] | None, history: int | None = None):
    """The saved policy as a DAgger student. Module level: the families' DAgger tasks receive
    it (:class:`agents.imitation.families.DaggerRequest`).

    Without a ``history``: its deterministic actions as ``fn(obs (N, n_obs)) -> actions
    (N, n_act)`` (the env's raw observations; the ``obs_features`` are appended here).

    With a ``history`` (k decisions, :mod:`agents.features.history`): a guidance law
    (:class:`agents.laws.SB3Law`) with memory per lander, which the roll-out resets, asks
    and tells the actions flown (:meth:`~agents.laws.SB3Law.flown`: the teacher's where it
    flies), so that its stacked inputs (``last_inputs``, the labels' inputs) are those it
    would build flying alone.
    """
    model = load_policy_model(policy_file)
    if history is not None:
        from agents.laws import SB3Law

        return SB3Law(model, None, name="DAgger student", obs_features=obs_features,
                      history=history)
    inputs = policy_inputs(env_id, env_kwargs, obs_features)
    return lambda obs: model.predict(inputs(obs), deterministic=True)[0]


def mean_actions(policy, obs):
    """Deterministic (mean) actions of an ``ActorCriticPolicy`` for a torch batch ``obs``."""
    features = policy.extract_features(obs, policy.pi_features_extractor)
    latent_pi = policy.mlp_extractor.forward_actor(features)
    return policy.action_net(latent_pi)


def load_policy_model(path: str | Path, device: str = "cpu"):
    """Load a PPO zip (or a run directory holding ``model.zip``)."""
    from stable_baselines3 import PPO

    p = Path(path)
    if p.is_dir():
        p = p / "model.zip"
    if not p.exists():
        raise FileNotFoundError(f"no model at {p}; give a run directory with model.zip or a .zip")
    return PPO.load(p, device=device)


# ----------------------------------------------------------------------------- fitting


def fit_policy(policy, obs: np.ndarray, act: np.ndarray, *, n_epochs: int, batch_size: int,
               learning_rate: float, learning_rate_final: float, rng: np.random.Generator,
               extra_obs: np.ndarray | None = None, extra_act: np.ndarray | None = None,
               extra_fraction: float = 0.0, val_obs: np.ndarray | None = None,
               val_act: np.ndarray | None = None, optimizer=None, start_epoch: int = 0,
               on_epoch=None, logger=None, progress: bool = True, log_prefix: str = "bc",
               step_offset: int = 0) -> dict[str, Any]:
    """Regress the policy's mean action on ``act`` (MSE), epoch by epoch.

    Parameters
    ----------
    policy : ActorCriticPolicy
    obs, act : ndarray, shapes (N, n_obs), (N, n_act)
        Main data; one epoch is one pass over it in random order.
    extra_obs, extra_act, extra_fraction :
        Extra data (DAgger labels), ``extra_fraction`` of every minibatch, drawn with
        replacement.
    val_obs, val_act : optional validation data (loss logged per epoch).
    optimizer : torch optimizer, optional
        Reused across calls (resume); created (Adam on the actor) if None.
    start_epoch : int
        First epoch index (resume); the cosine learning-rate schedule runs over ``n_epochs``.
    on_epoch : callable(epoch, optimizer, stats), optional
        Called after each epoch (checkpoints).

    Returns
    -------
    dict with the last ``train_loss``, ``val_loss``, ``val_rms_deg`` and the ``optimizer``.
    """
    import torch as th

    device = policy.device
    if optimizer is None:
        optimizer = th.optim.Adam(actor_parameters(policy, include_log_std=False), lr=learning_rate)
    n = len(obs)
    if n == 0:
        raise ValueError("no training samples")
    n_extra = 0 if extra_obs is None else len(extra_obs)
    f = float(extra_fraction) if n_extra else 0.0
    bs_main = max(int(round(batch_size * (1.0 - f))), 1)
    bs_extra = int(batch_size) - bs_main if n_extra else 0
    n_batches = max(n // bs_main, 1)
    total = max(int(n_epochs) * n_batches, 1)
    obs_t = th.as_tensor(obs, dtype=th.float32, device=device)
    act_t = th.as_tensor(act, dtype=th.float32, device=device)
    if n_extra:
        eobs_t = th.as_tensor(extra_obs, dtype=th.float32, device=device)
        eact_t = th.as_tensor(extra_act, dtype=th.float32, device=device)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=total, initial=start_epoch * n_batches, desc=log_prefix, unit="batch")
    stats: dict[str, Any] = {}
    policy.set_training_mode(True)
    try:
        for epoch in range(start_epoch, int(n_epochs)):
            perm = rng.permutation(n)
            run_loss = 0.0
            for b in range(n_batches):
                step = epoch * n_batches + b
                lr = learning_rate_final + 0.5 * (learning_rate - learning_rate_final) * (
                    1.0 + math.cos(math.pi * step / total))
                for g in optimizer.param_groups:
                    g["lr"] = lr
                idx = perm[b * bs_main:(b + 1) * bs_main]
                o, a = obs_t[idx], act_t[idx]
                if bs_extra:
                    j = rng.integers(0, n_extra, size=bs_extra)
                    o = th.cat([o, eobs_t[j]])
                    a = th.cat([a, eact_t[j]])
                loss = th.mean((mean_actions(policy, o) - a) ** 2)
                optimizer.zero_grad()
                loss.backward()
                optimizer.step()
                run_loss += float(loss.detach())
                if bar is not None:
                    bar.update(1)
            stats = {"epoch": epoch, "train_loss": run_loss / n_batches, "learning_rate": lr}
            if val_obs is not None and len(val_obs):
                with th.no_grad():
                    policy.set_training_mode(False)
                    vo = th.as_tensor(val_obs, dtype=th.float32, device=device)
                    va = th.as_tensor(val_act, dtype=th.float32, device=device)
                    vl = float(th.mean((mean_actions(policy, vo) - va) ** 2))
                    policy.set_training_mode(True)
                stats["val_loss"] = vl
                # action 1 = 90°: RMS error of the thrust angle in degrees
                stats["val_rms_deg"] = 90.0 * math.sqrt(vl)
            if logger is not None:
                for k, v in stats.items():
                    if k != "epoch":
                        logger.record(f"{log_prefix}/{k}", v)
                logger.dump(step_offset + epoch + 1)
            if bar is not None:
                bar.set_postfix({k: f"{v:.3g}" for k, v in stats.items() if k != "epoch"})
            if on_epoch is not None:
                on_epoch(epoch, optimizer, stats)
    finally:
        if bar is not None:
            bar.close()
        policy.set_training_mode(False)
    stats["optimizer"] = optimizer
    return stats


def _split_by_trajectory(ds, val_fraction: float, rng: np.random.Generator):
    tid = ds.arrays["traj_index"]
    ids = np.unique(tid)
    n_val = int(round(val_fraction * len(ids))) if len(ids) > 1 else 0
    val_ids = rng.choice(ids, size=n_val, replace=False) if n_val else np.zeros(0, int)
    is_val = np.isin(tid, val_ids)
    return ~is_val, is_val


def imitation_history(hp: dict[str, Any], mode: str) -> int | None:
    """The run's ``history`` (k decisions, :mod:`agents.features.history`), checked for its
    ``mode`` (``bc`` or ``dagger``) before any work starts.

    A student with a history learns by DAgger from a law teacher: the teacher flies the first
    iteration and the student's own stacked inputs are the labels' inputs. A dataset holds no
    histories, so it is not trained on.

    Raises
    ------
    ValueError
        ``history`` is not an integer from 1 to :data:`agents.features.history.MAX_HISTORY`;
        or it is set for behaviour cloning, with a built-in DAgger teacher (``privileged``,
        ``navigated``), or with a ``dagger_fraction`` (a share of every minibatch from the
        dataset).
    """
    from agents.features.history import validate_history

    k = validate_history(hp.get("history"))
    if k is None:
        return None
    if mode != "dagger":
        raise ValueError(f"history={k}: behaviour cloning trains on a dataset, which holds no "
                         "histories; a student with a history learns by DAgger "
                         "(python -m agents.imitation dagger) from a law teacher")
    from agents.imitation.teachers import parse_teacher

    dg = hp.get("dagger") or {}
    teacher = parse_teacher(dg.get("teacher"))
    if not teacher.is_law:
        raise ValueError(f"history={k} with dagger teacher = {teacher.kind!r}: a student with "
                         "a history learns from a law teacher (dagger.teacher a law spec, "
                         "e.g. 'zem-zev'), which flies along and labels what the student sees")
    if dg.get("dagger_fraction") is not None:
        raise ValueError(f"history={k} with dagger_fraction={dg['dagger_fraction']!r}: the "
                         "dataset holds no histories, so a student with a history trains on "
                         "the DAgger labels alone; set dagger_fraction: null")
    return k
