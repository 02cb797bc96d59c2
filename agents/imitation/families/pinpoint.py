"""The pinpoint family's imitation data: dataset shards from the Pontryagin feedback expert's
own (noisy) flights, and DAgger roll-outs labelled in flight by the same expert or by a
guidance law (``dagger.teacher``, :mod:`agents.imitation.teachers`) (what
:meth:`guidance.families.pinpoint.PinpointFamily.dataset_recipe` and
:meth:`~guidance.families.pinpoint.PinpointFamily.dagger_iteration` answer).

No open-loop solution can be sampled on the pinpoint env (the optimum held over 1 s env steps
misses the gate by ~10 m/s, and a clone of the optimal trajectories alone drifts off them), so
the samples come from the **feedback expert's own closed-loop flights**
(:func:`pinpoint_expert_flights`): at every decision the minimum-fuel extremal is re-solved
from the visited state (~1-15 ms), the label is its law averaged over the step, and the env is
flown with that action plus Gaussian noise (default :data:`PINPOINT_ACTION_NOISE`), so the
states cover the tube a learner visits. Per trajectory, ``fuel_kg`` / ``tf_s`` are the extremal
from the initial state (the per-case optimum) and ``replay_*`` the noisy flight; ``certified``
= that flight is the env's success within the tolerances (default: the env's, 5 m/s and
500 m) and the first solve converged.
"""

from __future__ import annotations

import time
import warnings
from typing import Any

import numpy as np

from agents.imitation.families import DaggerRequest, DatasetRecipe, ImitationFamily
from agents.imitation.flights import collect_samples, make_env
from agents.imitation.teachers import (
    TEACHER_KINDS,
    fly_dagger_rollouts,
    law_dagger_chunk,
    law_dagger_rollouts,
    parse_teacher,
)
from guidance.flight import fly
from guidance.law import Navigation, PrivilegedLaw, Truth
from guidance.laws.pontryagin_pinpoint import PinpointPontryaginExpert
from lunar_env import get_scenario

__all__ = ["PINPOINT_LABEL_RULE", "PINPOINT_TOLERANCES", "PINPOINT_ACTION_NOISE",
           "OBSERVATION_NAMES", "ExpertFlightTeacher", "pinpoint_expert_flights",
           "pinpoint_shard", "pinpoint_dataset_recipe", "DaggerRolloutTeacher",
           "expert_dagger_chunk", "pinpoint_dagger_rollouts", "pinpoint_dagger_iteration"]

PINPOINT_LABEL_RULE = ("action_from_angles(mean of the extremal's (alpha*, beta*) over "
                       "[t_k, t_k + dt_s]) at each state visited by the Pontryagin feedback "
                       "expert's own flight, flown with Gaussian action noise (DART)")
#: pinpoint certification: the expert's (noisy) flight is the env's success and lands within
#: these gate miss / gate speed (default: the env's own success tolerances)
PINPOINT_TOLERANCES = {"radius_m": 500.0, "speed_m_s": 5.0}
#: standard deviation of the action noise of the expert's flights (action units; 0.02 = 0.9°
#: of α or β). Measured (50 flights at 1 s decisions): the noisy expert still lands 98 % (gate
#: speed median 1.2 m/s, miss median 20 m) and its states cover the tube a clone visits; a
#: clone trained on noise-free flights drifts 1-10 km from them.
PINPOINT_ACTION_NOISE = 0.02
OBSERVATION_NAMES = ["altitude/h0", "d_radial/d0", "d_along/d0", "d_cross/d0", "u/(0.1 v0)",
                     "v/v0", "w/(0.1 v0)", "propellant/nominal", "t/time_limit"]


