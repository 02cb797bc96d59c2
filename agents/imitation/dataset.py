"""Datasets of optimal landings for imitation learning: (observation, action) pairs in the env's
own spaces, each from a certified minimum-fuel trajectory.

::

    python -m agents.dataset                                   # 1000 trajectories, zhu2007
    python -m agents.dataset --n 20 --out data/imitation/small.npz --workers 1
    python -m agents.dataset --n 1000 --workers 2 --out data/imitation/zhu2007_1000.npz  # resumes

Pipeline
--------
1. Initial states: ``scenario.sample_initial(np.random.default_rng(seed), n)`` (SI rows), the
   scenario's dispersion, the same draw the env's reset makes (but a different seed from the
   evaluation set, so the evaluation states are held out).
2. Solver: :func:`optimizers.indirect.batch.solve_many` (indirect shooting, each solve warm-started
   from its nearest neighbour in the chain). Decision (measured, not assumed): it is the fastest
   certified solver available here — ~12–19 ms per state serial on this loaded machine. A
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

Pinpoint (``--env LunarPinpointLanding-v*``): no open-loop solution can be sampled there (the
optimum held over 1 s env steps misses the gate by ~10 m/s, and a clone of the optimal
trajectories alone drifts off them), so the samples come from the **Pontryagin feedback
expert's own closed-loop flights** (:func:`pinpoint_expert_flights`): at every decision the
minimum-fuel extremal is re-solved from the visited state (~1-15 ms), the label is its law
averaged over the step, and the env is flown with that action plus Gaussian noise (``--noise``,
default :data:`PINPOINT_ACTION_NOISE`), so the states cover the tube a learner visits. Per
trajectory, ``fuel_kg`` / ``tf_s`` are the extremal from the initial state (the per-case
optimum) and ``replay_*`` the noisy flight; ``certified`` = that flight is the env's success
within the tolerances (default: the env's, 5 m/s and 500 m) and the first solve converged.

Parallel, progress, resume: the rows are split into shards of ``shard_size``; shards are tasks
of :mod:`optimizers.common.executor` (a local process pool of ``--workers``, or a Ray cluster
with ``--address`` / ``RAY_ADDRESS``), each written atomically to ``<out>.shards/shard_<k>.npz``.
A re-run with the same arguments skips finished shards (an interrupted run loses at most the
shards in flight); the meta of the shard directory must match or the run refuses to mix data.
The finished shards are merged into ``<out>``.

File format (``FORMAT_VERSION`` = 1; ``numpy.savez_compressed``)
---------------------------------------------------------------
``meta`` : 0-d str, JSON: ``format_version``, ``env_id``, ``env_kwargs``, ``scenario``, ``seed``,
    ``n_trajectories``, ``dt_s``, ``label_rule``, ``solver`` (name, n_steps, check),
    ``certification`` (tolerances), ``observation_names``, ``wall_s`` (generation), ...
Per sample (M rows):
``observations`` (M, n_obs) float32; ``actions`` (M, n_act) float32 (env action space);
``traj_index`` (M,) int64; ``t_s`` (M,) float64; ``state_nd`` (M, 5) float64 (normalised
    (r, vr, θ, ω, m)); ``phi_rad`` (M,) float64 (the label's thrust angle).
Per trajectory (N rows):
``initial_state_si`` (N, 5) (r m, vr m/s, θ rad, v_t m/s, m kg); ``solver_success`` (N,) bool;
``fuel_kg``, ``tf_s`` (N,) (optimum; NaN when the solve failed); ``terminal_error_radius_m``,
``terminal_error_speed_m_s`` (N,); ``replay_fuel_kg``, ``replay_touchdown_speed_m_s`` (N,),
``replay_success`` (N,) bool; ``replay_fuel_gap_kg`` (N,); ``certified`` (N,) bool;
``solve_wall_s`` (N,).
Only certified trajectories contribute samples.
"""

from __future__ import annotations

