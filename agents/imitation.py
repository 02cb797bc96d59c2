"""Imitation of the optimiser: behaviour cloning (BC) and DAgger into an SB3 PPO policy.

::

    python -m agents.dataset --n 1000                                   # optimal landings
    python -m agents.imitation bc --dataset data/imitation/LunarSoftLanding-v0_n1000_seed0.npz
    python -m agents.imitation dagger --dataset <same> \\
        --init runs/imitation/bc_LunarSoftLanding-v0_1
    python -m agents.imitation bc --quick --dataset small.npz           # CI-sized
    python -m agents.imitation bc --resume runs/imitation/bc_LunarSoftLanding-v0_1
    python train.py --init-from runs/imitation/bc_LunarSoftLanding-v0_1  # PPO fine-tuned from BC
    python -m agents.imitation evaluate --model BC=runs/imitation/bc_... \\
        --model DAgger=runs/imitation/dagger_... --model PPO=runs/ppo/... --n-states 1000

The ``imitation`` library pins gymnasium 0.29 / SB3 2.2, so both algorithms are written here on
SB3's ``ActorCriticPolicy`` and torch:

- **BC** ([Pomerleau 1991]; as in ``imitation.algorithms.bc``): the policy's Gaussian *mean*
  action is regressed on the dataset's optimal actions (mean-squared error; decision: the
  evaluation flies the deterministic mean, and MSE on it is what matters; ``log_std`` keeps its
  initial value so PPO starts exploring from ``log_std_init``). Only the actor (``mlp_extractor``
  policy branch + ``action_net``) is trained; the value branch is left for PPO.
- **DAgger** ([Ross, Gordon & Bagnell 2011]): iteration i rolls out the current policy
  (β = 0: the first "expert" iteration is the BC dataset itself) in the native vector env,
  labels visited states with the closed-loop expert :class:`agents.experts.
  PontryaginExpert` (re-solves the optimal problem from the state), aggregates, and retrains
  the policy (warm-started) on the union, each minibatch mixing ``dagger_fraction`` DAgger
  labels with optimal-trajectory samples (``dagger_fraction: null``: all data pooled and drawn
  alike, as the pinpoint entry does). Labels: the thrust angle of the expert's new plan at
  the middle of the env step (the dataset's label rule); where the expert holds, falls back or
  plans with the ground constraint, the angle it returns.

Output: a run directory ``runs/imitation/<bc|dagger>_<env id>_<k>/`` in the layout of
:mod:`agents.train` — ``config.yml``, ``args.yml`` (``algo: ppo``), ``command.txt``, ``tb/``
(TensorBoard), ``checkpoints/``, and ``model.zip``, a Stable-Baselines3 **PPO** model whose
policy holds the cloned weights (``PPO.load`` works; ``agents.evaluate --model`` and
``train.py --init-from`` accept the directory). Hyperparameters: ``agents/hyperparams/
imitation.yml`` keyed by env id. ``--resume RUN_DIR`` continues from the newest checkpoint
(BC: epoch; DAgger: iteration, whose labels are kept on disk and not recomputed).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import shlex
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.runs import save_model_atomic, write_text_atomic
from agents.training import actor_parameters

__all__ = ["build_model", "mean_actions", "fit_policy", "train_bc", "train_dagger",
           "rollout_policy", "label_episodes", "load_policy_model", "main"]

DEFAULT_ENV_ID = "LunarSoftLanding-v0"
_HP_FILE = Path(__file__).parent / "hyperparams" / "imitation.yml"
_BC_CKPT = re.compile(r"^bc_epoch_(\d+)\.pt$")
_DG_CKPT = re.compile(r"^dagger_iter_(\d+)\.zip$")


# ----------------------------------------------------------------------------- model


def _policy_kwargs(pk: dict[str, Any]) -> dict[str, Any]:
    from agents.hyperparams import resolve_algo_kwargs

    return resolve_algo_kwargs({"policy_kwargs": pk}, "ppo")["policy_kwargs"]


def build_model(env_id: str, env_kwargs: dict[str, Any] | None, policy_kwargs: dict[str, Any],
                seed: int, device: str = "cpu", obs_features: list[str] | None = None,
                standardize_inputs: np.ndarray | bool | None = None):
    """A fresh SB3 PPO model (MlpPolicy) on a one-lander SB3 vec env of ``env_id``.

    Only its policy is trained here; the PPO wrapper makes the saved zip loadable by
    ``PPO.load`` and fine-tunable. ``obs_features`` (:mod:`agents.features`) widen its input
    as in RL training; the run's ``config.yml`` records them, so :class:`agents.evaluate.
    SB3Policy` and ``train.py --init-from`` apply the same inputs.

    ``standardize_inputs``: an array of policy inputs (N, n_in) whose statistics the policy
    standardises its inputs with (:class:`agents.features.StandardizedInputs`), or True for
    placeholder statistics that a loaded state dict replaces.
    """
    from stable_baselines3 import PPO

    from agents.vec_env import make_sb3_vec_env

    venv = make_sb3_vec_env(env_id, 1, seed=seed, **(env_kwargs or {}))
    if obs_features:
        from agents.features import ObsFeatureWrapper

        venv = ObsFeatureWrapper(venv, obs_features)
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
    from agents.dataset import _make_env

    env = _make_env(env_id, env_kwargs)
    consts = feature_constants(env)
    return lambda obs: augment_observation(np.asarray(obs), consts, names)


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


# ----------------------------------------------------------------------------- run dirs


def _new_run_dir(log_folder: str, mode: str, env_id: str) -> Path:
    from agents.runs import next_run_dir

    return next_run_dir(Path(log_folder) / "imitation", f"{mode}_{env_id}")


def _logger(run_dir: Path, tensorboard: bool):
    from stable_baselines3.common.logger import configure

    fmts = ["csv"] + (["tensorboard"] if tensorboard else [])
    return configure(str(run_dir / "tb"), fmts)


def _save_final(model, run_dir: Path) -> Path:
    from agents.runs import save_model_atomic

    return save_model_atomic(model, run_dir / "model.zip")


def _rng_state(rng: np.random.Generator) -> dict:
    return rng.bit_generator.state


# ----------------------------------------------------------------------------- BC


def train_bc(hp: dict[str, Any], run: dict[str, Any], run_dir: Path, resume: bool = False):
    """Behaviour cloning on ``run["dataset"]``; writes checkpoints and ``model.zip``.

    Returns the PPO model whose policy holds the cloned weights.
    """
    import torch as th

    from agents.dataset import load_dataset

    ds = load_dataset(run["dataset"])
    if ds.meta["env_id"] != run["env"]:
        raise ValueError(f"dataset {run['dataset']} is for {ds.meta['env_id']!r}, not "
                         f"{run['env']!r}")
    env_kwargs = ds.meta.get("env_kwargs") or {}
    bc = hp["bc"]
    seed = int(run["seed"])
    th.manual_seed(seed)
    obs = policy_inputs(run["env"], env_kwargs, hp.get("obs_features"))(ds.observations)
    rng = np.random.default_rng(seed)
    train_mask, val_mask = _split_by_trajectory(ds, float(bc.get("val_fraction", 0.0)), rng)
    model = build_model(run["env"], env_kwargs, hp["policy_kwargs"], seed, run["device"],
                        hp.get("obs_features"),
                        obs[train_mask] if hp.get("standardize_inputs") else None)
    policy = model.policy
    ckdir = run_dir / "checkpoints"
    ckdir.mkdir(parents=True, exist_ok=True)
    optimizer = None
    start = 0
    if resume:
        found = sorted((int(m.group(1)), f) for f in ckdir.iterdir()
                       if (m := _BC_CKPT.match(f.name)))
        if not found:
            raise FileNotFoundError(f"no BC checkpoint bc_epoch_<k>.pt in {ckdir}; start again "
                                    "without --resume")
        from agents.runs import newest_loadable

        # the newest checkpoint that loads (a damaged one is skipped, and said so)
        path, state = newest_loadable([f for _, f in reversed(found)],
                                      lambda f: th.load(f, weights_only=False),
                                      what="BC checkpoint")
        epoch = int(_BC_CKPT.match(path.name).group(1))
        policy.load_state_dict(state["policy"])
        optimizer = th.optim.Adam(actor_parameters(policy, include_log_std=False),
                                  lr=float(bc["learning_rate"]))
        optimizer.load_state_dict(state["optimizer"])
        rng.bit_generator.state = state["rng"]
        start = epoch + 1
        print(f"Resuming BC {run_dir} after epoch {epoch} of {bc['n_epochs']}")
    every = max(int(bc.get("checkpoint_every", 5)), 1)

    def on_epoch(epoch, opt, stats):
        if (epoch + 1) % every == 0 or epoch + 1 == int(bc["n_epochs"]):
            tmp = ckdir / f".bc_epoch_{epoch}.pt.{os.getpid()}.tmp"
            th.save({"policy": policy.state_dict(), "optimizer": opt.state_dict(),
                     "rng": _rng_state(rng), "stats": stats}, tmp)
            os.replace(tmp, ckdir / f"bc_epoch_{epoch}.pt")

    logger = _logger(run_dir, not run.get("no_tensorboard"))
    act = ds.actions
    t0 = time.perf_counter()
    stats = fit_policy(policy, obs[train_mask], act[train_mask], n_epochs=int(bc["n_epochs"]),
                       batch_size=int(bc["batch_size"]),
                       learning_rate=float(bc["learning_rate"]),
                       learning_rate_final=float(bc.get("learning_rate_final",
                                                        bc["learning_rate"])),
                       rng=rng, val_obs=obs[val_mask], val_act=act[val_mask],
                       optimizer=optimizer, start_epoch=start, on_epoch=on_epoch, logger=logger,
                       progress=not run.get("no_progress"), log_prefix="bc")
    wall = time.perf_counter() - t0
    logger.close()
    path = _save_final(model, run_dir)
    summary = {k: v for k, v in stats.items() if k != "optimizer"}
    summary.update(train_wall_s_this_session=wall, n_samples=int(train_mask.sum()),
                   n_val_samples=int(val_mask.sum()))
    write_text_atomic(run_dir / "bc_summary.yml", yaml.safe_dump(summary))
    print(f"BC done: {summary}. Model: {path}")
    return model


# ----------------------------------------------------------------------------- DAgger


def rollout_policy(model, env_id: str, env_kwargs: dict[str, Any] | None, n_episodes: int,
                   seed: int, obs_features: list[str] | None = None) -> list[dict[str, Any]]:
    """Fly the policy's deterministic actions from ``n_episodes`` dispersed starts.

    Sub-env i is reset with seed ``seed + i``. Returns one dict per episode: ``obs`` (T, n_obs),
    ``state_nd`` (T, 5), ``t_s`` (T,) — the states at which the policy acted — and the outcome
    ``success``, ``fuel_kg``, ``touchdown_speed_m_s``.
    """
    from agents.rollout import fly

    inputs = policy_inputs(env_id, env_kwargs, obs_features)

    def act(obs, venv, active):
        return model.predict(inputs(obs), deterministic=True)[0]

    res = fly(env_id, act, n_episodes, seed=seed, env_kwargs=env_kwargs,
              record=range(n_episodes), max_steps=100_000, name="policy")
    out: list[dict[str, Any]] = []
    for i in range(n_episodes):
        r = res.records[i]
        out.append({"success": bool(res.is_success[i]), "fuel_kg": float(res.fuel_used_kg[i]),
                    "touchdown_speed_m_s": float(res.touchdown_speed_m_s[i]),
                    "obs": r["obs"], "state_nd": r["state_nd"], "t_s": r["t_s"]})
    return out


def _pinpoint_dagger_chunk(job: dict[str, Any]) -> dict[str, Any]:
    """Fly one chunk of DAgger roll-outs on a pinpoint env and label every visited state with
    the Pontryagin feedback expert (a worker process; see :func:`pinpoint_dagger_rollouts`)."""
    import warnings

    import torch as th

    from agents.experts import PinpointPontryaginExpert
    from agents.rollout import fly
    from lunar_env import get_scenario

    th.set_num_threads(1)
    model = load_policy_model(job["model"])
    inputs = policy_inputs(job["env_id"], job["env_kwargs"], job["obs_features"])
    sc = get_scenario(job["scenario"])
    expert = PinpointPontryaginExpert(sc)
    n = int(job["n_episodes"])
    switch = np.asarray(job["switch_s"], dtype=np.float64)
    rec: dict[str, list] = {k: [] for k in ("obs", "actions", "phi_rad", "status")}

    def act(obs, venv, active):
        core = venv.unwrapped
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ang, lab, m = expert.label(core, active)
        st = np.asarray(expert.last_status)
        rec["obs"].append(np.asarray(obs)[m])
        rec["actions"].append(lab[m])
        rec["phi_rad"].append(ang[m])
        rec["status"].append(st[m].astype("<U12"))
        pol = model.predict(inputs(obs), deterministic=True)[0]
        return np.where((core.t_s < switch)[:, None], lab, pol).astype(np.float32)

    out = fly(job["env_id"], act, n, seed=int(job["seed"]), env_kwargs=job["env_kwargs"],
              name="DAgger roll-out")
    res = {k: np.concatenate(v) for k, v in rec.items()}
    res.update(success=out.is_success, fuel_kg=out.fuel_used_kg,
               touchdown_speed_m_s=out.touchdown_speed_m_s, miss_m=out.miss_distance_m,
               learner_only=switch <= 0.0)
    return res


def pinpoint_dagger_rollouts(model_path: str | Path, env_id: str,
                             env_kwargs: dict[str, Any] | None, n_episodes: int, seed: int,
                             obs_features: list[str] | None, beta: float, n_workers: int = 1,
                             cache_dir: str | Path | None = None, progress: bool = True
                             ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """One DAgger iteration's data on a pinpoint env: roll-outs of the policy saved at
    ``model_path`` from ``n_episodes`` dispersed starts (sub-env i seeded ``seed + i``), every
    visited state labelled by the Pontryagin feedback expert
    (:class:`agents.experts.PinpointPontryaginExpert`, the extremal from that state).

    Mixing (Ross et al. 2011's β): with probability ``beta`` an episode is flown by the expert
    up to a switch time drawn uniformly in [0, 540] s and by the policy after it, otherwise by
    the policy throughout; so the labelled states include the policy's own mistakes from every
    phase of the descent, not only from the start. The success rate reported is that of the
    policy-only episodes.

    ``cache_dir``: each chunk's labels are kept there (an :class:`optimizers.common.executor.
    ResultStore`) and reused on resume.
    Labels whose solve did not converge (status "stale"/"fallback") are not returned.
    """
    rng = np.random.default_rng([int(seed), 7])
    switch = np.where(rng.random(int(n_episodes)) < float(beta),
                      rng.uniform(0.0, 540.0, int(n_episodes)), 0.0)
    n_workers = max(1, min(int(n_workers), int(n_episodes)))
    bounds = np.linspace(0, int(n_episodes), n_workers + 1).astype(int)
    from agents.dataset import _make_env

    env = _make_env(env_id, env_kwargs)
    scenario = env.scenario.name
    env.close()
    jobs = [{"model": str(model_path), "env_id": env_id, "env_kwargs": dict(env_kwargs or {}),
             "obs_features": obs_features, "scenario": scenario, "seed": int(seed) + int(lo),
             "n_episodes": int(hi - lo), "switch_s": switch[lo:hi].tolist()}
            for lo, hi in zip(bounds[:-1], bounds[1:], strict=True) if hi > lo]
    from optimizers.common.executor import (
        LocalExecutor,
        ResultStore,
        Task,
        TaskKey,
        run_tasks,
    )

    # each chunk's result is stored as it arrives and read back on resume
    store = None if cache_dir is None else ResultStore(
        cache_dir, identity={"model": str(model_path), "env_id": env_id, "seed": int(seed),
                             "n_episodes": int(n_episodes), "beta": float(beta)},
        fmt="pickle")
    tasks = [Task(TaskKey(f"dagger-{env_id}", int(seed), k), _pinpoint_dagger_chunk, (job,))
             for k, job in enumerate(jobs)]
    with LocalExecutor(n_workers if n_workers > 1 else 0) as ex:
        results, _ = run_tasks(tasks, ex, store, progress=(
            f"DAgger roll-outs + expert labels ({n_workers} proc)" if progress else False))
    parts = [results[t.key] for t in tasks]
    lab = {k: np.concatenate([p[k] for p in parts]) for k in ("obs", "actions", "phi_rad",
                                                               "status")}
    succ = np.concatenate([p["success"] for p in parts])
    only = np.concatenate([p["learner_only"] for p in parts]).astype(bool)
    fuel = np.concatenate([p["fuel_kg"] for p in parts])
    sel = only if only.any() else np.ones(len(succ), dtype=bool)  # all mixed: over all
    roll = {"rollout_success_rate": float(np.mean(succ[sel])),
            "rollout_fuel_mean_kg": float(np.mean(fuel[sel])),
            "rollout_policy_only_episodes": float(sel.sum())}
    return lab, roll


def _label_chunk(job: dict[str, Any]) -> list[dict[str, np.ndarray]]:
    """Label the chosen steps of some episodes with the closed-loop expert (worker process)."""
    import warnings

    from agents.evaluate import planar_state_si
    from agents.experts import PontryaginExpert
    from lunar_env import get_scenario
    from lunar_env.envs.soft_landing import action_from_thrust_angle

    sc = get_scenario(job["scenario"])
    dt_s = float(job["dt_s"])
    res = []
    for ep in job["episodes"]:
        expert = PontryaginExpert(sc)
        idx = ep["label_idx"]
        si = planar_state_si(sc, ep["state_nd"][idx])
        phi = np.empty(len(idx))
        status = []
        n_fallback = 0
        n_done = len(idx)
        for j, k in enumerate(idx):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                p = float(expert(si[j], t_s=float(ep["t_s"][k])))
            st = expert.last_status[0]
            n_fallback = n_fallback + 1 if st == "fallback" else 0
            if n_fallback > int(job.get("max_fallbacks", 2)):
                # decision: no landing exists from here on (the expert failed repeatedly); the
                # rest of this episode teaches nothing and each failed re-plan costs seconds
                n_done = j
                break
            # decision: label with the new plan's angle at mid-step (the action is held for
            # dt_s), as the optimal-trajectory samples are labelled
            mem = getattr(expert, "_memory", {}).get(0)
            if st == "optimal" and mem is not None:
                p = float(mem[0].thrust_angle_at(0.5 * dt_s))
            phi[j] = p
            status.append(st)
        idx, phi = idx[:n_done], phi[:n_done]
        res.append({"obs": ep["obs"][idx],
                    "actions": np.asarray(action_from_thrust_angle(phi),
                                          dtype=np.float32).reshape(-1, 1),
                    "phi_rad": phi, "status": np.array(status[:n_done], dtype="<U12")})
    return res


def label_episodes(episodes: list[dict[str, Any]], scenario_name: str, dt_s: float,
                   label_every: int, dense_tail_s: float, n_workers: int = 1,
                   progress: bool = True, min_speed_m_s: float = 3.0,
                   velocity_ref_m_s: float | None = None,
                   cache_dir: str | Path | None = None,
                   tail_label_every: int = 1) -> dict[str, np.ndarray]:
    """Expert labels for the visited states of policy roll-outs.

    Every ``label_every``-th step of each episode and every step in its last ``dense_tail_s``
    seconds (where landing accuracy is decided) is labelled, in time order per episode so the
    expert re-plans warm-started from its previous plan. States slower than ``min_speed_m_s``
    relative to the surface are not labelled (decision): the env cuts the engine within a step
    there, so the action hardly matters, and from a near-hover high above the ground no landing
    exists — the expert then spends seconds to tens of seconds failing to find one (measured:
    40 s for one such state on the loaded machine) before returning its braking fallback.
    After more than two consecutive fallbacks an episode's remaining states are skipped too.

    ``cache_dir``: each task's labels are written there (``part_<k>.npz``) as it finishes, and
    tasks already there are not labelled again (resume within an iteration).

    ``tail_label_every`` thins the dense tail. Soft landing only: a pinpoint iteration flies
    and labels in one pass (:func:`pinpoint_dagger_rollouts`).

    Returns
    -------
    dict with ``obs`` (L, n_obs) float32, ``actions`` (L, 1) float32, ``phi_rad`` (L,),
    ``status`` (L,) str (the expert's per-label status).
    """
    from agents.dataset import _is_pinpoint
    from lunar_env import get_scenario

    if _is_pinpoint(get_scenario(scenario_name)):
        raise ValueError(f"scenario {scenario_name!r} is a pinpoint scenario: its DAgger data "
                         "comes from agents.imitation.pinpoint_dagger_rollouts")
    jobs_eps = []
    for ep in episodes:
        t = ep["t_s"]
        if len(t) == 0:
            continue
        k = np.arange(len(t))
        tail = t >= t[-1] - float(dense_tail_s)
        k_tail = np.cumsum(tail) - 1
        sel = (k % max(int(label_every), 1) == 0) | (
            tail & (k_tail % max(int(tail_label_every), 1) == 0))
        if velocity_ref_m_s is not None:
            x = ep["state_nd"]
            speed = np.hypot(x[:, 1], x[:, 0] * x[:, 3]) * float(velocity_ref_m_s)
            sel &= speed >= float(min_speed_m_s)
        jobs_eps.append({"obs": ep["obs"], "state_nd": ep["state_nd"], "t_s": t,
                         "label_idx": np.flatnonzero(sel)})
    n_workers = max(1, min(int(n_workers), len(jobs_eps)))
    # one task per few episodes: the pool balances the load and the bar moves as tasks finish
    per_task = max(1, min(4, len(jobs_eps) // (4 * n_workers) or 1))
    jobs = [{"scenario": scenario_name, "dt_s": dt_s, "episodes": jobs_eps[i:i + per_task]}
            for i in range(0, len(jobs_eps), per_task)]
    n_labels = sum(len(e["label_idx"]) for e in jobs_eps)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=n_labels, desc=f"expert labels ({n_workers} proc)", unit="label")
    results: list[list[dict[str, np.ndarray]] | None] = [None] * len(jobs)
    cache = Path(cache_dir) if cache_dir is not None else None
    keys = ("obs", "actions", "phi_rad", "status")

    def _part(i: int) -> Path:
        return cache / f"part_{i:04d}.npz"

    def _keep(i: int, res: list[dict[str, np.ndarray]]) -> None:
        results[i] = res
        if cache is not None:
            cache.mkdir(parents=True, exist_ok=True)
            tmp = _part(i).with_suffix(".tmp.npz")
            np.savez(tmp, n=np.array(len(res)),
                     **{f"{k}_{e}": r[k] for e, r in enumerate(res) for k in keys})
            os.replace(tmp, _part(i))
        if bar is not None:
            bar.update(sum(len(e["label_idx"]) for e in jobs[i]["episodes"]))

    todo = []
    for i in range(len(jobs)):
        if cache is not None and _part(i).exists():
            try:
                with np.load(_part(i)) as z:
                    results[i] = [{k: z[f"{k}_{e}"] for k in keys} for e in range(int(z["n"]))]
            except Exception as exc:  # a damaged cache part: label those episodes again
                print(f"label cache {_part(i)} is damaged ({type(exc).__name__}); relabelling")
                todo.append(i)
                continue
            if bar is not None:
                bar.update(sum(len(e["label_idx"]) for e in jobs[i]["episodes"]))
        else:
            todo.append(i)
    try:
        if n_workers == 1:
            for i in todo:
                _keep(i, _label_chunk(jobs[i]))
        else:
            from concurrent.futures import as_completed

            from agents.runs import process_pool

            with process_pool(n_workers) as ex:  # workers end with this process
                futs = {ex.submit(_label_chunk, jobs[i]): i for i in todo}
                for fut in as_completed(futs):
                    _keep(futs[fut], fut.result())
    finally:
        if bar is not None:
            bar.close()
    parts = [r for rs in results if rs for r in rs]
    if not parts:
        n_obs = episodes[0]["obs"].shape[1] if episodes else 5
        return {"obs": np.zeros((0, n_obs), np.float32),
                "actions": np.zeros((0, 1), np.float32),
                "phi_rad": np.zeros(0), "status": np.zeros(0, dtype="<U12")}
    return {k: np.concatenate([p[k] for p in parts]) for k in ("obs", "actions", "phi_rad",
                                                                "status")}


def train_dagger(hp: dict[str, Any], run: dict[str, Any], run_dir: Path, resume: bool = False):
    """DAgger with the closed-loop expert; returns the final PPO model (also ``model.zip``)."""
    import torch as th
    from stable_baselines3 import PPO

    from agents.dataset import load_dataset

    ds = load_dataset(run["dataset"])
    if ds.meta["env_id"] != run["env"]:
        raise ValueError(f"dataset {run['dataset']} is for {ds.meta['env_id']!r}, not "
                         f"{run['env']!r}")
    env_kwargs = ds.meta.get("env_kwargs") or {}
    dg = hp["dagger"]
    seed = int(run["seed"])
    th.manual_seed(seed)
    ckdir = run_dir / "checkpoints"
    ckdir.mkdir(parents=True, exist_ok=True)
    lbdir = run_dir / "labels"
    lbdir.mkdir(parents=True, exist_ok=True)
    done = sorted((int(m.group(1)), f) for f in ckdir.iterdir() if (m := _DG_CKPT.match(f.name)))
    if resume and done:
        from agents.runs import newest_loadable

        path, model = newest_loadable([f for _, f in reversed(done)],
                                      lambda f: PPO.load(f, device=run["device"]),
                                      what="DAgger checkpoint")
        it0 = int(_DG_CKPT.match(path.name).group(1))
        start = it0 + 1
        print(f"Resuming DAgger {run_dir} after iteration {it0} of {dg['n_iterations']}")
    else:
        if resume:
            print(f"No DAgger iteration finished in {run_dir}: starting from the initial policy")
        start = 0
        if run.get("init"):
            init = load_policy_model(run["init"], device=run["device"])
            model = build_model(run["env"], env_kwargs, hp["policy_kwargs"], seed, run["device"],
                                hp.get("obs_features"),
                                True if hp.get("standardize_inputs") else None)
            try:
                model.policy.load_state_dict(init.policy.state_dict())
            except RuntimeError as exc:
                raise ValueError(f"--init {run['init']}: its policy does not match "
                                 f"policy_kwargs {hp['policy_kwargs']} ({exc})") from None
        else:
            print("No --init policy: behaviour cloning first (bc section of the config)")
            bc_dir = run_dir / "bc_init"
            bc_dir.mkdir(exist_ok=True)
            # a run directory of its own (evaluate / --init-from read its inputs from config.yml)
            write_text_atomic(bc_dir / "config.yml", yaml.safe_dump(hp, sort_keys=True))
            write_text_atomic(bc_dir / "args.yml", yaml.safe_dump(
                dict(run, mode="bc", run_dir=str(bc_dir)), sort_keys=True))
            model = train_bc(hp, dict(run, no_tensorboard=True), bc_dir)
    policy = model.policy
    rng = np.random.default_rng(seed + 7919)
    inputs = policy_inputs(run["env"], env_kwargs, hp.get("obs_features"))
    ds_inputs = inputs(ds.observations)
    logger = _logger(run_dir, not run.get("no_tensorboard"))
    dt_s = float(ds.meta["dt_s"])
    sc_name = ds.meta["scenario"]
    history_file = run_dir / "dagger_history.yml"
    history = yaml.safe_load(history_file.read_text()) if history_file.exists() else []
    history = [h for h in history if h["iteration"] < start]
    for it in range(start, int(dg["n_iterations"])):
        t_it = time.perf_counter()
        lb_file = lbdir / f"iter_{it:03d}.npz"
        if lb_file.exists():  # labels of an interrupted iteration: reuse, do not re-solve
            with np.load(lb_file) as z:
                lab = {k: z[k] for k in z.files}
            roll = {k: float(lab.pop(k)) for k in list(lab) if k.startswith("rollout_")}
            print(f"DAgger iteration {it}: reusing {len(lab['obs'])} labels from {lb_file}")
        else:
            ep_seed = seed + int(dg.get("seed_offset", 100000)) + it * int(dg["n_episodes"])
            t0 = time.perf_counter()
            from agents.dataset import _is_pinpoint
            from lunar_env import get_scenario

            if _is_pinpoint(get_scenario(sc_name)):
                # the policy flies (mixed with the expert, β) and the feedback expert labels
                # every visited state, in worker processes that load this iteration's policy
                pol_file = lbdir / f"iter_{it:03d}_policy.zip"
                if not pol_file.exists():
                    save_model_atomic(model, pol_file)
                lab, roll = pinpoint_dagger_rollouts(
                    pol_file, run["env"], env_kwargs, int(dg["n_episodes"]), ep_seed,
                    hp.get("obs_features"), float(dg.get("beta", 0.5)),
                    int(dg.get("n_label_workers", 1)), cache_dir=lbdir / f"iter_{it:03d}_parts",
                    progress=not run.get("no_progress"))
                roll["rollout_wall_s"] = time.perf_counter() - t0
                t0 = time.perf_counter()
            else:
                eps = rollout_policy(model, run["env"], env_kwargs, int(dg["n_episodes"]),
                                     ep_seed, hp.get("obs_features"))
                roll = {"rollout_success_rate": float(np.mean([e["success"] for e in eps])),
                        "rollout_fuel_mean_kg": float(np.mean([e["fuel_kg"] for e in eps])),
                        "rollout_wall_s": time.perf_counter() - t0}
                t0 = time.perf_counter()
                lab = label_episodes(eps, sc_name, dt_s, int(dg["label_every"]),
                                     float(dg["dense_tail_s"]), int(dg.get("n_label_workers", 1)),
                                     progress=not run.get("no_progress"),
                                     min_speed_m_s=float(dg.get("min_label_speed_m_s", 3.0)),
                                     velocity_ref_m_s=get_scenario(sc_name).scaling().velocity_m_s,
                                     cache_dir=lbdir / f"iter_{it:03d}_parts",
                                     tail_label_every=int(dg.get("tail_label_every", 1)))
            roll["label_wall_s"] = time.perf_counter() - t0
            tmp = lb_file.with_suffix(".tmp.npz")
            np.savez_compressed(tmp, **lab, **{k: np.array(v) for k, v in roll.items()})
            os.replace(tmp, lb_file)
        print(f"DAgger iteration {it}: policy roll-outs success "
              f"{100 * roll['rollout_success_rate']:.1f} %, mean fuel "
              f"{roll['rollout_fuel_mean_kg']:.2f} kg; {len(lab['obs'])} expert labels",
              flush=True)
        agg_obs, agg_act = [], []
        for j in range(it + 1):
            with np.load(lbdir / f"iter_{j:03d}.npz") as z:
                keep = np.ones(len(z["obs"]), dtype=bool)
                if dg.get("drop_fallback_labels", True):
                    # decision: a "fallback" label is the expert's braking guess where it found
                    # no landing at all, not an optimal action; measured, it contradicts the
                    # optimal labels next to it (35-43° RMS apart) and only adds noise
                    keep = z["status"] != "fallback"
                agg_obs.append(z["obs"][keep])
                agg_act.append(z["actions"][keep])
        eo, ea = inputs(np.concatenate(agg_obs)), np.concatenate(agg_act)
        fraction = dg.get("dagger_fraction")
        if fraction is None:
            # pooled (Ross et al. 2011's aggregate): one epoch is one pass over the dataset and
            # every label so far, drawn alike
            main_obs, main_act = np.concatenate([ds_inputs, eo]), np.concatenate([ds.actions, ea])
            eo = ea = None
            fraction = 0.0
        else:
            main_obs, main_act = ds_inputs, ds.actions
        stats = fit_policy(policy, main_obs, main_act, n_epochs=int(dg["n_epochs"]),
                           batch_size=int(dg["batch_size"]),
                           learning_rate=float(dg["learning_rate"]),
                           learning_rate_final=float(dg.get("learning_rate_final",
                                                            dg["learning_rate"])),
                           rng=rng, extra_obs=eo, extra_act=ea,
                           extra_fraction=float(fraction),
                           val_obs=inputs(agg_obs[-1]), val_act=agg_act[-1],
                           logger=logger, progress=not run.get("no_progress"),
                           log_prefix=f"dagger_iter{it}",
                           step_offset=it * int(dg["n_epochs"]))
        for k, v in roll.items():
            logger.record(f"dagger/{k}", v)
        n_total = sum(len(o) for o in agg_obs)
        logger.record("dagger/n_labels_total", n_total)
        logger.dump(it)
        status, counts = np.unique(lab["status"], return_counts=True)
        history.append({"iteration": it, **roll, "n_labels": int(len(lab["obs"])),
                        "n_labels_total": int(n_total),
                        "expert_status": {str(s): int(c) for s, c in zip(status, counts,
                                                                          strict=True)},
                        "train_loss": float(stats["train_loss"]),
                        "wall_s": time.perf_counter() - t_it})
        save_model_atomic(model, ckdir / f"dagger_iter_{it}.zip")
        write_text_atomic(history_file, yaml.safe_dump(history))
    logger.close()
    n_select = int(dg.get("select_states") or 0)
    if n_select > 0:
        model = select_iteration(run_dir, run["env"], env_kwargs, hp.get("obs_features"),
                                 n_select, int(dg.get("select_seed", 50000)), run["device"])
    path = _save_final(model, run_dir)
    print(f"DAgger done ({dg['n_iterations']} iterations). Model: {path}")
    return model


def select_iteration(run_dir: Path, env_id: str, env_kwargs: dict[str, Any] | None,
                     obs_features: list[str] | None, n_states: int, seed: int,
                     device: str = "cpu"):
    """The DAgger iteration whose policy lands most often on held-out validation states.

    Ross et al. (2011) guarantee the *best* of the iterates, not the last: the policy of one
    iteration to the next may trade a few cases (measured on the pinpoint env: 99.5 % after
    iteration 6, 99.0 % after 7, on the evaluation's 200 states). Each checkpoint flies cases
    ``seed .. seed + n_states - 1`` (default seed 50000: disjoint from the dataset's, the
    roll-outs' and the evaluation's cases; :mod:`agents.selection`); ties go to the later
    iteration. The scores are written to ``selection.yml``; returns the chosen model.
    """
    from stable_baselines3 import PPO

    from agents.selection import best_of, score_candidates, write_selection

    ckdir = run_dir / "checkpoints"
    done = sorted((int(m.group(1)), f) for f in ckdir.iterdir() if (m := _DG_CKPT.match(f.name)))
    if not done:
        raise FileNotFoundError(f"no DAgger checkpoint in {ckdir}")
    scores = score_candidates(done, env_id, env_kwargs,
                              obs_features, n_states, seed, device, label="DAgger iteration")
    best = best_of(scores)
    write_selection(run_dir, seed, n_states, "iteration", scores, best)
    print(f"DAgger selection: iteration {best['key']} ({100 * best['success_rate']:.1f} %)")
    return PPO.load(dict(done)[best["key"]], device=device)


# ----------------------------------------------------------------------------- CLI


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m agents.imitation",
                                description="Behaviour cloning and DAgger from optimal landings.")
    sub = p.add_subparsers(dest="mode", required=True)
    for mode in ("bc", "dagger"):
        s = sub.add_parser(mode, help=f"train by {mode.upper()}")
        s.add_argument("--env", default=DEFAULT_ENV_ID)
        s.add_argument("--dataset", default=None, help="dataset .npz (python -m agents.dataset)")
        s.add_argument("--hyperparams-file", default=str(_HP_FILE))
        s.add_argument("--config", default="default", help="profile: default or e.g. quick")
        s.add_argument("--quick", action="store_true", help="same as --config quick")
        s.add_argument("--hyperparams", "-params", nargs="+", default=[], metavar="KEY=VALUE")
        s.add_argument("--seed", type=int, default=None)
        s.add_argument("--log-folder", "-f", default="runs")
        s.add_argument("--run-dir", default=None)
        s.add_argument("--resume", default=None, metavar="RUN_DIR")
        s.add_argument("--device", default="cpu")
        s.add_argument("--torch-threads", type=int, default=1)
        s.add_argument("--no-progress", action="store_true")
        s.add_argument("--no-tensorboard", action="store_true")
        s.add_argument("--eval-states", type=int, default=0,
                       help="evaluate the final policy on this many dispersed states "
                            "(agents.evaluate; 0: skip)")
        s.add_argument("--eval-seed", type=int, default=2026)
        if mode == "dagger":
            s.add_argument("--init", default=None,
                           help="initial policy (BC run dir or PPO zip); default: BC first")
    e = sub.add_parser("evaluate", help="compare policies with agents.evaluate")
    e.add_argument("--env", default=DEFAULT_ENV_ID)
    e.add_argument("--model", action="append", default=[], metavar="NAME=PATH",
                   help="policy name and run dir / zip (repeatable)")
    e.add_argument("--n-states", type=int, default=1000)
    e.add_argument("--seed", type=int, default=2026)
    e.add_argument("--expert-states", type=int, default=20)
    e.add_argument("--feedback-states", type=int, default=None,
                   help="cases flown by the Pontryagin feedback expert (default: all)")
    e.add_argument("--no-open-loop", action="store_true")
    e.add_argument("--out", default="results/imitation")
    e.add_argument("--json", default=None)
    return p


def _resolve(args) -> tuple[dict[str, Any], dict[str, Any]]:
    from agents.hyperparams import apply_overrides, load_hyperparams, parse_override

    profile = "quick" if args.quick else args.config
    hp = load_hyperparams(args.hyperparams_file, args.env, profile)
    hp = apply_overrides(hp, dict(parse_override(t) for t in args.hyperparams))
    for key in ("policy_kwargs", "bc") + (("dagger",) if args.mode == "dagger" else ()):
        if key not in hp:
            raise ValueError(f"{args.hyperparams_file}: entry {args.env!r} lacks {key!r}")
    run = {k: v for k, v in vars(args).items()}
    run["config"] = profile
    run["algo"] = "ppo"  # the saved model is a PPO zip (agents.evaluate / train.py read this)
    if run["seed"] is None:
        run["seed"] = int(np.random.default_rng().integers(0, 2**31 - 1))
    return hp, run


def _run_env_kwargs(path: str | Path, env_id: str) -> dict[str, Any]:
    """The run's ``env_kwargs`` without entries equal to the env's defaults (so that runs with
    ``{}`` and ``{dt_s: 1.0}`` share one env configuration)."""
    import gymnasium as gym

    import lunar_env  # noqa: F401
    from agents.runs import read_run

    kw = dict(read_run(path)[1].get("env_kwargs") or {})
    env = gym.make(env_id, **kw)
    defaults = env.unwrapped.task_defaults()
    env.close()
    return {k: v for k, v in kw.items() if not (k in defaults and defaults[k] == v)}


def _evaluate_cli(args) -> int:
    """Compare named policies with :func:`agents.evaluate.compare`.

    Policies trained with different env settings (e.g. PPO's 5 s decisions, imitation's 1 s)
    each fly their own env configuration from the same seeded initial states (the dispersion
    draw does not depend on the step length); one :func:`compare` call per configuration, rows
    merged into one table. The optimiser baselines (open-loop replay, re-planning expert) run
    with the first configuration; the open-loop replay also with every other one.
    """
    from agents.evaluate import SB3Policy, compare, publish_report

    groups: dict[str, tuple[dict[str, Any], list]] = {}
    for item in args.model:
        if "=" not in item:
            raise SystemExit(f"--model {item!r}: expected NAME=PATH")
        name, path = item.split("=", 1)
        kw = _run_env_kwargs(path, args.env)
        key = json.dumps(kw, sort_keys=True)
        groups.setdefault(key, (kw, []))[1].append(SB3Policy.from_path(path, name=name))
    if not groups:
        groups["{}"] = ({}, [])
    reports = []
    for g, (kw, pols) in enumerate(groups.values()):
        rep = compare(args.env, pols, n_states=args.n_states, seed=args.seed, env_kwargs=kw,
                      open_loop=not args.no_open_loop,
                      n_expert_states=args.expert_states if g == 0 else 0,
                      n_feedback_states=args.feedback_states if g == 0 else 0)
        if len(groups) > 1:
            tag = ", ".join(f"{k}={v}" for k, v in sorted(kw.items())) or "env defaults"
            for row, res in zip(rep["rows"], rep["results"], strict=True):
                row["policy"] = f"{row['policy']} [{tag}]"
                res.name = row["policy"]
        reports.append(rep)
    report = dict(reports[0])
    report["rows"] = [r for rep in reports for r in rep["rows"]]
    report["results"] = [r for rep in reports for r in rep["results"]]
    report["env_kwargs_groups"] = [kw for kw, _ in groups.values()]
    publish_report(report, args.out, args.json)
    return 0


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point (``python -m agents.imitation``)."""
    import torch as th

    parser = build_parser()
    args = parser.parse_args(argv)
    if args.mode == "evaluate":
        return _evaluate_cli(args)
    th.set_num_threads(max(int(args.torch_threads), 1))
    argv_list = list(sys.argv[1:] if argv is None else argv)
    if args.resume:
        run_dir = Path(args.resume)
        if not (run_dir / "args.yml").exists():
            parser.error(f"--resume {run_dir}: not a run directory (args.yml missing)")
        run = yaml.safe_load((run_dir / "args.yml").read_text())
        hp = yaml.safe_load((run_dir / "config.yml").read_text())
        if run["mode"] != args.mode:
            parser.error(f"--resume {run_dir}: it is a {run['mode']} run, not {args.mode}")
        run["no_progress"] = args.no_progress
        cmd_file = run_dir / "command.txt"
        write_text_atomic(cmd_file, (cmd_file.read_text() if cmd_file.exists() else "")
                          + shlex.join([sys.executable, "-m", "agents.imitation", *argv_list])
                          + "\n")
        resume = True
    else:
        if args.dataset is None:
            parser.error("--dataset is required (make one with python -m agents.dataset)")
        hp, run = _resolve(args)
        from agents.runs import claim_run_dir

        try:  # both created atomically: concurrent runs never share a directory
            run_dir = (claim_run_dir(args.run_dir) if args.run_dir
                       else _new_run_dir(args.log_folder, args.mode, args.env))
        except FileExistsError as exc:
            parser.error(str(exc))
        run["run_dir"] = str(run_dir)
        from agents.dataset import load_dataset

        hp["env_kwargs"] = load_dataset(args.dataset).meta.get("env_kwargs") or {}
        write_text_atomic(run_dir / "config.yml", yaml.safe_dump(hp, sort_keys=True))
        write_text_atomic(run_dir / "args.yml", yaml.safe_dump(run, sort_keys=True))
        write_text_atomic(run_dir / "command.txt",
                          shlex.join([sys.executable, "-m", "agents.imitation", *argv_list])
                          + "\n")
        resume = False
    print(f"Run directory: {run_dir}  (mode={run['mode']}, env={run['env']}, "
          f"config={run['config']}, seed={run['seed']})")
    if run["mode"] == "bc":
        train_bc(hp, run, run_dir, resume=resume)
    else:
        train_dagger(hp, run, run_dir, resume=resume)
    n_eval = int(run.get("eval_states") or 0)
    if n_eval > 0:
        from agents.evaluate import evaluate_run

        evaluate_run(run_dir, n_states=n_eval, seed=int(run.get("eval_seed", 2026)))
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    # run the imported module's main: the DAgger roll-out tasks must be importable as
    # agents.imitation._pinpoint_dagger_chunk by spawned workers, not as __main__'s
    from agents.imitation import main as _main

    raise SystemExit(_main())
