"""DAgger teachers: one contract for every env family.

A DAgger run names its teacher with one setting, ``dagger.teacher``, whatever the family:

- ``privileged`` (the default): the family's Pontryagin expert labels every visited state from
  the lander's **true** state (the omniscient feedback law);
- ``navigated``: the same expert labels from the **navigation solution** the student is given
  (a teacher that sees what the student sees; in the nominal world the two coincide);
- a **law spec** (:mod:`guidance.registry`, e.g. ``zem-zev`` or
  ``feedback:thrust_reserve=0.05,terminal_window=1``): that guidance law flies along with every
  episode on the navigation solution, and its actions are the labels
  (:class:`LawRolloutTeacher`). A law that reads the truth (a
  :class:`~guidance.law.PrivilegedLaw`) is refused: ``privileged`` is the family's way to have
  an omniscient teacher.

:func:`parse_teacher` checks a setting before anything is flown. The two built-in kinds are
each family's own (:mod:`.families.planar`, :mod:`.families.pinpoint`); a law teacher's
roll-outs are the same for every family (:func:`law_dagger_rollouts`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from agents.imitation.families import FollowsFlight
from guidance.flight import fly
from guidance.law import GuidanceLaw, Navigation, PrivilegedLaw, actions_of
from optimizers.indirect.pinpoint_feedback import STATUS_FALLBACK, STATUS_STALE

__all__ = ["TEACHER_KINDS", "Teacher", "parse_teacher", "LawRolloutTeacher", "switch_times",
           "law_dagger_chunk", "law_dagger_rollouts", "fly_dagger_rollouts", "SWITCH_MAX_S"]

#: the built-in teachers of every family (setting ``dagger.teacher``; the first is the default)
TEACHER_KINDS = ("privileged", "navigated")
#: statuses of a law's decision without a converged solve (a guess, not a label)
_GUESSES = (STATUS_STALE, STATUS_FALLBACK)
#: DAgger mixing: the teacher flies a mixed episode up to a switch time drawn uniformly in
#: [0, this] (s); 540 s covers the pinpoint descent's braking phase, so the labelled states
#: include the student's own mistakes from every phase of it
SWITCH_MAX_S = 540.0


@dataclass(frozen=True)
class Teacher:
    """A parsed ``dagger.teacher`` setting: a built-in ``kind`` (one of
    :data:`TEACHER_KINDS`) or ``kind == "law"`` with the law's ``spec``."""

    kind: str
    spec: str | None = None

    @property
    def is_law(self) -> bool:
        return self.kind == "law"

    def __str__(self) -> str:
        return self.spec if self.is_law else self.kind


def parse_teacher(value: Any = None) -> Teacher:
    """The teacher a ``dagger.teacher`` setting names (``None``: the default, ``privileged``).

    Raises
    ------
    ValueError
        ``value`` is neither a built-in kind nor a law spec of a registered law; the message
        lists what is allowed. (A law that reads the truth is refused when the roll-outs
        build it: :class:`LawRolloutTeacher`.)
    """
    if value is None:
        return Teacher(TEACHER_KINDS[0])
    if not isinstance(value, str) or not value.strip():
        raise ValueError(f"dagger teacher = {value!r} is not allowed; give one of "
                         f"{', '.join(TEACHER_KINDS)} or a law spec (e.g. 'zem-zev')")
    if value in TEACHER_KINDS:
        return Teacher(value)
    from guidance.registry import parse_law_spec

    try:
        parse_law_spec(value)
    except ValueError as exc:
        raise ValueError(f"dagger teacher = {value!r} is neither one of "
                         f"{', '.join(TEACHER_KINDS)} nor a law spec of a registered law "
                         f"({exc})") from None
    return Teacher("law", value)


def switch_times(n_episodes: int, beta: float, seed: int) -> np.ndarray:
    """Per-episode time (s) at which the student takes over from the teacher (Ross et al.
    2011's β): with probability ``beta`` a time drawn uniformly in [0, :data:`SWITCH_MAX_S`],
    else 0 (the student throughout). Drawn from ``seed`` alone, so a resumed iteration flies
    the same mix.

    Raises
    ------
    ValueError
        ``beta`` outside [0, 1] or ``n_episodes`` < 1.
    """
    if not 0.0 <= float(beta) <= 1.0:
        raise ValueError(f"beta = {beta!r} must be in [0, 1]")
    if int(n_episodes) < 1:
        raise ValueError(f"n_episodes = {n_episodes!r} must be >= 1")
    rng = np.random.default_rng([int(seed), 7])
    n = int(n_episodes)
    return np.where(rng.random(n) < float(beta), rng.uniform(0.0, SWITCH_MAX_S, n), 0.0)