import json
import os
import time
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from agents.common.law import ActionSequenceLaw, Navigation, PrivilegedLaw, Truth
from agents.common.rollout import fly
from agents.common.runs import write_text_atomic
from agents.experts.pinpoint import PinpointPontryaginExpert
from agents.imitation.data import (
    FORMAT_VERSION,
    OPTIONAL_PER_TRAJECTORY_KEYS,
    PER_SAMPLE_KEYS,
    PER_TRAJECTORY_KEYS,
    ImitationDataset,
    load_dataset,
    save_dataset,
)

__all__ = ["generate", "trajectory_samples", "replay_labels", "pinpoint_expert_flights"]

DEFAULT_ENV_ID = "LunarSoftLanding-v0"
DEFAULT_OUT = "data/imitation/LunarSoftLanding-v0_n1000_seed0.npz"
LABEL_RULE = "action_from_thrust_angle(phi*(t_k + dt_s/2)), t_k = k*dt_s < tf"
PINPOINT_LABEL_RULE = ("action_from_angles(mean of the extremal's (alpha*, beta*) over "
                       "[t_k, t_k + dt_s]) at each state visited by the Pontryagin feedback "
                       "expert's own flight, flown with Gaussian action noise (DART)")
#: pinpoint certification: the expert's (noisy) flight is the env's success and lands within
#: these gate miss / gate speed (default: the env's own success tolerances)
PINPOINT_TOLERANCES = {"radius_m": 500.0, "speed_m_s": 5.0}
#: pinpoint: standard deviation of the action noise of the expert's flights (action units;
#: 0.02 = 0.9° of α or β). Measured (50 flights at 1 s decisions): the noisy expert still lands
#: 98 % (gate speed median 1.2 m/s, miss median 20 m) and its states cover the tube a clone
#: visits; a clone trained on noise-free flights drifts 1-10 km from them.
PINPOINT_ACTION_NOISE = 0.02


# --------------------------------------------------------------------------------- samples


def _make_env(env_id: str, env_kwargs: dict[str, Any] | None):
    import gymnasium as gym

    import lunar_env  # noqa: F401  (registers the ids)

    return gym.make(env_id, **(env_kwargs or {})).unwrapped


def trajectory_samples(sol, env, dt_s: float) -> dict[str, np.ndarray]:
    """(observation, action) samples of one optimal solution at the env's decision times.

    Parameters
    ----------
    sol : PontryaginSolution
        A converged solution (``state_costate_at``, ``thrust_angle_at``, ``tf_s``).
    env : LunarSoftLandingEnv (unwrapped)
        Provides ``observation_from_state``.
    dt_s : float
        Env step (s).

    Returns
    -------
    dict with ``observations`` (K, n_obs) float32, ``actions`` (K, 1) float32, ``t_s`` (K,),
    ``state_nd`` (K, 5), ``phi_rad`` (K,) — see :data:`LABEL_RULE`.
    """
    from lunar_env.envs.soft_landing import action_from_thrust_angle

    n_k = int(np.ceil(sol.tf_s / dt_s - 1e-9))
    t = dt_s * np.arange(max(n_k, 1), dtype=np.float64)
    x = sol.state_costate_at(t)[:, :5]
    phi = np.asarray(sol.thrust_angle_at(np.minimum(t + 0.5 * dt_s, sol.tf_s)), dtype=np.float64)
    obs = np.asarray(env.observation_from_state(x, t), dtype=np.float32)
    act = np.asarray(action_from_thrust_angle(phi), dtype=np.float32).reshape(-1, 1)
    return {"observations": obs, "actions": act, "t_s": t, "state_nd": x, "phi_rad": phi}


