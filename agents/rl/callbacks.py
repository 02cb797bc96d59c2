"""The SB3 callbacks of :func:`agents.rl.training.train`, one module-level class each.

Modelled on SB3's ``common/callbacks.py`` and the Zoo's ``callbacks.py``: every callback is
configured through its constructor only, and what the training loop needs back from one is a
public attribute or method (:attr:`RolloutCheckpointCallback.last_saved_steps`,
:meth:`RolloutCheckpointCallback.save_now`). Wrappers of the training env are found by type
(:func:`find_wrapper`), not by class name.

- :class:`RolloutCheckpointCallback`: checkpoints between rollouts (resumable runs);
- :class:`EpisodeInfoCallback`: landing quantities to TensorBoard and a console summary;
- :class:`CriticWarmupCallback`: the actor held fixed while the value head learns.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import yaml
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback

from agents.common.actor import actor_parameters
from agents.common.runs import save_model_atomic, save_vecnormalize_atomic, write_text_atomic

__all__ = ["EPISODE_INFO_KEYS", "CriticWarmupCallback", "EpisodeInfoCallback",
           "RolloutCheckpointCallback", "error_curriculum_of", "error_scale_state_path",
           "find_wrapper"]

#: info keys averaged over finished episodes and written to TensorBoard under ``episode/``
EPISODE_INFO_KEYS = ("fuel_used_kg", "touchdown_speed_m_s", "miss_distance_m")

W = TypeVar("W")


def find_wrapper(venv, wrapper_type: type[W]) -> W | None:
    """The outermost wrapper of type ``wrapper_type`` (an ``isinstance`` test) in the
    ``VecEnvWrapper`` chain of ``venv`` (``venv`` itself included), or None."""
    from stable_baselines3.common.vec_env.base_vec_env import VecEnvWrapper

    node = venv
    while node is not None:
        if isinstance(node, wrapper_type):
            return node
        node = node.venv if isinstance(node, VecEnvWrapper) else None
    return None


def error_curriculum_of(venv):
    """The :class:`agents.rl.curriculum.ErrorScaleCurriculum` in ``venv``'s chain, or None."""
    from agents.rl.curriculum import ErrorScaleCurriculum

    return find_wrapper(venv, ErrorScaleCurriculum)


def error_scale_state_path(checkpoint: str | Path) -> Path:
    """Where :class:`RolloutCheckpointCallback` saves the error curriculum's state next to the
    checkpoint ``.../rl_model_<steps>_steps.zip``."""
    checkpoint = Path(checkpoint)
    steps = checkpoint.stem.removeprefix("rl_model_")
    return checkpoint.with_name(f"rl_model_error_scale_{steps}.yml")


