"""Helpers the families' dataset and DAgger work shares: the unwrapped env of an id, and the
concatenation of a shard's certified samples (:mod:`agents.imitation.families.planar`,
:mod:`agents.imitation.families.pinpoint`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["make_env", "collect_samples", "SAMPLE_KEYS"]

#: per-sample arrays of one trajectory's samples, in the order a shard concatenates them
SAMPLE_KEYS = ("observations", "actions", "t_s", "state_nd", "phi_rad")


def make_env(env_id: str, env_kwargs: dict[str, Any] | None):
    """The unwrapped env ``gym.make(env_id, **env_kwargs)`` (the caller closes it)."""
    import gymnasium as gym

    import lunar_env  # noqa: F401  (registers the ids)

    return gym.make(env_id, **(env_kwargs or {})).unwrapped


def collect_samples(out: dict[str, Any], samples: list, cert: np.ndarray, first: int,
                    n_obs: int, n_act: int, nx: int, n_angle: int) -> None:
    """Concatenate the certified trajectories' samples into ``out`` (in place).

    Parameters
    ----------
    out : dict
        Receives ``observations`` (M, n_obs) float32, ``actions`` (M, n_act) float32, ``t_s``
        (M,), ``state_nd`` (M, nx), ``phi_rad`` (M,) or (M, n_angle) float64 and
        ``traj_index`` (M,) int64 (empty arrays of these shapes if no trajectory is certified).
    samples : list
        Per trajectory: a dict of :data:`SAMPLE_KEYS` arrays, or None (no samples).
    cert : ndarray, shape (len(samples),), bool
        Which trajectories contribute.
    first : int
        Dataset index of ``samples[0]`` (``traj_index`` = first + position).
    """
    keep = [i for i in range(len(samples)) if cert[i]]
    shape = {"observations": (0, n_obs), "actions": (0, n_act), "state_nd": (0, nx),
             "phi_rad": (0, n_angle) if n_angle > 1 else (0,)}
    for key in SAMPLE_KEYS:
        if keep:
            out[key] = np.concatenate([samples[i][key] for i in keep])
        else:
            out[key] = np.zeros(shape.get(key, (0,)),
                                dtype=np.float32 if key in ("observations", "actions")
                                else np.float64)
    out["traj_index"] = (np.concatenate([np.full(len(samples[i]["t_s"]), first + i)
                                         for i in keep]).astype(np.int64)
                         if keep else np.zeros(0, dtype=np.int64))