def replay_labels(env_id: str, env_kwargs: dict[str, Any] | None,
                  initial_state_si: np.ndarray | None, action_seqs: list[np.ndarray],
                  initial_state_nd: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Replay per-case action sequences open-loop in the native vector env.

    Each case starts from its SI initial state (or its normalised ``initial_state_nd``); after
    its sequence ends the last action is held.

    Returns
    -------
    dict with ``fuel_kg``, ``touchdown_speed_m_s`` (NaN if the episode was truncated), ``success``
    (arrays of length n_cases).
    """
    n = len(action_seqs)
    lens = np.array([len(a) for a in action_seqs])
    out = fly(env_id, ActionSequenceLaw(action_seqs), n, seed=0, env_kwargs=env_kwargs,
              reset_options=({"state_si": np.asarray(initial_state_si, dtype=np.float64)}
                             if initial_state_nd is None else
                             {"state_nd": np.asarray(initial_state_nd, dtype=np.float64)}),
              max_steps=int(lens.max()) + 100_000)
    fuel, speed, success = out.fuel_used_kg, out.touchdown_speed_m_s, out.is_success
    return {"fuel_kg": fuel, "touchdown_speed_m_s": speed, "success": success}


def _is_pinpoint(scenario) -> bool:
    from lunar_env.scenarios import PinpointScenario

    return isinstance(scenario, PinpointScenario)


class ExpertFlightTeacher(PrivilegedLaw):
    """The pinpoint feedback expert's own flights with DART action noise, every visited *true*
    state labelled with its clean action (a privileged teacher: see
    :func:`pinpoint_expert_flights`).

    Parameters
    ----------
    expert : PinpointPontryaginExpert
    n : int
        Cases flown.
    action_noise : float
        Standard deviation of the Gaussian noise on the flown action (action units).
    rng : numpy.random.Generator
    """

    name = "Pontryagin feedback expert"

    def __init__(self, expert, n: int, action_noise: float, rng: np.random.Generator) -> None:
        self.expert = expert
        self.action_noise = float(action_noise)
        self.rng = rng
        self.records: dict[str, list] = {
            k: [[] for _ in range(n)]
            for k in ("observations", "actions", "t_s", "state_nd", "phi_rad", "status")}
        #: optimum fuel (kg) and tf (s) of the extremal from each initial state
        self.first = np.full((n, 2), np.nan)

    def reset(self, computer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self.expert.reset(computer, case_ids)

    def act_privileged(self, nav: Navigation, truth: Truth) -> np.ndarray:
        states, times = truth.state_nd, truth.t_s
        ang, lab, is_label = self.expert.labels(states, times, nav.active)
        status = self.expert.last_status
        tgo = self.expert.feedback.last_tgo_s
        flow = self.expert.scenario.vehicle.mass_flow_kg_s
        rec = self.records
        for i in np.flatnonzero(nav.active):
            if times[i] == 0.0 and status[i] == "optimal":
                self.first[i] = flow * tgo[i], tgo[i]
            if is_label[i]:
                for key, val in (("observations", nav.obs[i]), ("actions", lab[i]),
                                 ("t_s", times[i]), ("state_nd", states[i]),
                                 ("phi_rad", ang[i]), ("status", status[i])):
                    rec[key][i].append(np.array(val, copy=True))
        noise = (self.rng.normal(0.0, self.action_noise, lab.shape) if self.action_noise > 0
                 else 0.0)
        return np.clip(lab + noise, -1.0, 1.0).astype(np.float32)


def pinpoint_expert_flights(rows_nd: np.ndarray, env_id: str,
                            env_kwargs: dict[str, Any] | None, action_noise: float,
                            rng: np.random.Generator) -> dict[str, Any]:
    """Fly the Pontryagin feedback expert from each normalised initial state and label every
    visited state with its clean action (DART: Laskey et al. 2017).

    The expert (:class:`agents.experts.pinpoint.PinpointPontryaginExpert`) re-solves the
    minimum-fuel
    extremal from the lander's state at every decision; the env is flown with its action plus
    Gaussian noise of standard deviation ``action_noise`` (action units; 0.02 ≈ 0.9°), so the
    visited states spread around the optimal trajectory the way a learner's do, while every
    label stays the expert's optimal action there (:data:`PINPOINT_LABEL_RULE`). Labels whose
    solve did not converge (status "stale"/"fallback") are dropped.

    Returns per case: ``samples`` (list of dicts ``observations``, ``actions``, ``t_s``,
    ``state_nd``, ``phi_rad``, ``status``), the flight's ``success``, ``touchdown_speed_m_s``,
    ``miss_m``, ``fuel_kg``; ``optimum_fuel_kg`` / ``optimum_tf_s`` of the extremal from the
    initial state (the per-case optimum; NaN if that first solve failed); ``wall_s``.
    """
    env = _make_env(env_id, env_kwargs)
    sc = env.scenario
    env.close()
    x0 = np.asarray(rows_nd, dtype=np.float64)
    n = len(x0)
    teacher = ExpertFlightTeacher(PinpointPontryaginExpert(sc), n, action_noise, rng)
    t0 = time.perf_counter()
    out = fly(env_id, teacher, n, seed=0, env_kwargs=env_kwargs, reset_options={"state_nd": x0})
    rec, first, expert = teacher.records, teacher.first, teacher.expert
    samples = []
    for i in range(n):
        if not rec["t_s"][i]:
            samples.append(None)
            continue
        smp = {k: np.asarray(v[i]) for k, v in rec.items()}
        smp["observations"] = smp["observations"].astype(np.float32)
        smp["actions"] = smp["actions"].astype(np.float32)
        samples.append(smp)
    return {"samples": samples, "success": out.is_success,
            "touchdown_speed_m_s": out.touchdown_speed_m_s, "miss_m": out.miss_distance_m,
            "fuel_kg": out.fuel_used_kg, "optimum_fuel_kg": first[:, 0],
            "optimum_tf_s": first[:, 1], "wall_s": time.perf_counter() - t0,
            "status_counts": dict(expert.status_counts)}


def _pinpoint_shard_work(job: dict[str, Any]) -> dict[str, np.ndarray]:
    """Fly, label and certify one pinpoint shard (see :func:`pinpoint_expert_flights`)."""
    from lunar_env.states import moon3d_nd_to_si

    env = _make_env(job["env_id"], job["env_kwargs"])
    sc = env.scenario
    n_obs = env.observation_space.shape[0]
    env.close()
    x0 = np.asarray(job["rows"], dtype=np.float64)
    t0 = time.perf_counter()
    rng = np.random.default_rng([int(job["seed"]), int(job["k"])])
    fl = pinpoint_expert_flights(x0, job["env_id"], job["env_kwargs"],
                                 float(job["action_noise"]), rng)
    n = len(x0)
    samples = fl["samples"]
    ok = np.isfinite(fl["optimum_fuel_kg"])
    err_v = np.asarray(fl["touchdown_speed_m_s"], dtype=np.float64)
    err_r = np.asarray(fl["miss_m"], dtype=np.float64)
    flown_ok = np.asarray(fl["success"], dtype=bool)
    cert = (ok & flown_ok & np.array([s is not None for s in samples])
            & (err_v <= job["tol_speed_m_s"]) & (err_r <= job["tol_radius_m"]))
    out: dict[str, Any] = {
        "initial_state_si": moon3d_nd_to_si(x0, sc.scaling()), "solver_success": ok,
        "start_time_s": np.zeros(n), "parent_index": np.full(n, -1, dtype=np.int64),
        "fuel_kg": fl["optimum_fuel_kg"], "tf_s": fl["optimum_tf_s"],
        "terminal_error_radius_m": err_r, "terminal_error_speed_m_s": err_v,
        "replay_fuel_kg": np.asarray(fl["fuel_kg"], dtype=np.float64),
        "replay_touchdown_speed_m_s": err_v, "replay_success": flown_ok,
        "replay_fuel_gap_kg": np.asarray(fl["fuel_kg"], dtype=np.float64)
        - fl["optimum_fuel_kg"], "certified": cert,
        "solve_wall_s": np.full(n, fl["wall_s"] / max(n, 1)),
    }
    _collect_samples(out, samples, cert, job["first_index"], n_obs, n_act=2, nx=7, n_angle=2)
    out["wall_s"] = np.array(time.perf_counter() - t0)
    return out


def _collect_samples(out: dict[str, Any], samples: list, cert: np.ndarray, first: int,
                     n_obs: int, n_act: int, nx: int, n_angle: int) -> None:
    """Concatenate the certified trajectories' samples into ``out`` (empty arrays if none)."""
    keep = [i for i in range(len(samples)) if cert[i]]
    shape = {"observations": (0, n_obs), "actions": (0, n_act), "state_nd": (0, nx),
             "phi_rad": (0, n_angle) if n_angle > 1 else (0,)}
    for key in ("observations", "actions", "t_s", "state_nd", "phi_rad"):
        if keep:
            out[key] = np.concatenate([samples[i][key] for i in keep])
        else:
            out[key] = np.zeros(shape.get(key, (0,)),
                                dtype=np.float32 if key in ("observations", "actions")
                                else np.float64)
    out["traj_index"] = (np.concatenate([np.full(len(samples[i]["t_s"]), first + i)
                                         for i in keep]).astype(np.int64)
                         if keep else np.zeros(0, dtype=np.int64))


def _shard_work(job: dict[str, Any]) -> dict[str, np.ndarray]:
    """Solve, sample and certify one shard (runs in a worker process)."""
    import warnings

    from optimizers.indirect.batch import solve_many

    if job.get("pinpoint"):
        return _pinpoint_shard_work(job)
    env = _make_env(job["env_id"], job["env_kwargs"])
    sc = env.scenario
    rows = np.asarray(job["rows"], dtype=np.float64)
    dt_s = float(job["dt_s"])
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sols = solve_many(sc, rows, n_workers=1, progress=False, n_steps=job["n_steps"],
                          check=job["check"])
    n = len(rows)
    wall = np.full(n, (time.perf_counter() - t0) / max(n, 1))
    ok = np.array([s.success for s in sols], dtype=bool)
    fuel = np.array([s.fuel_kg if s.success else np.nan for s in sols])
    tf = np.array([s.tf_s if s.success else np.nan for s in sols])
    err_r = np.array([s.terminal_errors.get("radius_m", np.nan) if s.success else np.nan
                      for s in sols])
    err_v = np.array([s.terminal_errors.get("speed_m_s", np.nan) if s.success else np.nan
                      for s in sols])
    samples = [trajectory_samples(s, env, dt_s) if s.success else None for s in sols]
    idx_ok = np.flatnonzero(ok)
    rep_fuel = np.full(n, np.nan)
    rep_speed = np.full(n, np.nan)
    rep_ok = np.zeros(n, dtype=bool)
    if len(idx_ok):
        rep = replay_labels(job["env_id"], job["env_kwargs"], rows[idx_ok],
                            [samples[i]["actions"] for i in idx_ok])
        rep_fuel[idx_ok] = rep["fuel_kg"]
        rep_speed[idx_ok] = rep["touchdown_speed_m_s"]
        rep_ok[idx_ok] = rep["success"]
    cert = (ok & (err_r <= job["tol_radius_m"]) & (err_v <= job["tol_speed_m_s"]) & rep_ok)
    out: dict[str, Any] = {
        "initial_state_si": rows, "solver_success": ok, "fuel_kg": fuel, "tf_s": tf,
        "terminal_error_radius_m": err_r, "terminal_error_speed_m_s": err_v,
        "replay_fuel_kg": rep_fuel, "replay_touchdown_speed_m_s": rep_speed,
        "replay_success": rep_ok, "replay_fuel_gap_kg": rep_fuel - fuel, "certified": cert,
        "solve_wall_s": wall,
    }
    _collect_samples(out, samples, cert, job["first_index"], env.observation_space.shape[0],
                     n_act=1, nx=5, n_angle=1)
    out["wall_s"] = np.array(time.perf_counter() - t0)
    return out


# --------------------------------------------------------------------------------- driver


def _shard_path(shard_dir: Path, k: int) -> Path:
    return shard_dir / f"shard_{k:05d}.npz"


def _read_shard(path: Path) -> dict[str, np.ndarray]:
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


def _shard_done(path: Path) -> bool:
    """True if the shard exists and reads; a damaged one is moved aside (``.damaged``) with a
    message naming it, and its rows are solved again."""
    if not path.exists():
        return False
    try:
        _read_shard(path)
        return True
    except ValueError as exc:
        os.replace(path, path.with_name(path.name + ".damaged"))
        print(f"{exc}: moved to {path.name}.damaged; its rows are solved again")
        return False


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
        Passed to :func:`optimizers.indirect.batch.solve_many`.
    tol_radius_m, tol_speed_m_s : float, optional
        Certification tolerances. Soft landing: on the solver's terminal errors (default
        1e-3 m, 1e-3 m/s). Pinpoint: on the gate miss and gate speed of the expert's own flight
        (:func:`pinpoint_expert_flights`; default :data:`PINPOINT_TOLERANCES`), on top of the
        env's success verdict.
    max_shards : int, optional
        Stop after this many new shards (simulates an interruption; returns None).
    action_noise : float, optional
        Pinpoint only: standard deviation of the Gaussian noise on the expert's flown actions
        (default :data:`PINPOINT_ACTION_NOISE`; 0 gives the optimal trajectories themselves).
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
    env = _make_env(env_id, env_kwargs)
    sc = env.scenario
    dt_s = float(env.dt_s)
    pinpoint = _is_pinpoint(sc)
    obs_names = (["altitude/h0", "d_radial/d0", "d_along/d0", "d_cross/d0", "u/(0.1 v0)",
                  "v/v0", "w/(0.1 v0)", "propellant/nominal", "t/time_limit"] if pinpoint else
                 ["altitude/h0", "vr/(0.1 v0)", "v_t/v0", "propellant/nominal", "t/time_limit"])
    env.close()
    if pinpoint:
        s_nd = sc.scaling()
        rows = np.array([sc.state_nd(r, scaling=s_nd)
                         for r in sc.sample_initial(np.random.default_rng(int(seed)), int(n))])
        tol_radius_m = PINPOINT_TOLERANCES["radius_m"] if tol_radius_m is None else tol_radius_m
        tol_speed_m_s = (PINPOINT_TOLERANCES["speed_m_s"] if tol_speed_m_s is None
                         else tol_speed_m_s)
        action_noise = PINPOINT_ACTION_NOISE if action_noise is None else float(action_noise)
        if not (np.isfinite(action_noise) and action_noise >= 0.0):
            raise ValueError(f"action_noise = {action_noise!r} must be finite and >= 0")
        solver_meta = {"name": "agents.experts.pinpoint.PinpointPontryaginExpert (the minimum-fuel "
                               "extremal from every visited state, optimizers.indirect."
                               "pinpoint_feedback)", "action_noise": action_noise}
        cert_meta = {"tol_radius_m": tol_radius_m, "tol_speed_m_s": tol_speed_m_s,
                     "replay": "the expert's own flight (with the action noise): is_success "
                               "and gate miss / speed within the tolerances"}
    else:
        if action_noise is not None:
            raise ValueError(f"action_noise = {action_noise!r}: defined for the pinpoint env "
                             "only (soft-landing datasets sample the optimal trajectories)")
        rows = sc.sample_initial(np.random.default_rng(int(seed)), int(n))
        tol_radius_m = 1e-3 if tol_radius_m is None else tol_radius_m
        tol_speed_m_s = 1e-3 if tol_speed_m_s is None else tol_speed_m_s
        solver_meta = {"name": "optimizers.indirect.batch.solve_many", "n_steps": int(n_steps),
                       "check": check, "warm_start": "nearest-neighbour chain per shard"}
        cert_meta = {"tol_radius_m": tol_radius_m, "tol_speed_m_s": tol_speed_m_s,
                     "replay": "labels replayed open-loop in the native vector env; "
                               "must be is_success"}
    meta = {
        "format_version": FORMAT_VERSION, "env_id": env_id, "env_kwargs": dict(env_kwargs or {}),
        "scenario": sc.name, "seed": int(seed), "n_trajectories": int(n),
        "shard_size": int(shard_size), "dt_s": dt_s,
        "label_rule": PINPOINT_LABEL_RULE if pinpoint else LABEL_RULE,
        "solver": solver_meta, "certification": cert_meta,
        "observation_names": obs_names, "initial_states": "scenario.sample_initial(rng, n)"
        + (" -> scenario.state_nd (initial_state_si: Moon-fixed SI)" if pinpoint else ""),
    }
    shard_dir = out.with_name(out.name + ".shards")
    shard_dir.mkdir(parents=True, exist_ok=True)
    meta_file = shard_dir / "meta.json"
    key_meta = {k: meta[k] for k in ("format_version", "env_id", "env_kwargs", "scenario",
                                     "seed", "n_trajectories", "shard_size", "dt_s", "solver",
                                     "certification")}
    if meta_file.exists():
        old = json.loads(meta_file.read_text())
        if old != json.loads(json.dumps(key_meta)):
            raise ValueError(f"{shard_dir} holds shards made with other settings "
                             f"({old}); delete it or choose another --out")
    else:
        write_text_atomic(meta_file, json.dumps(key_meta, indent=1))
    n_shards = (int(n) + int(shard_size) - 1) // int(shard_size)
    jobs = []
    done_before = 0
    for k in range(n_shards):
        lo, hi = k * int(shard_size), min((k + 1) * int(shard_size), int(n))
        if _shard_done(_shard_path(shard_dir, k)):
            done_before += hi - lo
            continue
        jobs.append({"k": k, "rows": rows[lo:hi], "first_index": lo, "env_id": env_id,
                     "env_kwargs": dict(env_kwargs or {}), "dt_s": dt_s, "n_steps": int(n_steps),
                     "check": check, "tol_radius_m": float(tol_radius_m),
                     "tol_speed_m_s": float(tol_speed_m_s), "pinpoint": pinpoint,
                     "action_noise": action_noise, "seed": int(seed)})
    if max_shards is not None:
        jobs = jobs[:int(max_shards)]
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=int(n), initial=done_before, desc=f"optimal landings {sc.name}",
                   unit="traj")
    t0 = time.perf_counter()
    # This session's timing is rewritten (atomically) after every shard, so a run killed
    # part-way still accounts for the shards it finished.
    timing_file = shard_dir / "timing.json"
    timing = json.loads(timing_file.read_text()) if timing_file.exists() else []
    session = {"new_shards": 0, "wall_s": 0.0, "n_workers": int(n_workers)}
    timing.append(session)

    def _record_timing():
        session["wall_s"] = time.perf_counter() - t0
        write_text_atomic(timing_file, json.dumps(timing))

    def _store(job, res):
        wall = float(res.pop("wall_s"))
        path = _shard_path(shard_dir, job["k"])
        tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.npz")
        np.savez_compressed(tmp, wall_s=np.array(wall), **res)
        os.replace(tmp, path)
        session["new_shards"] += 1
        _record_timing()
        if bar is not None:
            bar.update(len(job["rows"]))

    from optimizers.common.executor import LocalExecutor, Task, TaskKey, run_tasks

    tasks = [Task(TaskKey(f"dataset-{sc.name}", int(seed), job["k"]), _shard_work, (job,))
             for job in jobs]
    by_k = {job["k"]: job for job in jobs}
    ex = executor
    if ex is None:
        ex = LocalExecutor(0 if int(n_workers) == 1 or len(jobs) <= 1 else int(n_workers))
    session.update(n_workers=int(ex.n_workers), executor=ex.describe())
    try:
        run_tasks(tasks, ex, on_result=lambda task, res: _store(by_k[task.key.index], res))
    finally:
        if executor is None:
            ex.close()
        if bar is not None:
            bar.close()
    _record_timing()
    if not all(_shard_path(shard_dir, k).exists() for k in range(n_shards)):
        return None
    parts = [_read_shard(_shard_path(shard_dir, k)) for k in range(n_shards)]
    optional = [k for k in OPTIONAL_PER_TRAJECTORY_KEYS if all(k in p for p in parts)]
    arrays = {key: np.concatenate([p[key] for p in parts])
              for key in (*PER_TRAJECTORY_KEYS, *optional, *PER_SAMPLE_KEYS)}
    meta["wall_s"] = float(sum(t["wall_s"] for t in timing))
    meta["wall_s_sessions"] = timing
    meta["solver_wall_s_per_trajectory"] = float(np.mean(arrays["solve_wall_s"]))
    save_dataset(out, meta, arrays)
    return load_dataset(out)