class RolloutCheckpointCallback(CheckpointCallback):
    """``CheckpointCallback`` that saves between rollouts, every ``save_freq`` env steps.

    The save happens at the *start* of the next rollout, i.e. after the algorithm trained on the
    previous one (SB3 calls ``on_rollout_end`` *before* ``train()``: a checkpoint taken there
    counted a rollout the model had not learnt from, and a resumed run never trained on it). A
    resumed run therefore restarts from a state
    where every counted step has been trained on exactly once. The ``VecNormalize`` statistics,
    the replay buffer (off-policy) and ``config`` (as ``checkpoints/config.yml``, once) are saved
    alongside, and the success-driven error scale (:class:`agents.rl.curriculum.
    ErrorScaleCurriculum`, as ``rl_model_error_scale_<steps>_steps.yml``) when there is one; the
    model file is written last, so a model file implies a complete checkpoint.

    Parameters
    ----------
    run_dir : path
        The run directory; checkpoints go to ``run_dir/checkpoints/rl_model_<steps>_steps.zip``.
    save_freq : int
        Env steps (all envs together, not calls) between checkpoints; values below 1 mean 1.
    config : dict
        The run's hyperparameters, written next to the checkpoints.
    on_save : callable, optional
        Called without arguments after every checkpoint (timing bookkeeping).

    Attributes
    ----------
    last_saved_steps : int or None
        ``num_timesteps`` of the newest checkpoint this callback knows of (set to the model's
        step count when training starts, since that state is on disk); None before training.
    """

    def __init__(self, run_dir: str | Path, save_freq: int, config: dict[str, Any],
                 on_save: Callable[[], Any] | None = None) -> None:
        super().__init__(save_freq=1, save_path=str(Path(run_dir) / "checkpoints"),
                         name_prefix="rl_model", save_replay_buffer=True,
                         save_vecnormalize=True, verbose=0)
        self.save_every_steps = max(int(save_freq), 1)
        self.config = dict(config)
        self.on_save = on_save
        self.last_saved_steps: int | None = None
        self._last_trained = 0

    def _on_training_start(self) -> None:
        self.last_saved_steps = self.model.num_timesteps
        self._last_trained = self.model.num_timesteps

    def _on_step(self) -> bool:
        return True

    def _on_rollout_start(self) -> None:
        # the previous rollout (if any) has been collected *and* trained on
        self._last_trained = self.model.num_timesteps
        if self.model.num_timesteps - self.last_saved_steps >= self.save_every_steps:
            self.save_now()

    def save_now(self, interrupted: bool = False) -> Path:
        """Write the checkpoint for the current ``num_timesteps`` and return its path.

        ``interrupted``: called in the middle of a rollout (or of its training). An on-policy
        algorithm has not trained on the partial rollout, so its step counter is rolled back to
        the last trained rollout: the resumed run collects those steps again and ends after
        exactly as many trained steps as an uninterrupted run.
        """
        from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm

        if interrupted and isinstance(self.model, OnPolicyAlgorithm):
            self.model.num_timesteps = self._last_trained
        self.num_timesteps = self.model.num_timesteps  # the parent names files after this
        path = Path(self._checkpoint_path(extension="zip"))
        path.parent.mkdir(parents=True, exist_ok=True)
        vn = self.model.get_vec_normalize_env()
        if vn is not None:
            save_vecnormalize_atomic(vn, self._checkpoint_path("vecnormalize_", "pkl"))
        errors = error_curriculum_of(self.training_env)
        if errors is not None and errors.success_threshold is not None:
            # the success-driven error scale cannot be recomputed from the step count
            write_text_atomic(self._checkpoint_path("error_scale_", "yml"),
                              yaml.safe_dump(errors.state_dict()))
        if getattr(self.model, "replay_buffer", None) is not None:
            rb = Path(self._checkpoint_path("replay_buffer_", "pkl"))
            tmp = rb.with_name(f".{rb.name}.tmp.pkl")
            self.model.save_replay_buffer(tmp)
            os.replace(tmp, rb)
        save_model_atomic(self.model, path)
        cfg = path.parent / "config.yml"
        if not cfg.exists():
            write_text_atomic(cfg, yaml.safe_dump(self.config, sort_keys=True))
        self.last_saved_steps = self.model.num_timesteps
        if self.on_save is not None:
            self.on_save()
        return path


