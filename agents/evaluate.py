"""Compare policies with the optimiser baselines over one seeded set of dispersed initial states.

::

    python -m agents.evaluate --model runs/ppo/LunarSoftLanding-v0_1          # + baselines
    python -m agents.evaluate --model a/model.zip --model b/ --n-states 200 --out results/cmp
    python -m agents.evaluate --no-open-loop --expert-states 0 --model runs/ppo/...

Every policy flies the **same** initial states: the native vector env is reset with one seed,
and sub-env ``i`` draws its initial state with seed ``seed + i`` (the Gymnasium vector-env
convention the env follows), so case ``i`` is the same for every policy and for any batch size
that contains it. For each case the per-case optimum (minimum fuel, Pontryagin indirect shooting,
:func:`optimizers.indirect.batch.solve_many`) is computed from the very initial state the env drew.

Policies
--------
- ``SB3Policy``: a trained Stable-Baselines3 model with its ``VecNormalize`` statistics,
  deterministic actions, all landers in one batched forward pass.
- ``OpenLoopPolicy``: replay of the per-case optimal control history φ(t) (sampled at the
  middle of each env step, held over the step as the env holds every action).
- ``ExpertPolicy``: the closed-loop re-planning expert (:class:`agents.experts.
  PontryaginExpert`), which re-solves from the current state. It costs a solve per decision, so
  by default it flies only the first ``--expert-states`` cases (its fuel gap is measured on
  those cases' optima).

Metrics (one row per policy)
----------------------------
- ``success_rate``: touchdown with the env's success criterion (``info["is_success"]``);
- ``touchdown_speed_m_s`` mean and 95th percentile over cases that touched down;
- ``miss_distance_m`` mean (pinpoint env only);
- ``fuel_kg`` mean over all cases; ``fuel_gap_pct``: mean over *successful* cases of
  100·(fuel − optimal fuel)/optimal fuel (decision: a crash can use less fuel than the optimum,
  so averaging over failures would reward them; the all-case gap is in the JSON too);
- ``us_per_decision``: wall time of the policy's action computation divided by the number of
  decisions of landers still flying (batched policies amortise one forward pass over the
  batch; the expert's time is one re-plan per decision).

Outputs: a Markdown table (printed and ``comparison.md``), ``comparison.json`` and
``trajectories.png`` (trajectory and thrust angle of each policy beside the optimum for a few
cases) in the output directory.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from agents.rollout import fly, make_vec
from lunar_env.states import planar_nd_to_si

__all__ = ["Policy", "SB3Policy", "OpenLoopPolicy", "ExpertPolicy", "PolicyResult",
           "initial_states", "rollout", "optimal_solutions", "compare", "markdown_table",
           "plot_comparison", "evaluate_run", "publish_report", "main"]

DEFAULT_ENV_ID = "LunarSoftLanding-v0"
DEFAULT_N_STATES = 1000
DEFAULT_SEED = 2026
DEFAULT_EXPERT_STATES = 20
PINPOINT_EXPERT_STATES = 5
#: cases flown by the Pontryagin feedback expert after training (~1 ms per decision and case;
#: it lands every case at the optimum's fuel, so its row needs no more)
PINPOINT_FEEDBACK_STATES = 200


# ----------------------------------------------------------------------------- env helpers


def _core(venv):
    return getattr(venv, "unwrapped", venv)


def _is_planar(venv) -> bool:
    return np.asarray(_core(venv).state_nd).shape[1] == 5


def planar_state_si(scenario, state_nd: np.ndarray) -> np.ndarray:
    """Normalised planar states (r, vr, θ, ω, m) -> SI rows (r m, vr m/s, θ rad, v_t m/s, m kg)
    (:func:`lunar_env.states.planar_nd_to_si` with the scenario's scaling)."""
    return planar_nd_to_si(state_nd, scenario.scaling())


def initial_states(env_id: str, n: int, seed: int, env_kwargs: dict[str, Any] | None = None
                   ) -> np.ndarray:
    """The normalised initial states (n, nx) of cases ``0..n-1`` for ``seed``."""
    venv = make_vec(env_id, n, env_kwargs)
    try:
        venv.reset(seed=seed)
        return np.array(_core(venv).state_nd, dtype=np.float64, copy=True)
    finally:
        venv.close()


# ----------------------------------------------------------------------------- policies


class Policy(Protocol):
    """A batched policy: ``reset`` at episode start, then ``act`` once per env step."""

    name: str

    def reset(self, venv, case_ids: np.ndarray) -> None: ...

    def act(self, obs: np.ndarray, venv) -> np.ndarray: ...


class SB3Policy:
    """A trained SB3 model with its ``VecNormalize`` observation statistics.

    Parameters
    ----------
    model : BaseAlgorithm
    vecnormalize : VecNormalize or str or Path or None
        Statistics (or the ``.pkl`` written by ``VecNormalize.save``); ``None`` if the model was
        trained without normalisation.
    name : str
    obs_features : list of str, optional
        Derived observation features the model was trained with (:mod:`agents.features`, the
        run's ``obs_features``); appended to the env's observations before normalisation, as
        in training.
    """

    def __init__(self, model, vecnormalize=None, name: str = "PPO",
                 obs_features: list[str] | None = None) -> None:
        import pickle

        from agents.features import validate_features

        self.model = model
        self.name = name
        if isinstance(vecnormalize, str | Path):
            with open(vecnormalize, "rb") as fh:
                vecnormalize = pickle.load(fh)
        self.vecnormalize = vecnormalize
        self.obs_features = validate_features(obs_features)
        self._feature_consts = None

    @classmethod
    def from_path(cls, path: str | Path, name: str | None = None) -> SB3Policy:
        """Load from a run directory or model ``.zip`` (see :func:`agents.runs.load_trained`)."""
        from agents.runs import load_trained, read_run

        model, vn_path, algo = load_trained(path)
        hp = read_run(path)[1]
        return cls(model, vn_path, name=name or algo.upper(), obs_features=hp.get("obs_features"))

    def reset(self, venv, case_ids: np.ndarray) -> None:
        if self.obs_features:
            from agents.features import feature_constants

            self._feature_consts = feature_constants(_core(venv))

    def act(self, obs: np.ndarray, venv) -> np.ndarray:
        if self.obs_features:
            from agents.features import augment_observation, feature_constants

            if self._feature_consts is None:
                self._feature_consts = feature_constants(_core(venv))
            obs = augment_observation(obs, self._feature_consts, self.obs_features)
        if self.vecnormalize is not None:
            obs = self.vecnormalize.normalize_obs(obs)
        action, _ = self.model.predict(obs, deterministic=True)
        return action


def _thrust_angle_to_action(venv, phi_rad: np.ndarray) -> np.ndarray:
    from lunar_env.envs.soft_landing import action_from_thrust_angle

    return np.asarray(action_from_thrust_angle(phi_rad), dtype=np.float32).reshape(-1, 1)


class OpenLoopPolicy:
    """Replay of per-case optimal control histories φ(t) (planar env).

    The env holds each action for ``dt_s``; the replay samples φ at the middle of the step
    (a second-order accurate hold of a smooth control). After the optimal final time the last
    value is held.

    Parameters
    ----------
    solutions : sequence of PontryaginSolution
        One per case (indexed by case id), with ``thrust_angle_at(t_s)`` (times clipped to
        [0, tf]: the last optimal angle is held after tf). Cases whose solve failed fly φ = 0
        (a braking burn) and are reported like any other case.
    """

    name = "Pontryagin open loop"

    def __init__(self, solutions) -> None:
        self.solutions = list(solutions)
        self._ids = np.zeros(0, dtype=int)

    def reset(self, venv, case_ids: np.ndarray) -> None:
        self._ids = np.asarray(case_ids)

    def act(self, obs: np.ndarray, venv) -> np.ndarray:
        core = _core(venv)
        t_mid = np.asarray(core.t_s, dtype=np.float64) + 0.5 * float(core.dt_s)
        phi = np.zeros(len(self._ids))
        for k, cid in enumerate(self._ids):
            sol = self.solutions[cid]
            if sol.success:
                phi[k] = sol.thrust_angle_at(float(t_mid[k]))
        return _thrust_angle_to_action(venv, phi)


class ExpertPolicy:
    """Closed-loop re-planning expert: re-solves the optimal control from every current state.

    Wraps :class:`agents.experts.PontryaginExpert` (planar env): one expert per case, so
    each re-plan is warm-started from that case's previous plan, called once per decision of a
    lander still flying with its SI state and the time since the start of its episode.
    """

    name = "Pontryagin re-planning"

    def __init__(self, scenario, **expert_kwargs) -> None:
        self.scenario = scenario
        self.expert_kwargs = expert_kwargs
        self.experts: list = []
        self.active: np.ndarray | None = None

    def reset(self, venv, case_ids: np.ndarray) -> None:
        from agents.experts import PontryaginExpert

        self.experts = [PontryaginExpert(self.scenario, **self.expert_kwargs)
                        for _ in range(len(case_ids))]
        self.active = None

    def act(self, obs: np.ndarray, venv) -> np.ndarray:
        core = _core(venv)
        si = planar_state_si(self.scenario, np.asarray(core.state_nd))
        t_s = np.asarray(core.t_s, dtype=np.float64)
        phi = np.zeros(len(si))
        for k in range(len(si)):
            if self.active is None or self.active[k]:
                phi[k] = float(self.experts[k](si[k], t_s=float(t_s[k])))
        return _thrust_angle_to_action(venv, phi)


# ----------------------------------------------------------------------------- rollout


@dataclass
class PolicyResult:
    """Per-case outcome of one policy (arrays of length n_cases)."""

    name: str
    case_ids: np.ndarray
    is_success: np.ndarray
    touchdown_speed_m_s: np.ndarray
    miss_distance_m: np.ndarray
    fuel_used_kg: np.ndarray
    episode_time_s: np.ndarray
    n_decisions: int
    policy_wall_s: float
    traces: dict[int, dict[str, np.ndarray]] = field(default_factory=dict)

    @property
    def us_per_decision(self) -> float:
        return 1e6 * self.policy_wall_s / max(self.n_decisions, 1)


def rollout(env_id: str, policy: Policy, n: int, seed: int,
            env_kwargs: dict[str, Any] | None = None, trace_cases: int = 3,
            max_steps: int | None = None) -> PolicyResult:
    """Fly ``policy`` from cases ``0..n-1`` (one batched vector env) until every case ended.

    Parameters
    ----------
    env_id : str
    policy : Policy
    n : int
        Number of cases.
    seed : int
        Seed of the case set (case i = sub-env seeded ``seed + i``).
    env_kwargs : dict, optional
        Passed to the env (must match those used in training).
    trace_cases : int
        Record state and action histories of the first ``trace_cases`` cases for plots.
    max_steps : int, optional
        Safety bound on the number of vector steps (default: the env's time limit / dt + 10).

    Returns
    -------
    PolicyResult
    """
    def act(obs, venv, active):
        if hasattr(policy, "active"):
            policy.active = active  # lets a costly policy skip finished landers
        return policy.act(obs, venv)

    out = fly(env_id, act, n, seed=seed, env_kwargs=env_kwargs, record=range(trace_cases),
              record_final=True, max_steps=max_steps,
              on_reset=lambda venv: policy.reset(venv, np.arange(n)), name=policy.name)
    traces = {i: {"t_s": r["t_s"], "state_nd": r["state_nd"], "action": r["action"]}
              for i, r in out.records.items()}
    return PolicyResult(policy.name, np.arange(n), out.is_success, out.touchdown_speed_m_s,
                        out.miss_distance_m, out.fuel_used_kg, out.episode_time_s,
                        out.n_decisions, out.policy_wall_s, traces)


# ----------------------------------------------------------------------------- optimum


def optimal_solutions(scenario, states_nd: np.ndarray, progress: bool = True, executor=None):
    """Per-case minimum-fuel solutions (Pontryagin) from normalised planar initial states.

    ``executor`` (:mod:`optimizers.common.executor`, e.g. a Ray cluster) solves chunks of the
    warm-start chain in parallel; default: this process.

    Returns
    -------
    fuel_kg : ndarray (n,)
        Optimal fuel per case (NaN where the solver did not converge).
    solutions : list of PontryaginSolution
    wall_s : float
    """
    from optimizers.indirect.batch import solve_many

    states_si = planar_state_si(scenario, states_nd)
    t0 = time.perf_counter()
    sols = solve_many(scenario, states_si, progress=progress, executor=executor)
    wall = time.perf_counter() - t0
    fuel = np.array([s.fuel_kg if s.success else np.nan for s in sols], dtype=np.float64)
    return fuel, list(sols), wall


# ----------------------------------------------------------------------------- comparison


def _summary(res: PolicyResult, opt_fuel: np.ndarray | None,
             opt_tf: np.ndarray | None = None) -> dict[str, Any]:
    td = np.isfinite(res.touchdown_speed_m_s)
    row: dict[str, Any] = {
        "policy": res.name,
        "n_cases": int(len(res.case_ids)),
        "success_rate": float(np.mean(res.is_success)),
        "touchdown_rate": float(np.mean(td)),
        "touchdown_speed_mean_m_s": float(np.mean(res.touchdown_speed_m_s[td])) if td.any()
        else float("nan"),
        "touchdown_speed_p95_m_s": float(np.percentile(res.touchdown_speed_m_s[td], 95))
        if td.any() else float("nan"),
        "miss_distance_mean_m": float(np.nanmean(res.miss_distance_m))
        if np.isfinite(res.miss_distance_m).any() else float("nan"),
        "fuel_mean_kg": float(np.nanmean(res.fuel_used_kg)),
        "us_per_decision": float(res.us_per_decision),
        "n_decisions": int(res.n_decisions),
        "policy_wall_s": float(res.policy_wall_s),
    }
    gap_s = gap_all = float("nan")
    n_gap = 0
    if opt_fuel is not None:
        opt = opt_fuel[res.case_ids]
        ok = np.isfinite(opt) & np.isfinite(res.fuel_used_kg)
        gap = 100.0 * (res.fuel_used_kg - opt) / opt
        if ok.any():
            gap_all = float(np.mean(gap[ok]))
        oks = ok & res.is_success
        n_gap = int(oks.sum())
        if oks.any():
            gap_s = float(np.mean(gap[oks]))
        row["optimal_fuel_mean_kg"] = float(np.nanmean(opt))
    row["fuel_gap_pct"] = gap_s
    # final-time gap: mean over successful cases of 100·(episode time − optimal tf)/optimal tf
    row["final_time_gap_pct"] = float("nan")
    if opt_tf is not None:
        tf = opt_tf[res.case_ids]
        okt = np.isfinite(tf) & np.isfinite(res.episode_time_s) & res.is_success
        if okt.any():
            row["final_time_gap_pct"] = float(np.mean(
                100.0 * (res.episode_time_s[okt] - tf[okt]) / tf[okt]))
    row["fuel_gap_pct_all_cases"] = gap_all
    row["n_cases_in_gap"] = n_gap
    return row


def compare(env_id: str, policies: list[Policy], n_states: int = DEFAULT_N_STATES,
            seed: int = DEFAULT_SEED, env_kwargs: dict[str, Any] | None = None,
            open_loop: bool = True, n_expert_states: int = DEFAULT_EXPERT_STATES,
            trace_cases: int = 3, progress: bool = True,
            optimum_workers: int = 1, optimum_executor=None,
            feedback_expert: bool = True, n_feedback_states: int | None = None
            ) -> dict[str, Any]:
    """Run ``policies`` and the optimiser baselines over one case set; return the report dict.

    ``optimum_executor`` (:mod:`optimizers.common.executor`, e.g. Ray) runs the per-case optima
    (default: this process for the planar ones, ``optimum_workers`` processes for the pinpoint
    ones). ``feedback_expert`` (pinpoint): also fly the Pontryagin feedback expert
    (:class:`agents.experts.PinpointPontryaginExpert`, the DAgger oracle) on the first
    ``n_feedback_states`` cases (None: every case).

    Keys: ``env_id``, ``seed``, ``n_states``, ``rows`` (one summary per policy, see the module
    docstring), ``optimum`` (per-case optimal fuel summary and solver wall time), ``results``
    (the :class:`PolicyResult` objects, not JSON-serialised), ``optimal_solutions``.
    """
    import gymnasium as gym

    import lunar_env  # noqa: F401

    states = initial_states(env_id, n_states, seed, env_kwargs)
    env = gym.make(env_id, **(env_kwargs or {}))
    scenario = env.unwrapped.scenario
    env.close()
    planar = states.shape[1] == 5
    opt_fuel = opt_tf = None
    sols = None
    opt_info: dict[str, Any] = {}
    if planar:
        if progress:
            print(f"Solving {n_states} per-case optimal controls (Pontryagin)...", flush=True)
        opt_fuel, sols, wall = optimal_solutions(scenario, states, progress=progress,
                                                 executor=optimum_executor)
        opt_info = {"solver": "optimizers.indirect.batch.solve_many",
                    "converged": int(np.isfinite(opt_fuel).sum()),
                    "fuel_mean_kg": float(np.nanmean(opt_fuel)), "wall_s": wall}
        opt_tf = np.array([s.tf_s if s.success else np.nan for s in sols], dtype=np.float64)
    else:
        # 3D pinpoint: [001]'s serial GPM + shooting from each drawn state (cached on disk)
        from agents.pinpoint_optimum import PinpointOpenLoopPolicy, pinpoint_optima

        if progress:
            print(f"Per-case optimum of {n_states} states (GPM + direct shooting, cached)...",
                  flush=True)
        t0 = time.perf_counter()
        sols = pinpoint_optima(scenario, states, workers=optimum_workers, progress=progress,
                               executor=optimum_executor)
        opt_fuel = np.array([s.fuel_kg if s.success else np.nan for s in sols])
        opt_tf = np.array([s.tf_s if s.success else np.nan for s in sols])
        opt_info = {"solver": "optimizers.transcription.batch.solve_many "
                              "(serial GPM + direct shooting)",
                    "converged": int(np.isfinite(opt_fuel).sum()),
                    "fuel_mean_kg": float(np.nanmean(opt_fuel)) if np.isfinite(
                        opt_fuel).any() else float("nan"),
                    "wall_s": time.perf_counter() - t0}
    runs: list[PolicyResult] = []
    all_policies: list[tuple[Policy, int]] = [(p, n_states) for p in policies]
    if planar and open_loop and sols is not None:
        all_policies.append((OpenLoopPolicy(sols), n_states))
    if not planar and open_loop:
        all_policies.append((PinpointOpenLoopPolicy(sols), n_states))
    if not planar and feedback_expert:
        from agents.experts import PinpointPontryaginExpert

        n_fb = n_states if n_feedback_states is None else min(int(n_feedback_states), n_states)
        if n_fb > 0:
            all_policies.append((PinpointPontryaginExpert(scenario), n_fb))
    if not planar and n_expert_states and n_expert_states > 0:
        from agents.pinpoint_optimum import PinpointReplanningPolicy

        all_policies.append((PinpointReplanningPolicy(sols), min(n_expert_states, n_states)))
    if planar and n_expert_states and n_expert_states > 0:
        all_policies.append((ExpertPolicy(scenario), min(n_expert_states, n_states)))
    for pol, n in all_policies:
        if progress:
            print(f"Evaluating {pol.name} on {n} cases...", flush=True)
        runs.append(rollout(env_id, pol, n, seed, env_kwargs, trace_cases=trace_cases))
    rows = [_summary(r, opt_fuel, opt_tf) for r in runs]
    return {"env_id": env_id, "seed": seed, "n_states": n_states,
            "env_kwargs": dict(env_kwargs or {}), "rows": rows, "optimum": opt_info,
            "results": runs, "optimal_solutions": sols, "initial_states_nd": states,
            "scenario": scenario}


def _fmt(x: float, spec: str) -> str:
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def markdown_table(report: dict[str, Any]) -> str:
    """The comparison as a Markdown table (one row per policy)."""
    pinpoint = any(math.isfinite(r["miss_distance_mean_m"]) for r in report["rows"])
    head = ["policy", "cases", "success %", "touchdown speed mean / p95 (m/s)"]
    if pinpoint:
        head.append("miss mean (m)")
    head += ["fuel mean (kg)", "gap to optimum (%)", "final-time gap (%)", "µs / decision"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in report["rows"]:
        cells = [r["policy"], str(r["n_cases"]), _fmt(100 * r["success_rate"], ".1f"),
                 f"{_fmt(r['touchdown_speed_mean_m_s'], '.2f')} / "
                 f"{_fmt(r['touchdown_speed_p95_m_s'], '.2f')}"]
        if pinpoint:
            cells.append(_fmt(r["miss_distance_mean_m"], ".0f"))
        cells += [_fmt(r["fuel_mean_kg"], ".2f"), _fmt(r.get("fuel_gap_pct"), "+.2f"),
                  _fmt(r.get("final_time_gap_pct", float("nan")), "+.2f"),
                  _fmt(r["us_per_decision"], ".1f")]
        lines.append("| " + " | ".join(cells) + " |")
    opt = report.get("optimum", {})
    if opt.get("solver"):
        lines.append("")
        lines.append(f"Per-case optimum ({opt['solver']}): {opt['converged']}/"
                     f"{report['n_states']} converged, mean {opt['fuel_mean_kg']:.2f} kg, "
                     f"{opt['wall_s']:.1f} s. Gap: mean over successful cases of "
                     "100·(fuel − optimum)/optimum.")
    return "\n".join(lines)


def _json_report(report: dict[str, Any]) -> dict[str, Any]:
    out = {k: report[k] for k in ("env_id", "seed", "n_states", "env_kwargs", "rows", "optimum")}
    out["per_case"] = {
        r.name: {"success": r.is_success.astype(int).tolist(),
                 "touchdown_speed_m_s": [None if not math.isfinite(v) else v
                                         for v in r.touchdown_speed_m_s.tolist()],
                 "fuel_used_kg": [None if not math.isfinite(v) else v
                                  for v in r.fuel_used_kg.tolist()]}
        for r in report["results"]}
    sols = report.get("optimal_solutions")
    if sols is not None:
        out["per_case"]["optimum_fuel_kg"] = [float(s.fuel_kg) if s.success else None
                                              for s in sols]
        out["per_case"]["optimum_tf_s"] = [float(s.tf_s) if s.success else None
                                           for s in sols]
    return out


def plot_comparison(report: dict[str, Any], path: str | Path) -> Path:
    """Trajectory (altitude vs downrange) and thrust angle vs time of each policy and the optimum
    for the traced cases; saved as a PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenario = report["scenario"]
    results: list[PolicyResult] = report["results"]
    cases = sorted(set().union(*[set(r.traces) for r in results])) if results else []
    if not cases:
        raise ValueError("no traced cases to plot")
    planar = report["initial_states_nd"].shape[1] == 5
    fig, axes = plt.subplots(len(cases), 2, figsize=(12, 3.6 * len(cases)), squeeze=False)
    s = scenario.scaling()
    r_surf = scenario.surface_radius_m if planar else scenario.body.radius_m
    for row, cid in enumerate(cases):
        ax_tr, ax_u = axes[row]
        sols = report.get("optimal_solutions")
        if planar and sols is not None and sols[cid].success:
            tr = sols[cid].sample(n=301)
            st = tr.states
            ax_tr.plot(st["theta_rad"] * r_surf / 1e3, (st["radius_m"] - r_surf) / 1e3,
                       "k--", lw=2, label="optimum")
            ax_u.plot(tr.t_s, np.degrees(tr.controls["phi_rad"]), "k--", lw=2, label="optimum")
        for res in results:
            if cid not in res.traces:
                continue
            tc = res.traces[cid]
            y = tc["state_nd"]
            if len(y) == 0:
                continue
            if planar:
                alt_km = (y[:, 0] * s.length_m - r_surf) / 1e3
                down_km = y[:, 2] * r_surf / 1e3
                ax_tr.plot(down_km, alt_km, label=res.name)
                if len(tc["action"]):
                    from lunar_env.envs.soft_landing import thrust_angle_from_action

                    phi = thrust_angle_from_action(tc["action"][:, 0])
                    ax_u.step(tc["t_s"][:len(phi)], np.degrees(phi), where="post",
                              label=res.name)
            else:
                if sols is not None and getattr(sols[cid], "success", False) \
                        and res is results[0]:
                    opt_r = np.linalg.norm(sols[cid].states_nd[:, :3], axis=1) * s.length_m
                    ax_tr.plot(sols[cid].t_nodes_s, (opt_r - r_surf) / 1e3, "k--", lw=2,
                               label="optimum")
                rad = np.linalg.norm(y[:, :3], axis=1) * s.length_m
                ax_tr.plot(tc["t_s"], (rad - r_surf) / 1e3, label=res.name)
                if len(tc["action"]):
                    for j in range(tc["action"].shape[1]):
                        ax_u.step(tc["t_s"][:len(tc["action"])], tc["action"][:, j],
                                  where="post", label=f"{res.name} a{j}")
        # a trajectory that passed below the surface (an env failure, reported in the table as
        # no touchdown) must not squash the others: clip the view just below the surface
        tops = [ln.get_ydata().max() for ln in ax_tr.get_lines() if len(ln.get_ydata())]
        if tops:
            hi = 1.05 * max(max(tops), 1e-3)
            ax_tr.set_ylim(-0.05 * hi, hi)
        ax_tr.set_xlabel("downrange (km)" if planar else "time (s)")
        ax_tr.set_ylabel("altitude (km)")
        ax_tr.set_title(f"case {cid}: trajectory")
        ax_u.set_xlabel("time (s)")
        ax_u.set_ylabel("thrust angle φ (deg)" if planar else "action")
        ax_u.set_title(f"case {cid}: control")
        ax_tr.grid(alpha=0.3)
        ax_u.grid(alpha=0.3)
        ax_u.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_report(report: dict[str, Any], out_dir: str | Path) -> dict[str, Path]:
    """Write ``comparison.md``, ``comparison.json`` and ``trajectories.png`` into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    md = markdown_table(report)
    from agents.runs import write_text_atomic

    write_text_atomic(out / "comparison.md", md + "\n")
    write_text_atomic(out / "comparison.json", json.dumps(_json_report(report), indent=1))
    paths = {"markdown": out / "comparison.md", "json": out / "comparison.json"}
    try:
        paths["plot"] = plot_comparison(report, out / "trajectories.png")
    except ValueError:
        pass
    return paths


def evaluate_run(run_dir: str | Path, n_states: int = DEFAULT_N_STATES, seed: int = DEFAULT_SEED,
                 n_expert_states: int | None = None, open_loop: bool = True,
                 out_dir: str | Path | None = None) -> dict[str, Any]:
    """Evaluate a training run (its final model) against the baselines; print and save the table.

    Uses the run's env id and ``env_kwargs`` (from ``args.yml`` / ``config.yml``); writes into
    ``<run_dir>/evaluation`` unless ``out_dir`` is given.
    """
    from agents.runs import read_run

    run_dir = Path(run_dir)
    args, hp = read_run(run_dir)
    env_id = args["env"]
    policy = SB3Policy.from_path(run_dir, name=f"{args['algo'].upper()} ({run_dir.name})")
    if n_expert_states is None:
        # the pinpoint expert re-solves an NLP every 10 s of flight (~55 per case): fewer cases
        n_expert_states = PINPOINT_EXPERT_STATES if "Pinpoint" in env_id \
            else DEFAULT_EXPERT_STATES
    report = compare(env_id, [policy], n_states=n_states, seed=seed,
                     env_kwargs=hp.get("env_kwargs"), open_loop=open_loop,
                     n_expert_states=int(n_expert_states),
                     n_feedback_states=PINPOINT_FEEDBACK_STATES)
    paths = write_report(report, out_dir or run_dir / "evaluation")
    print()
    print(f"## {env_id}: {n_states} dispersed initial states (seed {seed})")
    print()
    print(markdown_table(report))
    print()
    print("Written: " + ", ".join(str(p) for p in paths.values()))
    return report


def publish_report(report: dict, out: str | Path, json_path: str | None = None) -> dict:
    """Write the report files to ``out`` (and the JSON to ``json_path``), print the table.

    Returns the written paths.
    """
    paths = write_report(report, out)
    if json_path:
        from agents.runs import write_text_atomic

        write_text_atomic(json_path, json.dumps(_json_report(report), indent=1))
    print()
    print(markdown_table(report))
    print()
    print("Written: " + ", ".join(str(p) for p in paths.values()))
    return paths


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point (``python -m agents.evaluate``)."""
    p = argparse.ArgumentParser(prog="python -m agents.evaluate", description=__doc__.split(
        "\n")[0])
    p.add_argument("--env", default=None,
                   help=f"env id (default: the first model's run, else {DEFAULT_ENV_ID})")
    p.add_argument("--env-kwargs", default=None,
                   help="JSON dict of env arguments over the run's, e.g. "
                        "'{\"scenario\": \"wang2003\", \"thrust_n\": 2929}' (a [003] lander "
                        "at its optimal thrust; the per-case optimum is solved at that thrust)")
    p.add_argument("--model", action="append", default=[],
                   help="run directory or model .zip (repeatable)")
    p.add_argument("--n-states", type=int, default=DEFAULT_N_STATES)
    p.add_argument("--seed", type=int, default=DEFAULT_SEED)
    p.add_argument("--expert-states", type=int, default=DEFAULT_EXPERT_STATES,
                   help="cases flown by the closed-loop re-planning expert (0: skip)")
    p.add_argument("--feedback-states", type=int, default=None,
                   help="pinpoint: cases flown by the Pontryagin feedback expert "
                        "(default: all)")
    p.add_argument("--no-open-loop", action="store_true", help="skip the open-loop replay")
    p.add_argument("--trace-cases", type=int, default=3)
    p.add_argument("--out", default=None, help="output directory (default results/evaluate)")
    p.add_argument("--json", default=None, help="also write the JSON report to this file")
    p.add_argument("--torch-threads", type=int, default=1,
                   help="torch threads for SB3 inference (default 1, as in training)")
    p.add_argument("--optimum-workers", type=int, default=1,
                   help="processes for the per-case optimum (pinpoint: cached on disk)")
    p.add_argument("--address", default=None,
                   help="Ray cluster for the per-case optima ('auto', 'host:port', "
                        "'local'); default $RAY_ADDRESS, else --optimum-workers local processes")
    args = p.parse_args(argv)
    import torch

    from agents.runs import read_run, run_dir_of

    torch.set_num_threads(max(args.torch_threads, 1))

    env_id = args.env
    env_kwargs = None
    policies: list[Policy] = []
    for m in args.model:
        run_dir = run_dir_of(m)
        ra, hp = read_run(run_dir)
        if ra:
            if env_id is None:
                env_id = ra["env"]
            if env_kwargs is None:
                env_kwargs = hp.get("env_kwargs")
        policies.append(SB3Policy.from_path(m))
        if len(args.model) > 1:
            policies[-1].name = f"{policies[-1].name} ({run_dir.name})"
    env_id = env_id or DEFAULT_ENV_ID
    if args.env_kwargs:
        import json as _json

        extra = _json.loads(args.env_kwargs)
        if not isinstance(extra, dict):
            p.error(f"--env-kwargs {args.env_kwargs!r} must be a JSON object")
        env_kwargs = {**(env_kwargs or {}), **extra}
    import os

    from optimizers.common.executor import RAY_ADDRESS_ENV, get_executor

    executor = None
    if args.address or os.environ.get(RAY_ADDRESS_ENV) or args.optimum_workers > 1:
        executor = get_executor(args.address, args.optimum_workers)
    try:
        report = compare(env_id, policies, n_states=args.n_states, seed=args.seed,
                         env_kwargs=env_kwargs, open_loop=not args.no_open_loop,
                         n_expert_states=args.expert_states, trace_cases=args.trace_cases,
                         n_feedback_states=args.feedback_states,
                         optimum_workers=args.optimum_workers, optimum_executor=executor)
    finally:
        if executor is not None:
            executor.close()
    publish_report(report, args.out or Path("results") / "evaluate", args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
