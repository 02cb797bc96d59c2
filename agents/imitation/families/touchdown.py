"""The touchdown family's imitation data (``LunarPinpointLanding-v3``): dataset shards of the
certified optimal landings flown in the env, and DAgger roll-outs labelled by a guidance law.

Dataset (:func:`touchdown_dataset_recipe`): initial states ``scenario.sample_initial(rng, n)``
(normalised), each case's certified optimum (:func:`optimizers.optimum.touchdown.
touchdown_optima`: phased collocation and Pontryagin multi-arc shooting that agree, DOP853
replays within 1 cm and 1 mm/s of the target; cached on disk), flown open loop in the env
(:class:`guidance.laws.touchdown_baselines.TouchdownOpenLoopLaw`): at every decision the
optimum's (α, β, throttle) averaged over the step, the minimum throttle straight up once the
plan has ended. Every decision of that flight is a sample: the observation of the state the
env's replay visits and the action it flew (:data:`TOUCHDOWN_LABEL_RULE`), so a Minari export
(:mod:`agents.imitation.minari_data`) re-flies the dataset's own transitions. ``certified`` =
the optimum is certified and its replay touches down within :data:`TOUCHDOWN_TOLERANCES` of the
target; ``replay_success`` is the env's verdict. The replay holds each action for a step, and
the optimum lands at zero speed with no margin, so the hold's error decides the verdict: over 39
dispersed cases the replay touched down within 0.7 m and 2.4 m/s at 1 s decisions (the env's
success in 77 % of the cases), within 2.7 m and 4.5 m/s at 2 s (72 %), and a success in every
case at 0.5 s and 0.25 s (``--env-kwargs dt_s=0.5``).

DAgger (:func:`touchdown_dagger_iteration`): law teachers only (``dagger.teacher`` a law spec,
e.g. ``zem-zev``: :func:`agents.imitation.teachers.law_dagger_rollouts`). The built-in
``privileged`` and ``navigated`` teachers re-solve the family's optimum from every visited
state, and the certified optimum costs ~0.6-1.2 s a solve from a dispersed start (~5 s from a
mid-flight state, whose throttle structure must be searched again): a DAgger iteration of 40
roll-outs of ~280 decisions would take hours. They are refused with that reason.
"""

from __future__ import annotations

import time
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
from lunar_env.envs.pinpoint_touchdown import OBSERVATION_NAMES as ENV_OBSERVATION_NAMES

__all__ = ["TOUCHDOWN_LABEL_RULE", "TOUCHDOWN_TOLERANCES", "NO_BUILT_IN_TEACHER",
           "touchdown_shard", "touchdown_dataset_recipe",
           "check_touchdown_teacher", "touchdown_dagger_iteration", "TouchdownImitation"]

TOUCHDOWN_LABEL_RULE = ("action_from_controls(the certified optimum's (alpha, beta, throttle) "
                        "averaged over [t_k, t_k + dt_s] while t_k < tf, then the minimum "
                        "throttle straight up) at each state the env's open-loop replay of "
                        "these actions visits")
#: certification of a trajectory: its open-loop replay touches down within this distance of
#: the target (m) and speed (m/s). 100 m is the env's pinpoint radius; 5 m/s a choice above
#: the step hold's error at 1 and 2 s decisions (2.4 and 4.5 m/s at most over 39 dispersed
#: cases) and far below a replay gone wrong (a mislabelled step crashes at tens of m/s)
TOUCHDOWN_TOLERANCES = {"radius_m": 100.0, "speed_m_s": 5.0}
#: why the built-in DAgger teachers are refused (module docstring)
NO_BUILT_IN_TEACHER = (
    "LunarPinpointLanding-v3 has no built-in DAgger teacher: 'privileged' and 'navigated' "
    "re-solve the certified optimum from every visited state, ~1 s a solve (~5 s mid-flight), "
    "hours per iteration; set dagger.teacher to a law spec (e.g. 'zem-zev', which lands v3's "
    "dispersed starts)")


