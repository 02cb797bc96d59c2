"""The on-disk cache of per-case optima: one ``.npz`` file per start state, named by a hash of
the solver settings, the scenario and the state, written atomically by the process that
solved it (so workers on several machines need a shared filesystem)."""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..common.checkpoint import save_npz_atomic

__all__ = ["cache_root", "cache_key", "load_optimum", "store_optimum", "cached_optima"]


def cache_root(name: str) -> Path:
    """``$LUNAR_CACHE_DIR/<name>`` (default ``~/.cache/lunar-descent-guidance/<name>``)."""
    root = os.environ.get("LUNAR_CACHE_DIR") or Path.home() / ".cache" / "lunar-descent-guidance"
    return Path(root) / name


def cache_key(settings: dict[str, Any], scenario, x0_nd: np.ndarray) -> str:
    """40 hex digits of the SHA-256 of the solver ``settings`` (JSON), ``repr(scenario)`` and
    the start state's float64 bytes."""
    h = hashlib.sha256()
    h.update(json.dumps(settings, sort_keys=True).encode())
    h.update(repr(scenario).encode())
    h.update(np.ascontiguousarray(x0_nd, dtype=np.float64).tobytes())
    return h.hexdigest()[:40]


def load_optimum(path: Path, cls):
    """``cls.from_arrays`` of the file, or None where it is unreadable or foreign (the case is
    then solved again and the file overwritten)."""
    try:
        with np.load(path, allow_pickle=False) as d:
            return cls.from_arrays(d)
    except (OSError, KeyError, ValueError):
        return None


def store_optimum(path: Path, opt) -> None:
    """Write ``opt.to_arrays()`` to ``path`` atomically
    (:func:`~optimizers.common.checkpoint.save_npz_atomic`)."""
    save_npz_atomic(path, opt.to_arrays())


def cached_optima(states: np.ndarray, paths: list[Path | None], cls,
                  solve_many: Callable[..., list], **solve_kwargs) -> list:
    """The optima of the rows of ``states``, in input order: read from ``paths[i]`` where it
    holds a readable file, else solved by ``solve_many(states[todo], store=..., store_keys=...,
    **solve_kwargs)``, which stores each (``paths[i]`` None: solved and not stored; all None:
    nothing stored)."""
    results: list = [None] * len(states)
    for i, p in enumerate(paths):
        if p is not None and p.exists():
            results[i] = load_optimum(p, cls)
    todo = [i for i, r in enumerate(results) if r is None]
    if todo:
        use_cache = any(p is not None for p in paths)
        solved = solve_many(states[todo], store=store_optimum if use_cache else None,
                            store_keys=[paths[i] for i in todo] if use_cache else None,
                            **solve_kwargs)
        for i, opt in zip(todo, solved, strict=True):
            results[i] = opt
    return results