class LawRolloutTeacher(GuidanceLaw):
    """A DAgger roll-out labelled by a guidance law that sees what the student sees (the
    navigation solution; e.g. the window law ``feedback:thrust_reserve=0.05,...``).

    The teacher flies along with every episode, asked at every decision and, where it follows
    the flight (:class:`~agents.imitation.families.FollowsFlight`), told the actions flown, so
    its own memory (a thrust estimate) follows the flight whoever flies it; it flies each episode
    until its switch time and the learner after it. Its actions are the labels, except where
    the law reports (a per-row ``last_status``, as the reserve law does) a decision that is a
    guess, no converged solve ("stale", "fallback"): those are not recorded.

    Parameters
    ----------
    teacher : GuidanceLaw
        Not privileged (the families' ``privileged`` teacher is their own).
    learner : callable or GuidanceLaw
        The policy being trained: ``learner(obs (N, n_obs)) -> actions (N, n_act)``, whose
        labels' inputs are the observations; or, for a student with memory, a guidance law
        with ``last_inputs`` (the inputs it decided on, the labels' inputs) and ``flown`` (told
        the actions flown, the teacher's where it flies), reset with the teacher.
    switch_s : ndarray, shape (N,)
        Per-case episode time (s) at which the learner takes over (0: the learner throughout;
        inf: the teacher throughout).
    """

    name = "DAgger roll-out (same-view law)"

    def __init__(self, teacher: GuidanceLaw, learner, switch_s: np.ndarray) -> None:
        if isinstance(teacher, PrivilegedLaw):
            raise ValueError(f"teacher law {teacher.name!r} reads the truth; a same-view "
                             "teacher must see only the navigation solution")
        self.teacher = teacher
        self.learner = learner
        self.switch_s = np.asarray(switch_s, dtype=np.float64)
        self.records: dict[str, list] = {k: [] for k in ("obs", "actions", "status")}

    def reset(self, computer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self.teacher.reset(computer, case_ids)
        if isinstance(self.learner, GuidanceLaw):
            self.learner.reset(computer, case_ids)

    def act(self, nav: Navigation) -> np.ndarray:
        lab = actions_of(self.teacher.computer, self.teacher.act(nav))
        status = np.asarray(getattr(self.teacher, "last_status", None) or ["law"] * nav.n,
                            dtype="<U12")
        m = np.asarray(nav.active, dtype=bool) & ~np.isin(status, _GUESSES)
        if isinstance(self.learner, GuidanceLaw):  # a student with memory
            pol = actions_of(self.learner.computer, self.learner.act(nav))
            inputs = self.learner.last_inputs
        else:
            pol, inputs = self.learner(nav.obs), nav.obs
        self.records["obs"].append(np.asarray(inputs)[m])
        self.records["actions"].append(lab[m])
        self.records["status"].append(status[m])
        flown = np.where((nav.t_s < self.switch_s)[:, None], lab, pol).astype(np.float32)
        # the teacher's memory must follow what was flown: the window law's thrust estimate,
        # fed its own controls while the student flew, was 8 % off (RMS over 12 student
        # flights; 0.4 % fed the flown ones), so its labels planned with the wrong engine;
        # a student's history, likewise, holds the actions that led to its inputs
        for law in (self.teacher, self.learner):
            if isinstance(law, FollowsFlight):
                law.flown(nav, flown)
        return flown


def law_dagger_chunk(job: dict[str, Any]) -> dict[str, Any]:
    """Executor task: one chunk of DAgger roll-outs labelled by the law ``job["teacher"]``
    (a law spec) flying along (:class:`LawRolloutTeacher`). ``job`` holds ``model``,
    ``load_learner``, ``env_id``, ``env_kwargs``, ``obs_features``, ``seed``, ``n_episodes``,
    ``switch_s``, ``teacher`` and ``history`` (the student's, or None)."""
    import torch as th

    from guidance.registry import LawContext, build_law
    from lunar_env import get_scenario

    th.set_num_threads(1)
    memory = {} if job.get("history") is None else {"history": int(job["history"])}
    learner = job["load_learner"](job["model"], job["env_id"], job["env_kwargs"],
                                  job["obs_features"], **memory)
    switch = np.asarray(job["switch_s"], dtype=np.float64)
    law = build_law(job["teacher"], LawContext(env_id=job["env_id"],
                                               env_kwargs=dict(job["env_kwargs"]),
                                               scenario=get_scenario(job["scenario"])))
    return fly_dagger_rollouts(job, LawRolloutTeacher(law, learner, switch), switch)


def fly_dagger_rollouts(job: dict[str, Any], teacher, switch_s: np.ndarray) -> dict[str, Any]:
    """Fly a chunk's DAgger roll-outs (``job``'s ``env_id``, ``env_kwargs``, ``n_episodes``,
    ``seed``) with ``teacher`` (its ``records`` the labelled samples) switching to the learner
    at ``switch_s``: the samples, concatenated, with each episode's ``success``, ``fuel_kg``,
    ``touchdown_speed_m_s``, ``miss_m`` and ``learner_only`` (switched at the start)."""
    out = fly(job["env_id"], teacher, int(job["n_episodes"]), seed=int(job["seed"]),
              env_kwargs=job["env_kwargs"])
    res = {k: np.concatenate(v) for k, v in teacher.records.items()}
    res.update(success=out.is_success, fuel_kg=out.fuel_used_kg,
               touchdown_speed_m_s=out.touchdown_speed_m_s, miss_m=out.miss_distance_m,
               learner_only=switch_s <= 0.0)
    return res


def law_dagger_rollouts(chunk_fn, model_path, load_learner, env_id: str,
                        env_kwargs: dict[str, Any] | None, n_episodes: int, seed: int,
                        obs_features: list[str] | None, beta: float, teacher: Teacher,
                        n_workers: int = 1, cache_dir=None, progress: bool = True,
                        history: int | None = None, teacher_throughout: bool = False,
                        ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """One DAgger iteration's roll-outs flown in chunks by ``chunk_fn`` (a module-level
    executor task: :func:`law_dagger_chunk` for a law teacher, a family's own for its built-in
    teachers), the teacher flying each episode up to its switch time (:func:`switch_times`)
    and the policy saved at ``model_path`` after it; sub-env i is seeded ``seed + i``.
    ``teacher_throughout``: the teacher flies every episode to its end (Ross et al. 2011's
    first iteration, β₁ = 1), the policy only asked. ``history``: the student's (k decisions,
    loaded by ``load_learner(..., history=k)``); the labels' inputs are then its stacked
    inputs, features included.

    Returns the labels (``obs``, ``actions``, ``status`` and whatever else the chunks record)
    and the roll-outs' figures: the success rate and mean fuel of the policy-only episodes
    (over all when there is none). ``cache_dir``: each chunk's result is kept there (an
    :class:`optimizers.common.executor.ResultStore`) and reused on resume.

    Raises
    ------
    ValueError
        ``beta`` outside [0, 1] or ``n_episodes`` < 1 (before anything is flown).
    """
    from agents.imitation.flights import make_env
    from optimizers.common.executor import LocalExecutor, ResultStore, Task, TaskKey, run_tasks

    switch = switch_times(n_episodes, beta, seed)
    if teacher_throughout:
        switch = np.full(int(n_episodes), np.inf)
    n_workers = max(1, min(int(n_workers), int(n_episodes)))
    bounds = np.linspace(0, int(n_episodes), n_workers + 1).astype(int)
    env = make_env(env_id, env_kwargs)
    scenario = env.scenario.name
    env.close()
    jobs = [{"model": str(model_path), "load_learner": load_learner, "env_id": env_id,
             "env_kwargs": dict(env_kwargs or {}), "obs_features": obs_features,
             "scenario": scenario, "seed": int(seed) + int(lo), "n_episodes": int(hi - lo),
             "switch_s": switch[lo:hi].tolist(), "teacher": str(teacher), "history": history}
            for lo, hi in zip(bounds[:-1], bounds[1:], strict=True) if hi > lo]
    # each chunk's result is stored as it arrives and read back on resume
    store = None if cache_dir is None else ResultStore(
        cache_dir, identity={"model": str(model_path), "env_id": env_id, "seed": int(seed),
                             "n_episodes": int(n_episodes), "beta": float(beta),
                             "teacher": str(teacher),
                             # only where set: the chunks of runs without them keep their key
                             **({"history": int(history)} if history is not None else {}),
                             **({"teacher_throughout": True} if teacher_throughout else {})},
        fmt="pickle")
    tasks = [Task(TaskKey(f"dagger-{env_id}", int(seed), k), chunk_fn, (job,))
             for k, job in enumerate(jobs)]
    with LocalExecutor(n_workers if n_workers > 1 else 0) as ex:
        results, _ = run_tasks(tasks, ex, store, progress=(
            f"DAgger roll-outs + {teacher} labels ({n_workers} proc)" if progress else False))
    parts = [results[t.key] for t in tasks]
    lab = {k: np.concatenate([p[k] for p in parts]) for k in ("obs", "actions", "phi_rad",
                                                               "status") if k in parts[0]}
    succ = np.concatenate([p["success"] for p in parts])
    only = np.concatenate([p["learner_only"] for p in parts]).astype(bool)
    fuel = np.concatenate([p["fuel_kg"] for p in parts])
    sel = only if only.any() else np.ones(len(succ), dtype=bool)  # all mixed: over all
    roll = {"rollout_success_rate": float(np.mean(succ[sel])),
            "rollout_fuel_mean_kg": float(np.mean(fuel[sel])),
            "rollout_policy_only_episodes": float(sel.sum())}
    return lab, roll