def touchdown_shard(job: dict[str, Any]) -> dict[str, np.ndarray]:
    """Solve (or read from the cache), fly and certify one shard (an executor task; ``job``: see
    :class:`agents.imitation.families.DatasetRecipe`)."""
    from guidance.flight import fly
    from guidance.laws.touchdown_baselines import TouchdownOpenLoopLaw
    from lunar_env.states import moon3d_nd_to_si
    from optimizers.optimum.touchdown import touchdown_optima

    env = make_env(job["env_id"], job["env_kwargs"])
    sc = env.scenario
    n_obs = env.observation_space.shape[0]
    controls_of = env.task.controls_from_actions
    env.close()
    x0 = np.asarray(job["rows"], dtype=np.float64)
    n = len(x0)
    t0 = time.perf_counter()
    optima = touchdown_optima(sc, x0, progress=False)
    ok = np.array([o.success for o in optima], dtype=bool)
    out_fly = fly(job["env_id"], TouchdownOpenLoopLaw(optima), n, seed=0,
                  env_kwargs=job["env_kwargs"], reset_options={"state_nd": x0},
                  record=range(n))
    samples = []
    for i in range(n):
        rec = out_fly.records[i]
        act = np.asarray(rec["action"], dtype=np.float32)
        samples.append({"observations": rec["obs"].astype(np.float32), "actions": act,
                        "t_s": rec["t_s"], "state_nd": rec["state_nd"],
                        "phi_rad": controls_of(act)[:, :2]} if ok[i] else None)
    fuel = np.array([o.fuel_kg for o in optima])
    miss = np.asarray(out_fly.miss_distance_m, dtype=np.float64)
    speed = np.asarray(out_fly.touchdown_speed_m_s, dtype=np.float64)
    rep_fuel = np.where(ok, out_fly.fuel_used_kg, np.nan)
    # a truncated replay has no touchdown speed (NaN): never certified
    cert = ok & (miss <= job["tol_radius_m"]) & (speed <= job["tol_speed_m_s"])
    out: dict[str, Any] = {
        "initial_state_si": moon3d_nd_to_si(x0, sc.scaling()), "solver_success": ok,
        "start_time_s": np.zeros(n), "parent_index": np.full(n, -1, dtype=np.int64),
        "fuel_kg": fuel, "tf_s": np.array([o.tf_s for o in optima]),
        "terminal_error_radius_m": np.where(ok, miss, np.nan),
        "terminal_error_speed_m_s": np.where(ok, speed, np.nan),
        "replay_fuel_kg": rep_fuel, "replay_touchdown_speed_m_s": np.where(ok, speed, np.nan),
        "replay_success": ok & np.asarray(out_fly.is_success, dtype=bool),
        "replay_fuel_gap_kg": rep_fuel - fuel, "certified": cert,
        "solve_wall_s": np.array([o.solve_s for o in optima]),
    }
    collect_samples(out, samples, cert, job["first_index"], n_obs, n_act=3, nx=7, n_angle=2)
    out["wall_s"] = np.array(time.perf_counter() - t0)
    return out


