"""DAgger's data: roll-outs of the current policy and expert labels of the visited states (planar:
:class:`~agents.experts.planar.PontryaginExpert` per state; pinpoint: the feedback expert in
flight).
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from agents.common.law import CallableLaw, Navigation, PrivilegedLaw, Truth
from agents.common.rollout import fly
from agents.experts.pinpoint import PinpointPontryaginExpert
from agents.experts.planar import PontryaginExpert, planar_state_si
from agents.imitation.policy import load_policy_model, policy_inputs
from lunar_env import get_scenario
from lunar_env.envs.soft_landing import action_from_thrust_angle

# ----------------------------------------------------------------------------- DAgger


def rollout_policy(model, env_id: str, env_kwargs: dict[str, Any] | None, n_episodes: int,
                   seed: int, obs_features: list[str] | None = None) -> list[dict[str, Any]]:
    """Fly the policy's deterministic actions from ``n_episodes`` dispersed starts.

    Sub-env i is reset with seed ``seed + i``. Returns one dict per episode: ``obs`` (T, n_obs),
    ``state_nd`` (T, 5), ``t_s`` (T,) — the states at which the policy acted — and the outcome
    ``success``, ``fuel_kg``, ``touchdown_speed_m_s``.
    """
    inputs = policy_inputs(env_id, env_kwargs, obs_features)
    law = CallableLaw(lambda nav: model.predict(inputs(nav.obs), deterministic=True)[0])
    res = fly(env_id, law, n_episodes, seed=seed, env_kwargs=env_kwargs,
              record=range(n_episodes), max_steps=100_000)
    out: list[dict[str, Any]] = []
    for i in range(n_episodes):
        r = res.records[i]
        out.append({"success": bool(res.is_success[i]), "fuel_kg": float(res.fuel_used_kg[i]),
                    "touchdown_speed_m_s": float(res.touchdown_speed_m_s[i]),
                    "obs": r["obs"], "state_nd": r["state_nd"], "t_s": r["t_s"]})
    return out


class DaggerRolloutTeacher(PrivilegedLaw):
    """A pinpoint DAgger roll-out: the Pontryagin feedback expert labels every visited *true*
    state (a privileged teacher), and flies each episode until its switch time; the learner
    flies after it.

    Parameters
    ----------
    expert : PinpointPontryaginExpert
    learner : callable
        ``learner(obs (N, n_obs)) -> actions (N, 2)``: the policy being trained.
    switch_s : ndarray, shape (N,)
        Per-case episode time (s) at which the learner takes over (0: the learner throughout).
    """

    name = "DAgger roll-out"

    def __init__(self, expert, learner, switch_s: np.ndarray) -> None:
        self.expert = expert
        self.learner = learner
        self.switch_s = np.asarray(switch_s, dtype=np.float64)
        self.records: dict[str, list] = {k: [] for k in ("obs", "actions", "phi_rad", "status")}

    def reset(self, computer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self.expert.reset(computer, case_ids)

    def act_privileged(self, nav: Navigation, truth: Truth) -> np.ndarray:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ang, lab, m = self.expert.labels(truth.state_nd, truth.t_s, nav.active)
        st = np.asarray(self.expert.last_status)
        rec = self.records
        rec["obs"].append(np.asarray(nav.obs)[m])
        rec["actions"].append(lab[m])
        rec["phi_rad"].append(ang[m])
        rec["status"].append(st[m].astype("<U12"))
        pol = self.learner(nav.obs)
        return np.where((nav.t_s < self.switch_s)[:, None], lab, pol).astype(np.float32)


def _pinpoint_dagger_chunk(job: dict[str, Any]) -> dict[str, Any]:
    """Fly one chunk of DAgger roll-outs on a pinpoint env and label every visited state with
    the Pontryagin feedback expert (a worker process; see :func:`pinpoint_dagger_rollouts`)."""
    import torch as th

    th.set_num_threads(1)
    model = load_policy_model(job["model"])
    inputs = policy_inputs(job["env_id"], job["env_kwargs"], job["obs_features"])
    switch = np.asarray(job["switch_s"], dtype=np.float64)
    teacher = DaggerRolloutTeacher(
        PinpointPontryaginExpert(get_scenario(job["scenario"])),
        lambda obs: model.predict(inputs(obs), deterministic=True)[0], switch)
    out = fly(job["env_id"], teacher, int(job["n_episodes"]), seed=int(job["seed"]),
              env_kwargs=job["env_kwargs"])
    res = {k: np.concatenate(v) for k, v in teacher.records.items()}
    res.update(success=out.is_success, fuel_kg=out.fuel_used_kg,
               touchdown_speed_m_s=out.touchdown_speed_m_s, miss_m=out.miss_distance_m,
               learner_only=switch <= 0.0)
    return res


def pinpoint_dagger_rollouts(model_path: str | Path, env_id: str,
                             env_kwargs: dict[str, Any] | None, n_episodes: int, seed: int,
                             obs_features: list[str] | None, beta: float, n_workers: int = 1,
                             cache_dir: str | Path | None = None, progress: bool = True
                             ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """One DAgger iteration's data on a pinpoint env: roll-outs of the policy saved at
    ``model_path`` from ``n_episodes`` dispersed starts (sub-env i seeded ``seed + i``), every
    visited state labelled by the Pontryagin feedback expert
    (:class:`agents.experts.pinpoint.PinpointPontryaginExpert`, the extremal from that state).

    Mixing (Ross et al. 2011's β): with probability ``beta`` an episode is flown by the expert
    up to a switch time drawn uniformly in [0, 540] s and by the policy after it, otherwise by
    the policy throughout; so the labelled states include the policy's own mistakes from every
    phase of the descent, not only from the start. The success rate reported is that of the
    policy-only episodes.

    ``cache_dir``: each chunk's labels are kept there (an :class:`optimizers.common.executor.
    ResultStore`) and reused on resume.
    Labels whose solve did not converge (status "stale"/"fallback") are not returned.
    """
    rng = np.random.default_rng([int(seed), 7])
    switch = np.where(rng.random(int(n_episodes)) < float(beta),
                      rng.uniform(0.0, 540.0, int(n_episodes)), 0.0)
    n_workers = max(1, min(int(n_workers), int(n_episodes)))
    bounds = np.linspace(0, int(n_episodes), n_workers + 1).astype(int)
    from agents.imitation.dataset import _make_env

    env = _make_env(env_id, env_kwargs)
    scenario = env.scenario.name
    env.close()
    jobs = [{"model": str(model_path), "env_id": env_id, "env_kwargs": dict(env_kwargs or {}),
             "obs_features": obs_features, "scenario": scenario, "seed": int(seed) + int(lo),
             "n_episodes": int(hi - lo), "switch_s": switch[lo:hi].tolist()}
            for lo, hi in zip(bounds[:-1], bounds[1:], strict=True) if hi > lo]
    from optimizers.common.executor import (
        LocalExecutor,
        ResultStore,
        Task,
        TaskKey,
        run_tasks,
    )

    # each chunk's result is stored as it arrives and read back on resume
    store = None if cache_dir is None else ResultStore(
        cache_dir, identity={"model": str(model_path), "env_id": env_id, "seed": int(seed),
                             "n_episodes": int(n_episodes), "beta": float(beta)},
        fmt="pickle")
    tasks = [Task(TaskKey(f"dagger-{env_id}", int(seed), k), _pinpoint_dagger_chunk, (job,))
             for k, job in enumerate(jobs)]
    with LocalExecutor(n_workers if n_workers > 1 else 0) as ex:
        results, _ = run_tasks(tasks, ex, store, progress=(
            f"DAgger roll-outs + expert labels ({n_workers} proc)" if progress else False))
    parts = [results[t.key] for t in tasks]
    lab = {k: np.concatenate([p[k] for p in parts]) for k in ("obs", "actions", "phi_rad",
                                                               "status")}
    succ = np.concatenate([p["success"] for p in parts])
    only = np.concatenate([p["learner_only"] for p in parts]).astype(bool)
    fuel = np.concatenate([p["fuel_kg"] for p in parts])
    sel = only if only.any() else np.ones(len(succ), dtype=bool)  # all mixed: over all
    roll = {"rollout_success_rate": float(np.mean(succ[sel])),
            "rollout_fuel_mean_kg": float(np.mean(fuel[sel])),
            "rollout_policy_only_episodes": float(sel.sum())}
    return lab, roll


def _label_chunk(job: dict[str, Any]) -> list[dict[str, np.ndarray]]:
    """Label the chosen steps of some episodes with the closed-loop expert (worker process).

    The expert plans from the episodes' recorded *true* states: a privileged teacher, as the
    pinpoint roll-outs' :class:`DaggerRolloutTeacher`."""
    sc = get_scenario(job["scenario"])
    dt_s = float(job["dt_s"])
    res = []
    for ep in job["episodes"]:
        expert = PontryaginExpert(sc)
        idx = ep["label_idx"]
        si = planar_state_si(sc, ep["state_nd"][idx])
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
                   tail_label_every: int = 1) -> dict[str, np.ndarray]:
    """Expert labels for the visited states of policy roll-outs.

    Every ``label_every``-th step of each episode and every step in its last ``dense_tail_s``
    seconds (where landing accuracy is decided) is labelled, in time order per episode so the
    expert re-plans warm-started from its previous plan. States slower than ``min_speed_m_s``
    relative to the surface are not labelled (decision): the env cuts the engine within a step
    there, so the action hardly matters, and from a near-hover high above the ground no landing
    exists — the expert then spends seconds to tens of seconds failing to find one (measured:
    40 s for one such state on the loaded machine) before returning its braking fallback.
    After more than two consecutive fallbacks an episode's remaining states are skipped too.

    ``cache_dir``: each task's labels are written there (``part_<k>.npz``) as it finishes, and
    tasks already there are not labelled again (resume within an iteration).

    ``tail_label_every`` thins the dense tail. Soft landing only: a pinpoint iteration flies
    and labels in one pass (:func:`pinpoint_dagger_rollouts`).

    Returns
    -------
    dict with ``obs`` (L, n_obs) float32, ``actions`` (L, 1) float32, ``phi_rad`` (L,),
    ``status`` (L,) str (the expert's per-label status).
    """
    from agents.imitation.dataset import _is_pinpoint
    from lunar_env import get_scenario

    if _is_pinpoint(get_scenario(scenario_name)):
        raise ValueError(f"scenario {scenario_name!r} is a pinpoint scenario: its DAgger data "
                         "comes from agents.imitation.labelling.pinpoint_dagger_rollouts")
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
        if velocity_ref_m_s is not None:
            x = ep["state_nd"]
            speed = np.hypot(x[:, 1], x[:, 0] * x[:, 3]) * float(velocity_ref_m_s)
            sel &= speed >= float(min_speed_m_s)
        jobs_eps.append({"obs": ep["obs"], "state_nd": ep["state_nd"], "t_s": t,
                         "label_idx": np.flatnonzero(sel)})
    n_workers = max(1, min(int(n_workers), len(jobs_eps)))
    # one task per few episodes: the pool balances the load and the bar moves as tasks finish
    per_task = max(1, min(4, len(jobs_eps) // (4 * n_workers) or 1))
    jobs = [{"scenario": scenario_name, "dt_s": dt_s, "episodes": jobs_eps[i:i + per_task]}
            for i in range(0, len(jobs_eps), per_task)]
    n_labels = sum(len(e["label_idx"]) for e in jobs_eps)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=n_labels, desc=f"expert labels ({n_workers} proc)", unit="label")
    results: list[list[dict[str, np.ndarray]] | None] = [None] * len(jobs)
    cache = Path(cache_dir) if cache_dir is not None else None
    keys = ("obs", "actions", "phi_rad", "status")

    def _part(i: int) -> Path:
        return cache / f"part_{i:04d}.npz"

    def _keep(i: int, res: list[dict[str, np.ndarray]]) -> None:
        results[i] = res
        if cache is not None:
            cache.mkdir(parents=True, exist_ok=True)
            tmp = _part(i).with_suffix(".tmp.npz")
            np.savez(tmp, n=np.array(len(res)),
                     **{f"{k}_{e}": r[k] for e, r in enumerate(res) for k in keys})
            os.replace(tmp, _part(i))
        if bar is not None:
            bar.update(sum(len(e["label_idx"]) for e in jobs[i]["episodes"]))

    todo = []
    for i in range(len(jobs)):
        if cache is not None and _part(i).exists():
            try:
                with np.load(_part(i)) as z:
                    results[i] = [{k: z[f"{k}_{e}"] for k in keys} for e in range(int(z["n"]))]
            except Exception as exc:  # a damaged cache part: label those episodes again
                print(f"label cache {_part(i)} is damaged ({type(exc).__name__}); relabelling")
                todo.append(i)
                continue
            if bar is not None:
                bar.update(sum(len(e["label_idx"]) for e in jobs[i]["episodes"]))
        else:
            todo.append(i)
    try:
        if n_workers == 1:
            for i in todo:
                _keep(i, _label_chunk(jobs[i]))
        else:
            from concurrent.futures import as_completed

            from agents.common.runs import process_pool

            with process_pool(n_workers) as ex:  # workers end with this process
                futs = {ex.submit(_label_chunk, jobs[i]): i for i in todo}
                for fut in as_completed(futs):
                    _keep(futs[fut], fut.result())
    finally:
        if bar is not None:
            bar.close()
    parts = [r for rs in results if rs for r in rs]
    if not parts:
        n_obs = episodes[0]["obs"].shape[1] if episodes else 5
        return {"obs": np.zeros((0, n_obs), np.float32),
                "actions": np.zeros((0, 1), np.float32),
                "phi_rad": np.zeros(0), "status": np.zeros(0, dtype="<U12")}
    return {k: np.concatenate([p[k] for p in parts]) for k in ("obs", "actions", "phi_rad",
                                                                "status")}
