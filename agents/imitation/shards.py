"""The shard files of a dataset being generated (:func:`agents.imitation.dataset.generate`):
``<out>.shards/shard_<k>.npz``, each written atomically, read back on resume and merged.
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import numpy as np

from agents.imitation.data import PER_SAMPLE_KEYS, PER_TRAJECTORY_KEYS

__all__ = ["shard_path", "read_shard", "shard_done", "write_shard"]


def shard_path(shard_dir: Path, k: int) -> Path:
    """The file of shard ``k``."""
    return Path(shard_dir) / f"shard_{int(k):05d}.npz"


def read_shard(path: Path) -> dict[str, np.ndarray]:
    """Every array of a shard file; ValueError naming the shard if it is damaged."""
    try:
        with np.load(path, allow_pickle=False) as z:
            out = {f: z[f] for f in z.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise ValueError(f"dataset shard {path} is damaged ({type(exc).__name__}: {exc})"
                         ) from None
    missing = [k for k in (*PER_TRAJECTORY_KEYS, *PER_SAMPLE_KEYS) if k not in out]
    if missing:
        raise ValueError(f"dataset shard {path} is damaged (lacks {missing})")
    return out


def shard_done(path: Path) -> bool:
    """True if the shard exists and reads; a damaged one is moved aside (``.damaged``) with a
    message naming it, and its rows are solved again."""
    if not path.exists():
        return False
    try:
        read_shard(path)
        return True
    except ValueError as exc:
        os.replace(path, path.with_name(path.name + ".damaged"))
        print(f"{exc}: moved to {path.name}.damaged; its rows are solved again")
        return False


def write_shard(path: Path, arrays: dict[str, np.ndarray], wall_s: float) -> None:
    """Write one shard atomically (temporary file, then ``os.replace``); ``wall_s`` (s) is its
    computing time."""
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.npz")
    np.savez_compressed(tmp, wall_s=np.array(float(wall_s)), **arrays)
    os.replace(tmp, path)