def touchdown_dataset_recipe(scenario, n: int, seed: int, *, n_steps: int, check: str,
                             tol_radius_m: float | None, tol_speed_m_s: float | None,
                             action_noise: float | None) -> DatasetRecipe:
    """The touchdown dataset recipe (module docstring): normalised initial rows (n, 7),
    tolerances on the replay's touchdown (default :data:`TOUCHDOWN_TOLERANCES`). ``n_steps`` /
    ``check`` are not used (the optimum's settings are its own, :data:`optimizers.optimum.
    touchdown.SOLVER_SETTINGS`).

    Raises
    ------
    ValueError
        ``action_noise`` other than None or 0 (the samples are the optimal flights).
    """
    from optimizers.optimum.touchdown import CERTIFIED, SOLVER_SETTINGS

    if action_noise not in (None, 0, 0.0):
        raise ValueError(f"action_noise = {action_noise!r}: LunarPinpointLanding-v3 datasets "
                         "are the certified optimal flights themselves (no noise); omit it")
    s_nd = scenario.scaling()
    rows = np.array([scenario.state_nd(r, scaling=s_nd)
                     for r in scenario.sample_initial(np.random.default_rng(int(seed)), int(n))])
    tol_r = TOUCHDOWN_TOLERANCES["radius_m"] if tol_radius_m is None else float(tol_radius_m)
    tol_v = TOUCHDOWN_TOLERANCES["speed_m_s"] if tol_speed_m_s is None else float(tol_speed_m_s)
    return DatasetRecipe(
        rows=rows, observation_names=list(ENV_OBSERVATION_NAMES), label_rule=TOUCHDOWN_LABEL_RULE,
        initial_states="scenario.sample_initial(rng, n) -> scenario.state_nd "
                       "(initial_state_si: Moon-fixed SI)",
        solver={"name": CERTIFIED, "settings": SOLVER_SETTINGS, "action_noise": 0.0},
        certification={"tol_radius_m": tol_r, "tol_speed_m_s": tol_v,
                       "replay": "the certified optimum flown open loop in the env (each "
                                 "step's mean control): touchdown within the tolerances"},
        shard_fn=touchdown_shard)


def check_touchdown_teacher(teacher) -> None:
    """Refuse the built-in teachers (:data:`NO_BUILT_IN_TEACHER`): ValueError."""
    if not teacher.is_law:
        raise ValueError(f"dagger teacher = {teacher.kind!r} ({', '.join(TEACHER_KINDS)}): "
                         + NO_BUILT_IN_TEACHER)


def touchdown_dagger_iteration(scenario, request: DaggerRequest
                               ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """One DAgger iteration on ``LunarPinpointLanding-v3`` with a law teacher
    (``request.settings["teacher"]``, a law spec) flying along every roll-out
    (:func:`agents.imitation.teachers.law_dagger_rollouts`; ``beta``, default 0.5, the share of
    roll-outs it flies up to a random switch time).

    Raises
    ------
    ValueError
        The teacher is a built-in kind (:data:`NO_BUILT_IN_TEACHER`) or not a law spec.
    """
    choice = parse_teacher(request.settings.get("teacher"))
    check_touchdown_teacher(choice)
    t0 = time.perf_counter()
    lab, roll = law_dagger_rollouts(
        law_dagger_chunk, request.policy_file, request.load_learner, request.env_id,
        request.env_kwargs, int(request.n_episodes), int(request.seed), request.obs_features,
        float(request.settings.get("beta", 0.5)), choice, n_workers=int(request.n_workers),
        cache_dir=request.store_dir, progress=request.progress, **request.memory_kwargs())
    roll["rollout_wall_s"] = time.perf_counter() - t0
    roll["label_wall_s"] = 0.0
    return lab, roll


class TouchdownImitation(ImitationFamily):
    """The touchdown family's imitation recipes (module docstring)."""

    def dataset_recipe(self, scenario, n: int, seed: int, *, n_steps: int, check: str,
                       tol_radius_m: float | None, tol_speed_m_s: float | None,
                       action_noise: float | None) -> DatasetRecipe:
        """See :func:`touchdown_dataset_recipe`."""
        return touchdown_dataset_recipe(scenario, n, seed, n_steps=n_steps, check=check,
                                        tol_radius_m=tol_radius_m,
                                        tol_speed_m_s=tol_speed_m_s, action_noise=action_noise)

    def check_teacher(self, teacher) -> None:
        """See :func:`check_touchdown_teacher`."""
        check_touchdown_teacher(teacher)

    def dagger_iteration(self, scenario, request: DaggerRequest
                         ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
        """See :func:`touchdown_dagger_iteration`."""
        return touchdown_dagger_iteration(scenario, request)
