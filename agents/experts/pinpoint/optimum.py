"""Per-case minimum-fuel optimum of ``LunarPinpointLanding-v*`` from the env's own initial states:
the on-disk cache and the laws that fly it.

The solving half (the serial GPM + direct shooting from each state, warm-started along a
nearest-neighbour chain, on workers or an executor) is
:mod:`optimizers.transcription.batch`; this module adds what agents need:

- **Cache** (:func:`pinpoint_optima`): every solved case is stored in ``<cache_dir>/<key>.npz``
  (written to a temporary file and renamed, so a killed run never leaves a torn file), ``key`` =
  SHA-256 of the scenario, the solver options, the cache format and the exact bytes of the
  initial state. A second evaluation of the same states costs a file read per case; only the
  missing cases are solved, and each is stored by the process that solved it.
- **Law**: :class:`PinpointOpenLoopLaw` replays each case's optimum
  (:class:`~optimizers.transcription.batch.PinpointOptimum`: node controls, piecewise linear in
  time, and the replayed node states).
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from agents.common.law import GuidanceLaw, Navigation
from lunar_env.envs.pinpoint_landing import action_from_angles
from optimizers.transcription.batch import (
    GATE_CLEARANCE,
    N_RANDOM_RETRIES,
    SOLVER_OPTIONS,
    PinpointOptimum,
    pinpoint_states,
    solve_many,
)

__all__ = ["pinpoint_optima", "default_cache_dir", "PinpointOpenLoopLaw", "CACHE_FORMAT"]

#: bumped whenever the stored content or the solver pipeline changes (invalidates the cache)
CACHE_FORMAT = 3


def default_cache_dir() -> Path:
    """``$LUNAR_CACHE_DIR/pinpoint_optimum`` (default ``~/.cache/lunar-descent-guidance``)."""
    root = os.environ.get("LUNAR_CACHE_DIR") or Path.home() / ".cache" / "lunar-descent-guidance"
    return Path(root) / "pinpoint_optimum"


def _cache_key(scenario, x0_nd: np.ndarray) -> str:
    h = hashlib.sha256()
    h.update(json.dumps({"format": CACHE_FORMAT, "options": SOLVER_OPTIONS,
                         "retries": N_RANDOM_RETRIES, "gate_floor": True,
                         "clearance": GATE_CLEARANCE},
                        sort_keys=True).encode())
    h.update(repr(scenario).encode())
    h.update(np.ascontiguousarray(x0_nd, dtype=np.float64).tobytes())
    return h.hexdigest()[:40]


def _load(path: Path) -> PinpointOptimum | None:
    try:
        with np.load(path, allow_pickle=False) as d:
            return PinpointOptimum.from_arrays(d)
    except (OSError, KeyError, ValueError):
        return None  # unreadable or foreign file: solve again (and overwrite it)


def _store(path: Path, opt: PinpointOptimum) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".tmp.npz", dir=path.parent)
    os.close(fd)
    try:
        np.savez(tmp, **opt.to_arrays())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def pinpoint_optima(scenario, states_nd, *, workers: int = 1,
                    cache_dir: str | Path | None = None, use_cache: bool = True,
                    progress: bool = True, executor=None) -> list[PinpointOptimum]:
    """Per-case optima of normalised initial states ``states_nd`` (n, 7), in input order, read
    from the cache where stored and solved (:func:`optimizers.transcription.batch.solve_many`)
    and stored otherwise.

    Parameters
    ----------
    scenario : PinpointScenario
    states_nd : array_like, shape (n, 7)
    workers : int
        Processes (1: this process). Chunks of the nearest-neighbour chain go to spawned workers.
    cache_dir : path, optional
        Default :func:`default_cache_dir`.
    use_cache : bool
        False: solve everything and write nothing.
    progress : bool
        tqdm bar over the cases still to solve.
    executor : optimizers.common.executor.Executor, optional
        Runs the chunks instead of ``workers`` local processes (e.g. a Ray cluster; the cache
        is written by the workers, so on several machines it must be on a shared filesystem).
        The caller keeps ownership.

    Raises
    ------
    ValueError
        ``states_nd`` is not of shape (n, 7), or ``workers < 1``.
    """
    states = pinpoint_states(states_nd)
    if int(workers) < 1:
        raise ValueError(f"workers = {workers!r} must be >= 1")
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    paths: list[Path | None] = [cache / f"{_cache_key(scenario, x)}.npz" if use_cache else None
                                for x in states]
    results: list[PinpointOptimum | None] = [None] * len(states)
    for i, p in enumerate(paths):
        if p is not None and p.exists():
            results[i] = _load(p)
    todo = [i for i, r in enumerate(results) if r is None]
    if todo:
        solved = solve_many(scenario, states[todo], n_workers=workers, executor=executor,
                            progress=progress, store=_store if use_cache else None,
                            store_keys=[paths[i] for i in todo] if use_cache else None)
        for i, opt in zip(todo, solved, strict=True):
            results[i] = opt
    return results  # type: ignore[return-value]


# ----------------------------------------------------------------------------- law


class PinpointOpenLoopLaw(GuidanceLaw):
    """Replay of each case's optimal (α, β)(t), averaged over every env step (held after tf).
    A law of the clock alone: it reads nothing of the navigation solution.

    Cases whose solve failed fly the nominal braking attitude (α = 0, β = 180°) and are
    reported like any other case.

    Parameters
    ----------
    optima : list of PinpointOptimum
        One per case (indexed by case id).
    t_offset_s : array_like, optional
        Per-case episode time at which each plan starts (mid-flight plans; default 0).
    """

    name = "optimum, open loop"

    def __init__(self, optima: list[PinpointOptimum], t_offset_s=None) -> None:
        self.optima = list(optima)
        self.t_offset_s = (np.zeros(len(self.optima)) if t_offset_s is None
                           else np.asarray(t_offset_s, dtype=np.float64).reshape(-1))
        self._ids = np.zeros(0, dtype=int)

    def reset(self, computer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self._ids = np.asarray(case_ids)

    def act(self, nav: Navigation) -> np.ndarray:
        sc = self.computer.scenario
        dt = self.computer.dt_s
        ang = np.tile([0.0, np.pi], (len(self._ids), 1))
        for k, cid in enumerate(self._ids):
            opt = self.optima[cid]
            if opt.success:
                ang[k] = opt.mean_angles(float(nav.t_s[k]) - self.t_offset_s[cid], dt)
        return self.computer.at_full_thrust(action_from_angles(
            ang[:, 0], ang[:, 1], sc.alpha_bounds_rad, sc.beta_bounds_rad))