# --------------------------------------------------------------------------------- dataset


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
        n_angles = lab.shape[1]
        # the constant-thrust expert's action on the env's engine (a throttle channel at +1)
        lab = self.computer.actions_from_controls(np.c_[ang, np.ones(len(ang))])
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
        noise = 0.0
        if self.action_noise > 0:
            noise = self.rng.normal(0.0, self.action_noise, lab.shape)
            # on the angles only: clipped at full thrust, noise on a throttle channel would
            # only ever weaken the engine (measured: a 1.55 km miss at 2 s decisions)
            noise[:, n_angles:] = 0.0
        return np.clip(lab + noise, -1.0, 1.0).astype(np.float32)


def pinpoint_expert_flights(rows_nd: np.ndarray, env_id: str,
                            env_kwargs: dict[str, Any] | None, action_noise: float,
                            rng: np.random.Generator) -> dict[str, Any]:
    """Fly the Pontryagin feedback expert from each normalised initial state (n, 7) and label
    every visited state with its clean action (DART: Laskey et al. 2017).

    The expert (:class:`guidance.laws.pontryagin_pinpoint.PinpointPontryaginExpert`) re-solves the
    minimum-fuel extremal from the lander's state at every decision; the env is flown with its
    action plus Gaussian noise of standard deviation ``action_noise`` (action units; 0.02 ≈
    0.9°), so the visited states spread around the optimal trajectory the way a learner's do,
    while every label stays the expert's optimal action there (:data:`PINPOINT_LABEL_RULE`).
    Labels whose solve did not converge (status "stale"/"fallback") are dropped.

    Returns per case: ``samples`` (list of dicts ``observations``, ``actions``, ``t_s``,
    ``state_nd``, ``phi_rad``, ``status``, or None without a label), the flight's ``success``,
    ``touchdown_speed_m_s``, ``miss_m``, ``fuel_kg``; ``optimum_fuel_kg`` / ``optimum_tf_s`` of
    the extremal from the initial state (the per-case optimum; NaN if that first solve failed);
    ``wall_s``; ``status_counts``.
    """
    env = make_env(env_id, env_kwargs)
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


def pinpoint_shard(job: dict[str, Any]) -> dict[str, np.ndarray]:
    """Fly, label and certify one pinpoint shard (an executor task; ``job``: see
    :class:`optimizers.optimum.DatasetRecipe`, plus ``action_noise``); its noise is seeded
    ``(seed, k)``."""
    from lunar_env.states import moon3d_nd_to_si

    env = make_env(job["env_id"], job["env_kwargs"])
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
    collect_samples(out, samples, cert, job["first_index"], n_obs, n_act=2, nx=7, n_angle=2)
    out["wall_s"] = np.array(time.perf_counter() - t0)
    return out


def pinpoint_dataset_recipe(scenario, n: int, seed: int, *, n_steps: int, check: str,
                            tol_radius_m: float | None, tol_speed_m_s: float | None,
                            action_noise: float | None) -> DatasetRecipe:
    """The pinpoint dataset recipe (see :meth:`optimizers.optimum.EnvFamily.
    dataset_recipe`): normalised initial rows (n, 7), tolerances on the gate miss / speed of
    the expert's own flight (default :data:`PINPOINT_TOLERANCES`), action noise (default
    :data:`PINPOINT_ACTION_NOISE`). ``n_steps`` / ``check`` are not used (no open-loop solve).

    Raises
    ------
    ValueError
        ``action_noise`` negative or not finite.
    """
    s_nd = scenario.scaling()
    rows = np.array([scenario.state_nd(r, scaling=s_nd)
                     for r in scenario.sample_initial(np.random.default_rng(int(seed)), int(n))])
    tol_r = PINPOINT_TOLERANCES["radius_m"] if tol_radius_m is None else tol_radius_m
    tol_v = PINPOINT_TOLERANCES["speed_m_s"] if tol_speed_m_s is None else tol_speed_m_s
    noise = PINPOINT_ACTION_NOISE if action_noise is None else float(action_noise)
    if not (np.isfinite(noise) and noise >= 0.0):
        raise ValueError(f"action_noise = {noise!r} must be finite and >= 0")
    return DatasetRecipe(
        rows=rows, observation_names=list(OBSERVATION_NAMES), label_rule=PINPOINT_LABEL_RULE,
        initial_states="scenario.sample_initial(rng, n) -> scenario.state_nd "
                       "(initial_state_si: Moon-fixed SI)",
        solver={"name": "guidance.laws.pontryagin_pinpoint.PinpointPontryaginExpert (the "
                        "minimum-fuel "
                        "extremal from every visited state, optimizers.indirect."
                        "pinpoint_feedback)", "action_noise": noise},
        certification={"tol_radius_m": tol_r, "tol_speed_m_s": tol_v,
                       "replay": "the expert's own flight (with the action noise): is_success "
                                 "and gate miss / speed within the tolerances"},
        shard_fn=pinpoint_shard, job_args={"action_noise": noise})


