"""Behaviour cloning ([Pomerleau 1991]) into an SB3 PPO policy: :func:`train_bc` and its run
directory.
"""

from __future__ import annotations

import os
import re
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.common.actor import actor_parameters
from agents.common.runs import write_text_atomic
from agents.imitation.policy import (
    _split_by_trajectory,
    build_model,
    fit_policy,
    imitation_history,
    policy_inputs,
)

_BC_CKPT = re.compile(r"^bc_epoch_(\d+)\.pt$")


# ----------------------------------------------------------------------------- run dirs


def _new_run_dir(log_folder: str, mode: str, env_id: str) -> Path:
    from agents.common.runs import next_run_dir

    return next_run_dir(Path(log_folder) / "imitation", f"{mode}_{env_id}")


def _logger(run_dir: Path, tensorboard: bool):
    from stable_baselines3.common.logger import configure

    fmts = ["csv"] + (["tensorboard"] if tensorboard else [])
    return configure(str(run_dir / "tb"), fmts)


def _save_final(model, run_dir: Path) -> Path:
    from agents.common.runs import save_model_atomic

    return save_model_atomic(model, run_dir / "model.zip")


def _rng_state(rng: np.random.Generator) -> dict:
    return rng.bit_generator.state


# ----------------------------------------------------------------------------- BC


def train_bc(hp: dict[str, Any], run: dict[str, Any], run_dir: Path, resume: bool = False):
    """Behaviour cloning on ``run["dataset"]``; writes checkpoints and ``model.zip``.

    Returns the PPO model whose policy holds the cloned weights.
    """
    import torch as th

    from agents.imitation.sources import load_run_dataset

    imitation_history(hp, "bc")  # refused: a dataset holds no histories
    ds, env_kwargs = load_run_dataset(run, hp.get("env_kwargs"))
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
        from agents.common.runs import newest_loadable

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
