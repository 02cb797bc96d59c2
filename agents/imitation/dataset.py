"""Datasets of optimal landings for imitation learning: (observation, action) pairs in the env's
own spaces, each from a certified minimum-fuel trajectory.

::

    lunar dataset                                   # 1000 trajectories, zhu2007
    lunar dataset --n 20 --out data/imitation/small.npz --workers 1
    lunar dataset --n 1000 --workers 2 --out data/imitation/zhu2007_1000.npz  # resumes

What the trajectories are, how they are labelled and certified is the env family's
(:meth:`agents.imitation.families.ImitationFamily.dataset_recipe`; soft landing:
:mod:`agents.imitation.families.planar`, pinpoint: :mod:`agents.imitation.families.
pinpoint`); this module is the generic driver (shards, executor, resume, merge). Soft landing:

Pipeline
--------
1. Initial states: ``scenario.sample_initial(np.random.default_rng(seed), n)`` (SI rows), the
   scenario's dispersion, the same draw the env's reset makes (but a different seed from the
   evaluation set, so the evaluation states are held out).
2. Solver: :func:`optimizers.indirect.batch.solve_many` (indirect shooting, each solve warm-started
   from its nearest neighbour in the chain). Decision (measured, not assumed): it is the fastest
   certified solver available here — ~12–19 ms per state serial on a shared 2-core machine. A
   backward propagation of the state–costate system from the terminal set (CasADi, ``simpleRK``,
   batched chord/Broyden iterations on the terminal unknowns to hit the requested initial
   states) was prototyped and took ~20–30 ms per state for the same accuracy, so it was not
   kept.
3. Sampling: at every env decision time ``t_k = k·dt_s`` with ``t_k < tf`` the optimal state
   x*(t_k) (cubic Hermite on the solver's RK4 grid) becomes the observation
   ``env.observation_from_state(x*(t_k), t_k)`` and the label is
   ``action_from_thrust_angle(φ*(t_k + dt_s/2))``: the env holds an action over a step, and the
   mid-step value is the second-order accurate hold of a smooth control (the same rule as the
   open-loop replay of :mod:`agents.evaluate`).
4. Certification of every trajectory: (a) the solver's terminal errors (``check``: "grid" =
   shooting residual on the RK4 grid, "doubling" = RK4 step-doubling estimate, "reference" =
   DOP853 replay); (b) the dataset's own labels replayed open-loop in the env (native vector env,
   ``options={"state_si": ...}``) — touchdown speed, success flag and fuel used, so the fuel of
   what a perfect imitator would fly is compared with the per-case optimum
   (``replay_fuel_gap_kg``). ``certified`` = solver success, terminal speed and radius errors
   below ``tol_speed_m_s`` / ``tol_radius_m`` and the env replay a success.

Pinpoint (``--env LunarPinpointLanding-v*``): the samples come from the Pontryagin feedback
expert's own noisy closed-loop flights (:func:`agents.imitation.families.pinpoint.
pinpoint_expert_flights`; ``--noise``).

Parallel, progress, resume: the rows are split into shards of ``shard_size``; shards are tasks
of :mod:`optimizers.common.executor` (a local process pool of ``--workers``, or a Ray cluster
with ``--address`` / ``RAY_ADDRESS``), kept in an ``npz``
:class:`optimizers.common.executor.ResultStore` at ``<out>.shards/`` (``results/<key>.npz``,
one atomically written file per shard task key; ``identity.json``; ``timing.json``).
A re-run with the same arguments skips finished shards (an interrupted run loses at most the
shards in flight; a damaged shard is moved aside to ``.damaged`` and solved again); the
identity of the store must match or the run refuses to mix data.
The finished shards are merged into ``<out>``.

File format
-----------
``FORMAT_VERSION`` = 1, written by ``numpy.savez_compressed``:

- ``meta``: 0-d str, JSON: ``format_version``, ``env_id``, ``env_kwargs``, ``scenario``,
  ``seed``, ``n_trajectories``, ``dt_s``, ``label_rule``, ``solver`` (name, n_steps, check),
  ``certification`` (tolerances), ``observation_names``, ``wall_s`` (generation), ...
- per sample (M rows): ``observations`` (M, n_obs) float32; ``actions`` (M, n_act) float32
  (env action space); ``traj_index`` (M,) int64; ``t_s`` (M,) float64; ``state_nd`` (M, 5)
  float64 (normalised (r, vr, θ, ω, m)); ``phi_rad`` (M,) float64 (the label's thrust angle);
- per trajectory (N rows): ``initial_state_si`` (N, 5) (r m, vr m/s, θ rad, v_t m/s, m kg);
  ``solver_success`` (N,) bool; ``fuel_kg``, ``tf_s`` (N,) (optimum; NaN when the solve
  failed); ``terminal_error_radius_m``, ``terminal_error_speed_m_s`` (N,); ``replay_fuel_kg``,
  ``replay_touchdown_speed_m_s`` (N,), ``replay_success`` (N,) bool; ``replay_fuel_gap_kg``
  (N,); ``certified`` (N,) bool; ``solve_wall_s`` (N,).

Only certified trajectories contribute samples.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from agents.common.runs import write_text_atomic
from agents.imitation.data import (
    FORMAT_VERSION,
    OPTIONAL_PER_TRAJECTORY_KEYS,
    PER_SAMPLE_KEYS,
    PER_TRAJECTORY_KEYS,
    ImitationDataset,
    load_dataset,
    save_dataset,
)
from agents.imitation.families import IMITATION_FAMILIES
from agents.imitation.flights import make_env

__all__ = ["generate", "DEFAULT_ENV_ID", "DEFAULT_OUT"]

DEFAULT_ENV_ID = "LunarSoftLanding-v0"
DEFAULT_OUT = "data/imitation/LunarSoftLanding-v0_n1000_seed0.npz"


def _check_shard(arrays: dict) -> None:
    """A shard read back must hold every per-trajectory and per-sample array."""
    missing = [k for k in (*PER_TRAJECTORY_KEYS, *PER_SAMPLE_KEYS) if k not in arrays]
    if missing:
        raise ValueError(f"lacks {missing}")


def generate(out: str | Path = DEFAULT_OUT, *, env_id: str = DEFAULT_ENV_ID,
             env_kwargs: dict[str, Any] | None = None, n: int = 1000, seed: int = 0,
             n_workers: int = 2, shard_size: int = 50, n_steps: int = 400,
             check: str = "doubling", tol_radius_m: float | None = None,
             tol_speed_m_s: float | None = None,
             progress: bool = True, max_shards: int | None = None,
             executor=None, action_noise: float | None = None) -> ImitationDataset | None:
    """Generate (or resume) a dataset; returns it once every shard is done.

    Parameters
    ----------
    out : path
        Final ``.npz``; shards go to ``<out>.shards/``.
    env_id, env_kwargs :
        The env whose observation and action spaces the samples use.
    n : int
        Number of initial states drawn from the scenario's dispersion.
    seed : int
        Seed of ``np.random.default_rng`` for the initial states.
    n_workers : int
        Worker processes (spawned) over shards; 1 runs in this process.
    shard_size : int
        Trajectories per shard (the unit of resumption).
    n_steps, check :
        Soft landing: passed to :func:`optimizers.indirect.batch.solve_many`.
    tol_radius_m, tol_speed_m_s : float, optional
        Certification tolerances. Soft landing: on the solver's terminal errors (default
        1e-3 m, 1e-3 m/s). Pinpoint: on the gate miss and gate speed of the expert's own flight
        (default :data:`agents.imitation.families.pinpoint.PINPOINT_TOLERANCES`), on top of the
        env's success verdict. (The family's :meth:`~agents.imitation.families.ImitationFamily.
        dataset_recipe` sets the defaults.)
    max_shards : int, optional
        Stop after this many new shards (simulates an interruption; returns None).
    action_noise : float, optional
        Pinpoint only: standard deviation of the Gaussian noise on the expert's flown actions
        (default :data:`agents.imitation.families.pinpoint.PINPOINT_ACTION_NOISE`; 0 gives the
        optimal trajectories themselves).
    executor : optimizers.common.executor.Executor, optional
        Runs the shards (e.g. a Ray cluster: ``--address``); overrides ``n_workers``. The
        caller keeps ownership. Each shard is a task keyed (scenario, seed, shard index),
        written atomically as it finishes.

    Raises
    ------
    ValueError
        Bad counts, or existing shards made with other settings.
    """
    if int(n) < 1 or int(shard_size) < 1 or int(n_workers) < 1:
        raise ValueError(f"n = {n}, shard_size = {shard_size}, n_workers = {n_workers}: all "
                         "must be >= 1")
    if check not in ("grid", "doubling", "reference"):
        raise ValueError(f"check = {check!r}; use 'grid', 'doubling' or 'reference'")
    out = Path(out)
    env = make_env(env_id, env_kwargs)
    sc = env.scenario
    dt_s = float(env.dt_s)
    env.close()
    recipe = IMITATION_FAMILIES.of(sc).dataset_recipe(
        sc, int(n), int(seed), n_steps=int(n_steps), check=check, tol_radius_m=tol_radius_m,
        tol_speed_m_s=tol_speed_m_s, action_noise=action_noise)
    rows = recipe.rows
    tol_radius_m, tol_speed_m_s = recipe.tolerances
    meta = {
        "format_version": FORMAT_VERSION, "env_id": env_id, "env_kwargs": dict(env_kwargs or {}),
        "scenario": sc.name, "seed": int(seed), "n_trajectories": int(n),
        "shard_size": int(shard_size), "dt_s": dt_s, "label_rule": recipe.label_rule,
        "solver": recipe.solver, "certification": recipe.certification,
        "observation_names": recipe.observation_names, "initial_states": recipe.initial_states,
    }
    shard_dir = out.with_name(out.name + ".shards")
    key_meta = {k: meta[k] for k in ("format_version", "env_id", "env_kwargs", "scenario",
                                     "seed", "n_trajectories", "shard_size", "dt_s", "solver",
                                     "certification")}
    from optimizers.common.executor import LocalExecutor, ResultStore, Task, TaskKey, run_tasks

    # one file per shard, written atomically; other settings refused; damaged shards moved aside
    store = ResultStore(shard_dir, identity=key_meta, fmt="npz", validate=_check_shard)
    n_shards = (int(n) + int(shard_size) - 1) // int(shard_size)
    keys = [TaskKey(f"dataset-{sc.name}", int(seed), k) for k in range(n_shards)]
    tasks = []
    done_before = 0
    for k, key in enumerate(keys):
        lo, hi = k * int(shard_size), min((k + 1) * int(shard_size), int(n))
        if key in store:
            done_before += hi - lo
        job = {**recipe.job_args, "k": k, "rows": rows[lo:hi], "first_index": lo,
               "env_id": env_id, "env_kwargs": dict(env_kwargs or {}), "dt_s": dt_s,
               "tol_radius_m": tol_radius_m, "tol_speed_m_s": tol_speed_m_s, "seed": int(seed)}
        tasks.append(Task(key, recipe.shard_fn, (job,)))
    n_todo = n_shards - sum(1 for key in keys if store.path(key).exists())
    if max_shards is not None:
        n_todo = min(n_todo, int(max_shards))
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=int(n), initial=done_before, desc=f"optimal landings {sc.name}",
                   unit="traj")
    t0 = time.perf_counter()
    # One timing record per call (a resumed dataset appends one), rewritten (atomically) after
    # every shard, so a run killed part-way still accounts for the shards it finished.
    timing_file = shard_dir / "timing.json"
    timing = json.loads(timing_file.read_text()) if timing_file.exists() else []
    record = {"new_shards": 0, "wall_s": 0.0, "n_workers": int(n_workers)}
    timing.append(record)

    def _record_timing():
        record["wall_s"] = time.perf_counter() - t0
        write_text_atomic(timing_file, json.dumps(timing))

    def _on_shard(task, res):  # after the store wrote it
        record["new_shards"] += 1
        _record_timing()
        if bar is not None:
            bar.update(len(task.args[0]["rows"]))

    ex = executor
    if ex is None:
        ex = LocalExecutor(0 if int(n_workers) == 1 or n_todo <= 1 else int(n_workers))
    record.update(n_workers=int(ex.n_workers), executor=ex.describe())
    try:
        run_tasks(tasks, ex, store, on_result=_on_shard, max_tasks=max_shards)
    finally:
        if executor is None:
            ex.close()
        if bar is not None:
            bar.close()
    _record_timing()
    if not all(store.path(key).exists() for key in keys):
        return None
    parts = [store.get(key) for key in keys]
    optional = [k for k in OPTIONAL_PER_TRAJECTORY_KEYS if all(k in p for p in parts)]
    arrays = {key: np.concatenate([p[key] for p in parts])
              for key in (*PER_TRAJECTORY_KEYS, *optional, *PER_SAMPLE_KEYS)}
    meta["wall_s"] = float(sum(t["wall_s"] for t in timing))
    meta["wall_s_sessions"] = timing
    meta["solver_wall_s_per_trajectory"] = float(np.mean(arrays["solve_wall_s"]))
    save_dataset(out, meta, arrays)
    return load_dataset(out)