# --------------------------------------------------------------------------------- DAgger


class DaggerRolloutTeacher(PrivilegedLaw):
    """A pinpoint DAgger roll-out labelled by the Pontryagin feedback expert (the extremal
    from every visited state), which flies each episode until its switch time; the learner
    flies after it.

    Parameters
    ----------
    expert : PinpointPontryaginExpert
    learner : callable
        ``learner(obs (N, n_obs)) -> actions (N, 2)``: the policy being trained.
    switch_s : ndarray, shape (N,)
        Per-case episode time (s) at which the learner takes over (0: the learner throughout).
    view : str
        ``"privileged"``: the expert plans from the *true* state; ``"navigated"``: from the
        navigation solution the student is given (:data:`agents.imitation.teachers.
        TEACHER_KINDS`).
    """

    name = "DAgger roll-out"

    def __init__(self, expert, learner, switch_s: np.ndarray,
                 view: str = "privileged") -> None:
        if view not in TEACHER_KINDS:
            raise ValueError(f"view = {view!r} is not allowed; choose one of {TEACHER_KINDS}")
        self.expert = expert
        self.learner = learner
        self.switch_s = np.asarray(switch_s, dtype=np.float64)
        self.view = view
        self.records: dict[str, list] = {k: [] for k in ("obs", "actions", "phi_rad", "status")}

    def reset(self, computer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self.expert.reset(computer, case_ids)

    def act_privileged(self, nav: Navigation, truth: Truth) -> np.ndarray:
        state = truth.state_nd if self.view == "privileged" else nav.state_nd
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ang, lab, m = self.expert.labels(state, truth.t_s, nav.active)
        lab = self.computer.actions_from_controls(np.c_[ang, np.ones(len(ang))])
        st = np.asarray(self.expert.last_status)
        rec = self.records
        rec["obs"].append(np.asarray(nav.obs)[m])
        rec["actions"].append(lab[m])
        rec["phi_rad"].append(ang[m])
        rec["status"].append(st[m].astype("<U12"))
        pol = self.learner(nav.obs)
        return np.where((nav.t_s < self.switch_s)[:, None], lab, pol).astype(np.float32)


def expert_dagger_chunk(job: dict[str, Any]) -> dict[str, Any]:
    """Executor task: one chunk of pinpoint DAgger roll-outs labelled by the Pontryagin
    feedback expert (``job["teacher"]``: ``privileged`` or ``navigated``;
    :func:`agents.imitation.teachers.law_dagger_rollouts` makes the jobs)."""
    import torch as th

    th.set_num_threads(1)
    learner = job["load_learner"](job["model"], job["env_id"], job["env_kwargs"],
                                  job["obs_features"])
    switch = np.asarray(job["switch_s"], dtype=np.float64)
    teacher = DaggerRolloutTeacher(PinpointPontryaginExpert(get_scenario(job["scenario"])),
                                   learner, switch, view=job["teacher"])
    return fly_dagger_rollouts(job, teacher, switch)


def pinpoint_dagger_rollouts(model_path, load_learner, env_id: str,
                             env_kwargs: dict[str, Any] | None, n_episodes: int, seed: int,
                             obs_features: list[str] | None, beta: float, n_workers: int = 1,
                             cache_dir=None, progress: bool = True,
                             teacher: str | None = None, history: int | None = None,
                             teacher_throughout: bool = False
                             ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """One DAgger iteration's data on a pinpoint env: roll-outs of the policy saved at
    ``model_path`` (loaded in each task by the module-level ``load_learner``, see
    :class:`agents.imitation.families.DaggerRequest`) from ``n_episodes`` dispersed starts
    (sub-env i seeded ``seed + i``), every visited state labelled by ``teacher``
    (:func:`agents.imitation.teachers.parse_teacher`): the Pontryagin feedback expert
    (:class:`guidance.laws.pontryagin_pinpoint.PinpointPontryaginExpert`) from the true state
    (``privileged``, the default) or the navigation solution (``navigated``), or a guidance
    law flying along on the navigation solution (a law spec, e.g. the terminal-window law).

    Mixing (Ross et al. 2011's β): with probability ``beta`` an episode is flown by the
    teacher up to a switch time drawn uniformly in [0, 540] s and by the policy after it,
    otherwise by the policy throughout (:func:`agents.imitation.teachers.switch_times`).
    Labels whose solve did not converge (status "stale"/"fallback") are not returned.
    ``history`` and ``teacher_throughout``: a student with memory and the teacher flying
    every episode (:func:`agents.imitation.teachers.law_dagger_rollouts`; law teachers only).

    Raises
    ------
    ValueError
        ``beta`` outside [0, 1], ``n_episodes`` < 1, ``teacher`` not a teacher, or a
        ``history`` with a built-in teacher (before anything is flown).
    """
    choice = parse_teacher(teacher)
    if not choice.is_law and (history is not None or teacher_throughout):
        raise ValueError(f"dagger teacher = {choice.kind!r}: a student with a history "
                         f"(history={history!r}) learns from a law teacher only (a law spec, "
                         "e.g. 'zem-zev')")
    return law_dagger_rollouts(law_dagger_chunk if choice.is_law else expert_dagger_chunk,
                               model_path, load_learner, env_id, env_kwargs, n_episodes, seed,
                               obs_features, beta, choice, n_workers=n_workers,
                               cache_dir=cache_dir, progress=progress, history=history,
                               teacher_throughout=teacher_throughout)


def pinpoint_dagger_iteration(scenario, request: DaggerRequest
                              ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """One pinpoint DAgger iteration (see :meth:`optimizers.optimum.EnvFamily.
    dagger_iteration`): :func:`pinpoint_dagger_rollouts` with the setting ``beta`` (default
    0.5); flying and labelling are one pass (``label_wall_s`` = 0, all in ``rollout_wall_s``)."""
    t0 = time.perf_counter()
    lab, roll = pinpoint_dagger_rollouts(
        request.policy_file, request.load_learner, request.env_id, request.env_kwargs,
        int(request.n_episodes), int(request.seed), request.obs_features,
        float(request.settings.get("beta", 0.5)), int(request.n_workers),
        cache_dir=request.store_dir, progress=request.progress,
        teacher=request.settings.get("teacher"), **request.memory_kwargs())
    roll["rollout_wall_s"] = time.perf_counter() - t0
    roll["label_wall_s"] = 0.0
    return lab, roll


class PinpointImitation(ImitationFamily):
    """The pinpoint family's imitation recipes."""

    def dataset_recipe(self, scenario, n: int, seed: int, *, n_steps: int, check: str,
                       tol_radius_m: float | None, tol_speed_m_s: float | None,
                       action_noise: float | None) -> DatasetRecipe:
        """See :func:`pinpoint_dataset_recipe`."""
        return pinpoint_dataset_recipe(scenario, n, seed, n_steps=n_steps, check=check,
                                       tol_radius_m=tol_radius_m, tol_speed_m_s=tol_speed_m_s,
                                       action_noise=action_noise)

    def dagger_iteration(self, scenario, request: DaggerRequest
                         ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
        """See :func:`pinpoint_dagger_iteration`."""
        return pinpoint_dagger_iteration(scenario, request)
