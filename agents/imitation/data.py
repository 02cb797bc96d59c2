"""The imitation dataset format: :class:`ImitationDataset`, versioned ``.npz`` I/O.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from optimizers.common.checkpoint import save_npz_atomic

__all__ = ["FORMAT_VERSION", "ImitationDataset", "load_dataset", "save_dataset",
           "PER_TRAJECTORY_KEYS", "OPTIONAL_PER_TRAJECTORY_KEYS", "PER_SAMPLE_KEYS"]

FORMAT_VERSION = 1
PER_TRAJECTORY_KEYS = ("initial_state_si", "solver_success", "fuel_kg", "tf_s",
                       "terminal_error_radius_m",
             "terminal_error_speed_m_s", "replay_fuel_kg", "replay_touchdown_speed_m_s",
             "replay_success", "replay_fuel_gap_kg", "certified", "solve_wall_s")
#: pinpoint datasets: episode time of each trajectory's first state (0 for a dispersed start)
#: and, for a perturbed mid-flight restart, the row of the trajectory it branched from (else -1)
OPTIONAL_PER_TRAJECTORY_KEYS = ("start_time_s", "parent_index")
PER_SAMPLE_KEYS = ("observations", "actions", "traj_index", "t_s", "state_nd", "phi_rad")


@dataclass
class ImitationDataset:
    """A loaded dataset (see the module docstring for every field).

    Attributes
    ----------
    meta : dict
    arrays : dict of str -> ndarray
        Per-sample and per-trajectory arrays.
    """

    meta: dict[str, Any]
    arrays: dict[str, np.ndarray]

    @property
    def observations(self) -> np.ndarray:
        return self.arrays["observations"]

    @property
    def actions(self) -> np.ndarray:
        return self.arrays["actions"]

    @property
    def n_samples(self) -> int:
        return int(len(self.arrays["observations"]))

    @property
    def n_trajectories(self) -> int:
        return int(len(self.arrays["certified"]))

    def summary(self) -> dict[str, Any]:
        """Certification figures: counts, worst terminal errors, fuel gap of the replay."""
        a = self.arrays
        c = a["certified"].astype(bool)
        # the open-loop replay is made for the dispersed starts only (pinpoint restarts have
        # parent_index >= 0)
        base = a["parent_index"] < 0 if "parent_index" in a else np.ones(len(c), dtype=bool)
        extra = ({"n_restarts": int((~base).sum()), "n_restarts_certified": int(c[~base].sum())}
                 if (~base).any() else {})
        return {**extra,
            "n_trajectories": self.n_trajectories,
            "n_certified": int(c.sum()),
            "n_samples": self.n_samples,
            "max_terminal_error_radius_m": float(np.max(a["terminal_error_radius_m"][c]))
            if c.any() else float("nan"),
            "max_terminal_error_speed_m_s": float(np.max(a["terminal_error_speed_m_s"][c]))
            if c.any() else float("nan"),
            "mean_fuel_kg": float(np.mean(a["fuel_kg"][c])) if c.any() else float("nan"),
            "replay_success_rate": float(np.mean(a["replay_success"][base])),
            "replay_fuel_gap_kg_mean": float(np.mean(a["replay_fuel_gap_kg"][c & base]))
            if (c & base).any() else float("nan"),
            "replay_touchdown_speed_m_s_max": float(np.max(
                a["replay_touchdown_speed_m_s"][c & base])) if (c & base).any() else float("nan"),
            "wall_s": self.meta.get("wall_s"),
        }


# --------------------------------------------------------------------------------- I/O


def save_dataset(path: str | Path, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> Path:
    """Write a dataset file atomically
    (:func:`~optimizers.common.checkpoint.save_npz_atomic`, compressed)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = dict(meta, format_version=FORMAT_VERSION)
    return save_npz_atomic(path, {"meta": np.array(json.dumps(meta)), **arrays},
                           compressed=True)


def load_dataset(path: str | Path) -> ImitationDataset:
    """Read a dataset file written by :func:`generate` / :func:`save_dataset` (a Minari
    dataset ``minari:<dataset id>`` is read by :func:`agents.imitation.sources.open_dataset`).

    Raises
    ------
    ValueError
        The file has no ``meta``, a different ``format_version`` than :data:`FORMAT_VERSION`,
        or lacks a required array.
    """
    if not Path(path).is_file():
        raise FileNotFoundError(f"dataset file {path} does not exist; make one with python -m "
                                "lunar dataset (or give minari:<dataset id>)")
    try:
        z = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise ValueError(f"dataset file {path} is damaged or not an .npz "
                         f"({type(exc).__name__}: {exc}); regenerate it with python -m "
                         "lunar dataset (finished shards are kept)") from None
    with z:
        if "meta" not in z.files:
            raise ValueError(f"{path} is not an imitation dataset (no 'meta' entry); create one "
                             "with lunar dataset")
        meta = json.loads(str(z["meta"]))
        ver = meta.get("format_version")
        if ver != FORMAT_VERSION:
            raise ValueError(f"{path} has dataset format_version {ver!r}; this code reads "
                             f"version {FORMAT_VERSION}: regenerate it with python -m "
                             "lunar dataset")
        try:
            arrays = {k: z[k] for k in z.files if k != "meta"}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise ValueError(f"dataset file {path} is damaged ({type(exc).__name__}: {exc})"
                             ) from None
    missing = [k for k in (*PER_SAMPLE_KEYS, *PER_TRAJECTORY_KEYS) if k not in arrays]
    if missing:
        raise ValueError(f"{path} lacks arrays {missing}")
    return ImitationDataset(meta, arrays)
