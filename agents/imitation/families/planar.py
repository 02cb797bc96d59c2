"""The planar family's imitation data: dataset shards sampled from certified optimal
trajectories, and DAgger labels of the policy's roll-outs by :class:`~agents.experts.planar.
PontryaginExpert` (what :meth:`guidance.families.planar.PlanarFamily.dataset_recipe` and
:meth:`~guidance.families.planar.PlanarFamily.dagger_iteration` answer).

Dataset (see :mod:`agents.imitation.dataset` for the pipeline and the file format): initial
states ``scenario.sample_initial(rng, n)`` (SI rows), solved by
:func:`optimizers.indirect.batch.solve_many`, sampled at the env's decision times
(:data:`LABEL_RULE`), certified on the solver's terminal errors and on the open-loop replay of
the labels in the env.
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from agents.imitation.families import DaggerRequest, DatasetRecipe, ImitationFamily
from agents.imitation.flights import collect_samples, make_env
from agents.imitation.teachers import (
    TEACHER_KINDS,
    law_dagger_chunk,
    law_dagger_rollouts,
    parse_teacher,
)
from guidance.flight import fly
from guidance.law import ActionSequenceLaw, CallableLaw
from guidance.laws.pontryagin_planar import PontryaginExpert, planar_state_si
from lunar_env import get_scenario
from lunar_env.envs.soft_landing import action_from_thrust_angle
from lunar_env.scenarios import PlanarScenario
from optimizers.optimum import plant_scenario

__all__ = ["LABEL_RULE", "OBSERVATION_NAMES", "TEACHERS", "trajectory_samples", "replay_labels",
           "planar_shard", "planar_dataset_recipe", "rollout_policy", "check_teacher",
           "teacher_view", "label_chunk", "label_episodes", "planar_dagger_iteration"]

LABEL_RULE = "action_from_thrust_angle(phi*(t_k + dt_s/2)), t_k = k*dt_s < tf"
OBSERVATION_NAMES = ["altitude/h0", "vr/(0.1 v0)", "v_t/v0", "propellant/nominal",
                     "t/time_limit"]
#: certification tolerances on the solver's terminal errors (m, m/s)
DEFAULT_TOLERANCES = {"radius_m": 1e-3, "speed_m_s": 1e-3}
#: the planar expert's two views (the built-in kinds of ``dagger.teacher``,
#: :data:`agents.imitation.teachers.TEACHER_KINDS`): ``privileged`` plans from the lander's
#: true state with its true plant (the scenario's engine with the episode's drawn thrust and
#: Isp scales: the omniscient feedback law); ``navigated`` plans from the navigation solution
#: the student is given, with the nominal plant. In the nominal world they coincide.
TEACHERS = TEACHER_KINDS


# --------------------------------------------------------------------------------- dataset


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
    lens = np.array([len(a) for a in action_seqs])
    out = fly(env_id, ActionSequenceLaw(action_seqs), len(action_seqs), seed=0,
              env_kwargs=env_kwargs,
              reset_options=({"state_si": np.asarray(initial_state_si, dtype=np.float64)}
                             if initial_state_nd is None else
                             {"state_nd": np.asarray(initial_state_nd, dtype=np.float64)}),
              max_steps=int(lens.max()) + 100_000)
    return {"fuel_kg": out.fuel_used_kg, "touchdown_speed_m_s": out.touchdown_speed_m_s,
            "success": out.is_success}


def planar_shard(job: dict[str, Any]) -> dict[str, np.ndarray]:
    """Solve, sample and certify one shard (an executor task; ``job``: see
    :class:`optimizers.optimum.DatasetRecipe`, plus ``n_steps`` and ``check``)."""
    from optimizers.indirect.batch import solve_many

    env = make_env(job["env_id"], job["env_kwargs"])
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
    collect_samples(out, samples, cert, job["first_index"], env.observation_space.shape[0],
                    n_act=1, nx=5, n_angle=1)
    env.close()
    out["wall_s"] = np.array(time.perf_counter() - t0)
    return out


def planar_dataset_recipe(scenario, n: int, seed: int, *, n_steps: int, check: str,
                          tol_radius_m: float | None, tol_speed_m_s: float | None,
                          action_noise: float | None) -> DatasetRecipe:
    """The planar dataset recipe (see :meth:`optimizers.optimum.EnvFamily.dataset_recipe`):
    SI initial rows (n, 5), tolerances on the solver's terminal errors (default 1e-3 m,
    1e-3 m/s). ``action_noise`` must be None (the samples are the optimal trajectories)."""
    if action_noise is not None:
        raise ValueError(f"action_noise = {action_noise!r}: defined for the pinpoint env "
                         "only (soft-landing datasets sample the optimal trajectories)")
    rows = scenario.sample_initial(np.random.default_rng(int(seed)), int(n))
    tol_r = DEFAULT_TOLERANCES["radius_m"] if tol_radius_m is None else tol_radius_m
    tol_v = DEFAULT_TOLERANCES["speed_m_s"] if tol_speed_m_s is None else tol_speed_m_s
    return DatasetRecipe(
        rows=rows, observation_names=list(OBSERVATION_NAMES), label_rule=LABEL_RULE,
        initial_states="scenario.sample_initial(rng, n)",
        solver={"name": "optimizers.indirect.batch.solve_many", "n_steps": int(n_steps),
                "check": check, "warm_start": "nearest-neighbour chain per shard"},
        certification={"tol_radius_m": tol_r, "tol_speed_m_s": tol_v,
                       "replay": "labels replayed open-loop in the native vector env; "
                                 "must be is_success"},
        shard_fn=planar_shard, job_args={"n_steps": int(n_steps), "check": check})


# --------------------------------------------------------------------------------- DAgger


def rollout_policy(learner, env_id: str, env_kwargs: dict[str, Any] | None, n_episodes: int,
                   seed: int) -> list[dict[str, Any]]:
    """Fly ``learner(obs (N, n_obs)) -> actions (N, 1)`` from ``n_episodes`` dispersed starts.

    Sub-env i is reset with seed ``seed + i`` (its plant and navigation errors, under an
    ``uncertainty`` env argument, from that seed's error stream). Returns one dict per
    episode: ``obs`` (T, n_obs), ``state_nd`` (T, 5) (the true states),
    ``navigation_state_nd`` (T, 5) (the navigation solutions the observations encode) and
    ``t_s`` (T,) — the states at which the policy acted —, the lander's true plant
    ``thrust_scale`` and ``isp_scale`` (true / nominal; 1 without an uncertainty model), and
    the outcome ``success``, ``fuel_kg``, ``touchdown_speed_m_s``.
    """
    law = CallableLaw(lambda nav: learner(nav.obs))
    res = fly(env_id, law, n_episodes, seed=seed, env_kwargs=env_kwargs,
              record=range(n_episodes), max_steps=100_000)
    err = res.episode_errors
    out: list[dict[str, Any]] = []
    for i in range(n_episodes):
        r = res.records[i]
        out.append({"success": bool(res.is_success[i]), "fuel_kg": float(res.fuel_used_kg[i]),
                    "touchdown_speed_m_s": float(res.touchdown_speed_m_s[i]),
                    "obs": r["obs"], "state_nd": r["state_nd"],
                    "navigation_state_nd": r["navigation_state_nd"], "t_s": r["t_s"],
                    "thrust_scale": float(err.thrust_scale[i]),
                    "isp_scale": float(err.isp_scale[i])})
    return out


def check_teacher(teacher: str) -> str:
    """``teacher`` if it is one of :data:`TEACHERS`, else ValueError naming the allowed ones."""
    if not isinstance(teacher, str) or teacher not in TEACHERS:
        raise ValueError(f"dagger teacher = {teacher!r} is not allowed; choose one of "
                         f"{', '.join(TEACHERS)} (privileged: true state and true plant; "
                         "navigated: the student's navigation solution and the nominal plant)")
    return teacher


def teacher_view(episode: dict[str, Any], teacher: str) -> tuple[np.ndarray, float, float]:
    """What ``teacher`` knows of one roll-out: the states it plans from (T, 5), normalised,
    and the plant's thrust and Isp scales (true / nominal).

    ``privileged``: the recorded true states ``state_nd`` and the episode's ``thrust_scale``
    and ``isp_scale`` (1 when absent: an episode flown on the nominal plant, e.g. an optimal
    trajectory). The plant's thrust-direction misalignment is not part of it (decision): the
    label is the commanded angle of the optimal plan, as the campaign's omniscient optimum
    is the fuel of the true engine, not of a compensated gimbal. ``navigated``: the recorded
    ``navigation_state_nd`` and scales of 1 (the nominal plant).

    Raises
    ------
    ValueError
        ``teacher`` is not one of :data:`TEACHERS`, or the navigated teacher is asked of an
        episode without a recorded navigation solution.
    """
    check_teacher(teacher)
    if teacher == "privileged":
        return (np.asarray(episode["state_nd"], dtype=np.float64),
                float(episode.get("thrust_scale", 1.0)), float(episode.get("isp_scale", 1.0)))
    if "navigation_state_nd" not in episode:
        raise ValueError("the navigated teacher needs each episode's navigation_state_nd "
                         "(recorded by rollout_policy); this episode has only "
                         f"{', '.join(sorted(episode))}")
    return np.asarray(episode["navigation_state_nd"], dtype=np.float64), 1.0, 1.0


def label_chunk(job: dict[str, Any]) -> list[dict[str, np.ndarray]]:
    """Label the chosen steps of some episodes with the closed-loop expert (an executor task).

    ``job``: ``scenario`` (name), ``dt_s``, ``teacher`` (one of :data:`TEACHERS`; default
    ``privileged``), ``episodes`` (dicts with ``obs``, ``t_s``, ``label_idx`` and what
    :func:`teacher_view` reads). The expert (:class:`PontryaginExpert`, one per episode,
    re-planning in time order warm-started from its previous plan) plans from the teacher's
    states with the teacher's plant: ``privileged``, the true states and the lander's true
    engine (:func:`optimizers.optimum.plant_scenario`, as the campaign's omniscient optimum
    and the pinpoint roll-outs' :class:`agents.imitation.families.pinpoint.DaggerRolloutTeacher`);
    ``navigated``, the navigation solutions the student saw and the nominal engine. The SI
    states come from the nominal scaling, which the plant does not change. The labels pair
    the student's observations ``obs`` with the teacher's actions."""
    from optimizers.indirect.planar import release_solvers

    sc = get_scenario(job["scenario"])
    dt_s = float(job["dt_s"])
    teacher = check_teacher(job.get("teacher", TEACHERS[0]))
    res = []
    for ep in job["episodes"]:
        states_nd, thrust_scale, isp_scale = teacher_view(ep, teacher)
        plant = plant_scenario(sc, thrust_scale, isp_scale)
        expert = PontryaginExpert(plant)
        idx = ep["label_idx"]
        si = planar_state_si(sc, states_nd[idx])
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
            plan = expert.plan(0)
            if st == "optimal" and plan is not None:
                p = float(plan.thrust_angle_at(0.5 * dt_s))
            phi[j] = p
            status.append(st)
        if plant is not sc:
            # each true plant has its own shooting functions (a few MB): one episode's only
            release_solvers()
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
                   tail_label_every: int = 1, teacher: str = TEACHERS[0]
                   ) -> dict[str, np.ndarray]:
    """Expert labels for the visited states of planar policy roll-outs.

    ``teacher`` (:data:`TEACHERS`): whose view the expert plans from (:func:`label_chunk`,
    :func:`teacher_view`): ``privileged`` (default), the true states and the lander's true
    plant; ``navigated``, the navigation solutions and the nominal plant. The episodes are
    those of :func:`rollout_policy`.

    Every ``label_every``-th step of each episode and every step in its last ``dense_tail_s``
    seconds (where landing accuracy is decided) is labelled, in time order per episode so the
    expert re-plans warm-started from its previous plan. States slower than ``min_speed_m_s``
    relative to the surface (as the teacher sees them) are not labelled (decision): the env
    cuts the engine within a step there, so the action hardly matters, and from a near-hover
    high above the ground no landing exists — the expert then spends seconds to tens of
    seconds failing to find one (measured: 40 s for one such state)
    before returning its braking fallback.
    After more than two consecutive fallbacks an episode's remaining states are skipped too.
    ``tail_label_every`` thins the dense tail.

    The episodes are labelled in tasks of a few episodes each (:func:`label_chunk`) on the
    executor (``n_workers`` processes; 1: this process). ``cache_dir``: a
    :class:`optimizers.common.executor.ResultStore` there keeps each task's labels as it
    finishes, and tasks already stored are not labelled again (resume within an iteration).

    Returns
    -------
    dict with ``obs`` (L, n_obs) float32, ``actions`` (L, 1) float32, ``phi_rad`` (L,),
    ``status`` (L,) str (the expert's per-label status).

    Raises
    ------
    ValueError
        ``scenario_name`` is not a planar scenario, or ``teacher`` is not one of
        :data:`TEACHERS`.
    """
    from optimizers.common.executor import LocalExecutor, ResultStore, Task, TaskKey, run_tasks

    check_teacher(teacher)
    if not isinstance(get_scenario(scenario_name), PlanarScenario):
        raise ValueError(f"scenario {scenario_name!r} is not a planar scenario: its DAgger data "
                         "comes from its own family (guidance.families.family_of)")
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
        x, thrust_scale, isp_scale = teacher_view(ep, teacher)
        if velocity_ref_m_s is not None:
            speed = np.hypot(x[:, 1], x[:, 0] * x[:, 3]) * float(velocity_ref_m_s)
            sel &= speed >= float(min_speed_m_s)
        # the task gets only the teacher's view (a privileged one as "state_nd" and its plant)
        view = ({"state_nd": x, "thrust_scale": thrust_scale, "isp_scale": isp_scale}
                if teacher == "privileged" else {"navigation_state_nd": x})
        jobs_eps.append({"obs": ep["obs"], "t_s": t, "label_idx": np.flatnonzero(sel),
                         **view})
    n_workers = max(1, min(int(n_workers), len(jobs_eps)))
    # one task per few episodes: the pool balances the load and the bar moves as tasks finish
    per_task = max(1, min(4, len(jobs_eps) // (4 * n_workers) or 1))
    jobs = [{"scenario": scenario_name, "dt_s": dt_s, "teacher": teacher,
             "episodes": jobs_eps[i:i + per_task]}
            for i in range(0, len(jobs_eps), per_task)]
    store = None if cache_dir is None else ResultStore(
        cache_dir, identity={"scenario": scenario_name, "dt_s": float(dt_s),
                             "label_every": int(label_every),
                             "dense_tail_s": float(dense_tail_s),
                             "tail_label_every": int(tail_label_every),
                             "min_speed_m_s": float(min_speed_m_s), "teacher": teacher,
                             "n_episodes": len(jobs_eps), "n_tasks": len(jobs)},
        fmt="pickle")
    tasks = [Task(TaskKey(f"dagger-labels-{scenario_name}", 0, i), label_chunk, (job,))
             for i, job in enumerate(jobs)]
    with LocalExecutor(n_workers if n_workers > 1 else 0) as ex:
        results, _ = run_tasks(tasks, ex, store, progress=(
            f"expert labels ({n_workers} proc)" if progress else False))
    parts = [r for t in tasks for r in results[t.key]]
    if not parts:
        n_obs = episodes[0]["obs"].shape[1] if episodes else 5
        return {"obs": np.zeros((0, n_obs), np.float32),
                "actions": np.zeros((0, 1), np.float32),
                "phi_rad": np.zeros(0), "status": np.zeros(0, dtype="<U12")}
    return {k: np.concatenate([p[k] for p in parts]) for k in ("obs", "actions", "phi_rad",
                                                                "status")}


def planar_dagger_iteration(scenario, request: DaggerRequest
                            ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """One planar DAgger iteration (see :meth:`optimizers.optimum.EnvFamily.
    dagger_iteration`): the policy flies alone (deterministic) from ``n_episodes`` dispersed
    starts (under the request's ``env_kwargs``, e.g. an ``uncertainty`` model), then
    :func:`label_episodes` labels the visited states (settings ``teacher`` (``privileged``,
    the default, or ``navigated``), ``label_every``, ``dense_tail_s``, ``min_label_speed_m_s``
    (default 3 m/s), ``tail_label_every`` (1)). A law spec as ``teacher``
    (:mod:`agents.imitation.teachers`) flies along instead and labels every decision, mixed
    with the policy by the setting ``beta`` (default 0: the policy throughout).

    Raises
    ------
    ValueError
        ``teacher`` is not a teacher (checked before anything is flown).
    """
    dg = request.settings
    choice = parse_teacher(dg.get("teacher"))
    if choice.is_law:
        t0 = time.perf_counter()
        lab, roll = law_dagger_rollouts(
            law_dagger_chunk, request.policy_file, request.load_learner, request.env_id,
            request.env_kwargs, int(request.n_episodes), int(request.seed),
            request.obs_features, float(dg.get("beta", 0.0)), choice,
            n_workers=int(request.n_workers), cache_dir=request.store_dir,
            progress=request.progress, **request.memory_kwargs())
        roll.update(rollout_wall_s=time.perf_counter() - t0, label_wall_s=0.0)
        return lab, roll
    teacher = choice.kind
    t0 = time.perf_counter()
    learner = request.load_learner(request.policy_file, request.env_id, request.env_kwargs,
                                   request.obs_features)
    eps = rollout_policy(learner, request.env_id, request.env_kwargs, int(request.n_episodes),
                         int(request.seed))
    roll = {"rollout_success_rate": float(np.mean([e["success"] for e in eps])),
            "rollout_fuel_mean_kg": float(np.mean([e["fuel_kg"] for e in eps])),
            "rollout_wall_s": time.perf_counter() - t0}
    t0 = time.perf_counter()
    lab = label_episodes(eps, scenario.name, float(_dt_s(request)), int(dg["label_every"]),
                         float(dg["dense_tail_s"]), int(request.n_workers),
                         progress=request.progress,
                         min_speed_m_s=float(dg.get("min_label_speed_m_s", 3.0)),
                         velocity_ref_m_s=scenario.scaling().velocity_m_s,
                         cache_dir=request.store_dir,
                         tail_label_every=int(dg.get("tail_label_every", 1)),
                         teacher=teacher)
    roll["label_wall_s"] = time.perf_counter() - t0
    return lab, roll


def _dt_s(request: DaggerRequest) -> float:
    env = make_env(request.env_id, request.env_kwargs)
    dt_s = float(env.dt_s)
    env.close()
    return dt_s


class PlanarImitation(ImitationFamily):
    """The planar family's imitation recipes."""

    def dataset_recipe(self, scenario, n: int, seed: int, *, n_steps: int, check: str,
                       tol_radius_m: float | None, tol_speed_m_s: float | None,
                       action_noise: float | None) -> DatasetRecipe:
        """See :func:`planar_dataset_recipe`."""
        return planar_dataset_recipe(scenario, n, seed, n_steps=n_steps, check=check,
                                     tol_radius_m=tol_radius_m, tol_speed_m_s=tol_speed_m_s,
                                     action_noise=action_noise)

    def dagger_iteration(self, scenario, request: DaggerRequest
                         ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
        """See :func:`planar_dagger_iteration`."""
        return planar_dagger_iteration(scenario, request)