class EpisodeInfoCallback(BaseCallback):
    """Log the mean SI landing quantities of finished episodes (``episode/*``) and print, every
    ``summary_every`` env steps, one summary line of the episodes finished since the previous
    line (success rate, touchdown speed, miss distance, fuel; with a curriculum also the success
    of the episodes that started from the dispersion, the evaluation's distribution, and the
    curriculum's state).

    Parameters
    ----------
    total_timesteps : int
        The run's length (shown as ``step k/total``).
    summary_every : int
        Env steps between console lines; 0 prints none.
    """

    def __init__(self, total_timesteps: int, summary_every: int = 0) -> None:
        super().__init__()
        if summary_every < 0:
            raise ValueError(f"summary_every={summary_every!r} must be >= 0")
        self.total_timesteps = int(total_timesteps)
        self.summary_every = int(summary_every)
        self._acc: dict[str, list[float]] = {k: [] for k in EPISODE_INFO_KEYS}
        self._console: dict[str, list[float]] = {
            k: [] for k in (*EPISODE_INFO_KEYS, "is_success", "dispersed_success")}
        self._next_summary = 0
        self._t0 = time.perf_counter()

    def _curriculum(self):
        from agents.rl.curriculum import OptimalStartCurriculum

        return find_wrapper(self.training_env, OptimalStartCurriculum)

    def _on_training_start(self) -> None:
        self._t0 = time.perf_counter()
        if self.summary_every > 0:
            self._next_summary = self.model.num_timesteps + self.summary_every

    def summary_line(self) -> str | None:
        """The console line of the episodes finished since the previous one (and forget them),
        or None when none finished."""
        c = self._console
        n = len(c["is_success"])
        if n == 0:
            return None
        parts = [f"step {self.model.num_timesteps:,}/{self.total_timesteps:,}",
                 f"{n} episodes", f"success {100 * np.mean(c['is_success']):.1f} %"]
        labels = {"touchdown_speed_m_s": ("touchdown", "m/s", ".1f"),
                  "miss_distance_m": ("miss", "m", ".0f"),
                  "fuel_used_kg": ("fuel", "kg", ".1f")}
        for key, (label, unit, spec) in labels.items():
            if c[key]:
                parts.append(f"{label} {format(float(np.mean(c[key])), spec)} {unit}")
        cur = self._curriculum()
        if cur is not None:
            if c["dispersed_success"]:
                parts.append(f"from dispersion {100 * np.mean(c['dispersed_success']):.1f} %"
                             f" of {len(c['dispersed_success'])}")
            parts.append(f"curriculum p {cur.current_prob:.2f}")
        errors = error_curriculum_of(self.training_env)
        if errors is not None:
            parts.append(f"errors × {errors.current_scale:.2f}")
        parts.append(f"{time.perf_counter() - self._t0:.0f} s")
        for v in c.values():
            v.clear()
        return " | ".join(parts)

    def _on_step(self) -> bool:
        dones = self.locals.get("dones")
        infos = self.locals.get("infos")
        if dones is None or infos is None:
            return True
        for i in np.flatnonzero(dones):
            info = infos[i]
            for k in EPISODE_INFO_KEYS:
                v = info.get(k)
                if v is not None and np.isfinite(v):
                    self._acc[k].append(float(v))
                    self._console[k].append(float(v))
            self._console["is_success"].append(float(bool(info.get("is_success"))))
            f = info.get("start_fraction")
            if f is not None and not np.isfinite(f):
                self._console["dispersed_success"].append(float(bool(info.get("is_success"))))
        return True

    def _on_rollout_end(self) -> None:
        cur = self._curriculum()
        if cur is not None:
            self.logger.record("curriculum/start_prob", cur.current_prob)
        errors = error_curriculum_of(self.training_env)
        if errors is not None:
            self.logger.record("curriculum/error_scale", errors.current_scale)
        for k, vals in self._acc.items():
            if vals:
                self.logger.record(f"episode/{k}", float(np.mean(vals)))
                vals.clear()
        if self.summary_every > 0 and self.model.num_timesteps >= self._next_summary:
            self._next_summary = self.model.num_timesteps + self.summary_every
            line = self.summary_line()
            if line:
                print(line, flush=True)


class CriticWarmupCallback(BaseCallback):
    """Hold the actor fixed for the first ``warmup_steps`` env steps.

    Why: a policy cloned from an expert (``--init-from``) comes with an untrained value head;
    the first PPO updates would follow advantages computed from it and move a policy that
    already lands. With the actor's parameters (:func:`agents.common.actor.actor_parameters`)
    frozen (no gradient, so Adam leaves them alone) the PPO updates fit only the value function
    until ``warmup_steps``; at the end of training every parameter is trainable again.

    Raises
    ------
    ValueError
        ``warmup_steps`` < 0.
    """

    def __init__(self, warmup_steps: int) -> None:
        super().__init__()
        if warmup_steps < 0:
            raise ValueError(f"critic_warmup_steps={warmup_steps!r}: must be >= 0")
        self.warmup_steps = int(warmup_steps)

    def _set(self, trainable: bool) -> None:
        for p in actor_parameters(self.model.policy):
            p.requires_grad_(trainable)
            if not trainable:
                p.grad = None

    def _on_training_start(self) -> None:
        self._set(self.model.num_timesteps >= self.warmup_steps)

    def _on_rollout_end(self) -> None:  # called just before each PPO update
        self._set(self.model.num_timesteps >= self.warmup_steps)

    def _on_step(self) -> bool:
        return True

    def _on_training_end(self) -> None:
        self._set(True)
