"""Many seeded runs of one optimiser on one problem on the executor: ``optimizers.study``.

::

    python -m optimizers.study asaga zhu2007 --runs 100                 # local process pool
    python -m optimizers.study asaga zhu2007 --runs 100 --address auto  # the Ray cluster
    python -m optimizers.study pygmo-cmaes zhu2007 --runs 20 --set n_generations=300
    python -m optimizers.study --list

Run ``i`` of a study with master seed ``s`` is seeded with ``SeedSequence(s).spawn(n)[i]`` (the
same stream as run ``i`` of ``python -m optimizers.reproduce zhu2007 --seed s``), so its result
does not depend on ``n``, on the executor or on which worker ran it. Each run is one executor
task keyed ``(problem fingerprint, seed, i)``; its row (the problem's verdict, fuel, terminal
errors, wall time, and the :func:`~optimizers.certification.certify` certificate: a DOP853
replay judged by the problem and the fuel gap to the problem's certified optimum) is written
atomically to ``<out>/results/`` as soon as it finishes. An interrupted study rerun with the
same command does only the missing runs; a larger ``--runs`` extends it. The study's identity
(algorithm, settings, problem and its fingerprint, seed) is recorded and another study is
refused in the same directory; every stored row is verified when it is read back
(:class:`~optimizers.common.store.ResultStore`), and one process at a time writes a study
directory (:class:`~optimizers.common.lock.DirectoryLock`: a second run of the same study
refuses at once, naming the first one's PID). Ctrl-C or SIGTERM stops the workers, keeps every
finished run and exits 130 / 143 (:func:`~optimizers.common.cli.clean_interrupts`).

Outputs in ``<out>`` (default ``results/study/<algorithm>_<problem>_seed<s>/``): ``table.md``
(printed), ``study.json`` (the summary and every row) and ``study.png``.
"""

from __future__ import annotations

import math
import time
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from ..common.checkpoint import save_figure_atomic
from ..common.executor import Executor, ResultStore, Task, TaskKey, run_tasks
from ..common.lock import DirectoryLock
from .registry import ALGORITHMS, PROBLEMS, make_algorithm, make_problem

__all__ = ["run_one", "run_study", "study_identity", "default_out", "summarise",
           "markdown_table", "plot_study", "ALGORITHMS", "PROBLEMS"]


@lru_cache(maxsize=8)
def _problem(name: str, kwargs_items: tuple):
    # one problem object per worker process (numba kernels and the OCP built once)
    return make_problem(name, **dict(kwargs_items))


def _items(d: dict) -> tuple:
    return tuple(sorted((k, v) for k, v in d.items()))


def run_one(algorithm: str, settings: dict, problem: str, problem_kwargs: dict, seed: int,
            index: int, reference=None) -> dict[str, Any]:
    """One seeded run and its certificate (the study's task; runs in a worker).

    Parameters
    ----------
    algorithm, settings : registered algorithm name and its constructor arguments
    problem, problem_kwargs : registered problem name and overrides
    seed, index : master seed and run number; the run's stream is
        ``SeedSequence(seed, spawn_key=(index,))`` (= ``SeedSequence(seed).spawn(n)[index]``)
    reference : OptimResult, optional
        The certified optimum to compare with (computed once by the caller); None skips the
        certificate.

    Returns
    -------
    dict
        JSON-ready row: ``index``, ``success`` (the problem's verdict), ``fuel_kg``, ``tf_s``,
        ``terminal_errors``, ``fun``, ``n_fevals``, ``n_iter``, ``wall_s``, ``cpu_s``, ``x``,
        ``message``, ``certificate`` (or None) and ``certify_error`` (why not, if it failed).
    """
    from ..certification import certify

    prob = _problem(problem, _items(problem_kwargs))
    algo = make_algorithm(algorithm, **settings)
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(int(index),)))
    c0 = time.process_time()
    res = algo.solve(prob, seed=rng)
    cpu = time.process_time() - c0
    row = {"index": int(index), "seed": int(seed), "success": bool(res.success),
           "feasible": None if res.feasible is None else bool(res.feasible),
           "fuel_kg": float(res.fuel_kg), "tf_s": float(res.tf_s),
           "terminal_errors": {k: float(v) for k, v in res.terminal_errors.items()},
           "fun": float(res.fun), "n_fevals": int(res.n_fevals), "n_iter": int(res.n_iter),
           "wall_s": float(res.wall_s), "cpu_s": float(cpu), "x": [float(v) for v in res.x],
           "message": res.message, "certificate": None, "certify_error": None}
    if reference is not None:
        try:
            row["certificate"] = certify(res, prob, reference=reference).as_dict()
        except (ValueError, TypeError, ArithmeticError) as exc:
            row["certify_error"] = f"{type(exc).__name__}: {exc}"
    return row


def study_identity(algorithm: str, problem: str, *, seed: int = 0,
                   settings: dict | None = None, problem_kwargs: dict | None = None,
                   certify_runs: bool = True) -> dict[str, Any]:
    """What a study's results belong to (its store's identity): the algorithm and its
    resolved settings, the problem, its overrides and fingerprint, the seed, certification.

    Raises
    ------
    ValueError
        Unknown names or settings (as :func:`make_algorithm` / :func:`make_problem`).
    """
    settings = dict(settings or {})
    problem_kwargs = dict(problem_kwargs or {})
    prob = _problem(problem, _items(problem_kwargs))
    algo = make_algorithm(algorithm, **settings)  # validates the settings before any task
    algo_settings = algo.settings() if hasattr(algo, "settings") else settings
    return {"algorithm": algorithm, "settings": algo_settings, "problem": problem,
            "problem_kwargs": problem_kwargs, "problem_fingerprint": prob.fingerprint(),
            "seed": int(seed), "certified": bool(certify_runs)}


def default_out(algorithm: str, problem: str, seed: int, tag: str = "") -> Path:
    """``results/study/<algorithm>_<problem>_seed<seed><tag>``."""
    return Path("results") / "study" / f"{algorithm}_{problem}_seed{int(seed)}{tag}"


def run_study(algorithm: str, problem: str, n_runs: int, *, seed: int = 0,
              settings: dict | None = None, problem_kwargs: dict | None = None,
              executor: Executor | None = None, out: str | Path | None = None,
              certify_runs: bool = True, progress: bool = True,
              max_tasks: int | None = None) -> dict[str, Any]:
    """Run (or resume) a study; returns ``{"identity", "summary", "rows", "optimum", ...}``.

    Parameters
    ----------
    algorithm, problem : registered names (:mod:`optimizers.study.registry`)
    n_runs : int
    seed : int
        Master seed.
    settings, problem_kwargs : dict, optional
        Algorithm constructor arguments and problem overrides.
    executor : Executor, optional
        Default: in this process.
    out : path, optional
        Study directory (results, table, plot); default ``results/study/<alg>_<prob>_seed<s>``.
    certify_runs : bool
        Compute the certified optimum once and certify every run against it.
    max_tasks : int, optional
        Run at most this many of the missing runs (interruption, for tests).

    Raises
    ------
    ValueError
        Unknown names, ``n_runs < 1``, or a study directory of another study
        (:class:`~optimizers.common.store.StoreIdentityError`).
    DirectoryBusy
        Another process is writing to ``out`` (the message names its PID).
    """
    if int(n_runs) < 1:
        raise ValueError(f"n_runs = {n_runs!r} must be >= 1")
    settings = dict(settings or {})
    problem_kwargs = dict(problem_kwargs or {})
    identity = study_identity(algorithm, problem, seed=seed, settings=settings,
                              problem_kwargs=problem_kwargs, certify_runs=certify_runs)
    out = Path(out) if out is not None else default_out(algorithm, problem, seed)
    with DirectoryLock(out, what="study"):
        return _run_study(identity, n_runs, settings, problem_kwargs, executor, out,
                          certify_runs, progress, max_tasks)


def _run_study(identity: dict, n_runs: int, settings: dict, problem_kwargs: dict,
               executor: Executor | None, out: Path, certify_runs: bool, progress: bool,
               max_tasks: int | None) -> dict[str, Any]:
    algorithm, problem = identity["algorithm"], identity["problem"]
    seed, fingerprint = identity["seed"], identity["problem_fingerprint"]
    prob = _problem(problem, _items(problem_kwargs))
    store = ResultStore(out, identity)
    reference = None
    optimum: dict[str, Any] = {}
    if certify_runs:
        from ..certification import certified_optimum

        t0 = time.perf_counter()
        try:
            reference = certified_optimum(prob.ocp)
        except (AttributeError, TypeError) as exc:  # a problem without a certifier
            optimum = {"method": None, "note": f"no certified optimum: {exc}"}
        else:
            optimum = {"method": reference.algorithm or type(reference).__name__,
                       "success": bool(reference.success), "fuel_kg": float(reference.fuel_kg),
                       "tf_s": float(reference.tf_s), "wall_s": time.perf_counter() - t0}
    key_problem = f"{problem}-{fingerprint}"
    tasks = [Task(TaskKey(key_problem, int(seed), i), run_one,
                  (algorithm, settings, problem, problem_kwargs, int(seed), i, reference))
             for i in range(int(n_runs))]
    desc = f"{algorithm} on {problem}" if progress else False
    t0 = time.perf_counter()
    results, report = run_tasks(tasks, executor, store, progress=desc, max_tasks=max_tasks)
    wall = time.perf_counter() - t0
    rows = [results[t.key] for t in tasks if t.key in results]
    summary = summarise(rows, n_runs=int(n_runs))
    summary.update(study_wall_s_this_call=wall, runs_this_call=report.n_done,
                   runs_resumed=report.n_skipped, executor=report.executor)
    return {"identity": identity, "summary": summary, "optimum": optimum, "rows": rows,
            "out": str(out), "complete": len(rows) == int(n_runs)}


def _stats(v: np.ndarray) -> dict[str, float]:
    if v.size == 0:
        return {k: math.nan for k in ("mean", "median", "min", "max")}
    return {"mean": float(np.mean(v)), "median": float(np.median(v)),
            "min": float(np.min(v)), "max": float(np.max(v))}


def summarise(rows: list[dict], n_runs: int | None = None) -> dict[str, Any]:
    """Success rate, fuel gap to the certified optimum (successful runs and all runs), terminal
    errors and wall time of study rows."""
    n = len(rows)
    ok = np.array([r["success"] for r in rows], dtype=bool)
    certs = [r.get("certificate") for r in rows]
    gap = np.array([c["fuel_gap_kg"] if c else math.nan for c in certs], dtype=float)
    gap_pct = np.array([c["fuel_gap_pct"] if c else math.nan for c in certs], dtype=float)
    replay = np.array([bool(c and c["replay_success"]) for c in certs], dtype=bool)
    speed = np.array([r["terminal_errors"].get("speed_m_s", math.nan) for r in rows], float)
    radius = np.array([abs(r["terminal_errors"].get("radius_m", math.nan)) for r in rows], float)
    wall = np.array([r["wall_s"] for r in rows], dtype=float)
    cpu = np.array([r.get("cpu_s", math.nan) for r in rows], dtype=float)
    fin = np.isfinite(gap)
    return {
        "n_runs": n, "n_runs_requested": int(n_runs if n_runs is not None else n),
        "n_success": int(ok.sum()), "success_rate": float(ok.mean()) if n else math.nan,
        "n_replay_success": int(replay.sum()),
        "n_certified": int(fin.sum()),
        "fuel_gap_kg_success": _stats(gap[ok & fin]),
        "fuel_gap_pct_success": _stats(gap_pct[ok & fin]),
        "fuel_gap_kg_all": _stats(gap[fin]),
        "speed_error_m_s": _stats(speed[np.isfinite(speed)]),
        "radius_error_m": _stats(radius[np.isfinite(radius)]),
        "wall_s_per_run": _stats(wall), "cpu_s_per_run": _stats(cpu[np.isfinite(cpu)]),
        "n_fevals_mean": float(np.mean([r["n_fevals"] for r in rows])) if n else math.nan,
    }


def _f(x: float, spec: str = ".3f") -> str:
    return "–" if x is None or not math.isfinite(x) else format(x, spec)


def markdown_table(study: dict[str, Any]) -> str:
    """The study's table (Markdown)."""
    s, ident, opt = study["summary"], study["identity"], study.get("optimum") or {}
    gs, ga = s["fuel_gap_kg_success"], s["fuel_gap_kg_all"]
    lines = [
        f"Study: {ident['algorithm']} on {ident['problem']} ({s['n_runs']} of "
        f"{s['n_runs_requested']} runs, master seed {ident['seed']}; {s.get('executor', '')})",
        "",
        "| quantity | value |",
        "|---|---|",
        f"| success (problem's verdict) | {s['n_success']}/{s['n_runs']} "
        f"({100 * s['success_rate']:.0f} %) |",
        f"| DOP853 replay lands (problem's verdict) | {s['n_replay_success']}/{s['n_runs']} |",
        f"| fuel gap to optimum, successful runs (kg): mean / median / min / max | "
        f"{_f(gs['mean'])} / {_f(gs['median'])} / {_f(gs['min'])} / {_f(gs['max'])} |",
        f"| fuel gap to optimum, all runs (kg): mean / min / max | {_f(ga['mean'])} / "
        f"{_f(ga['min'])} / {_f(ga['max'])} |",
        f"| terminal speed error (m/s): median / max | {_f(s['speed_error_m_s']['median'])} / "
        f"{_f(s['speed_error_m_s']['max'])} |",
        f"| terminal radius error (m): median / max | {_f(s['radius_error_m']['median'])} / "
        f"{_f(s['radius_error_m']['max'])} |",
        f"| wall time per run (s): mean / max | {_f(s['wall_s_per_run']['mean'], '.2f')} / "
        f"{_f(s['wall_s_per_run']['max'], '.2f')} |",
        f"| evaluations per run | {_f(s['n_fevals_mean'], '.0f')} |",
    ]
    if "study_wall_s_this_call" in s:
        lines.append(f"| study wall time, this call (s) | "
                     f"{_f(s['study_wall_s_this_call'], '.1f')} "
                     f"({s['runs_this_call']} runs; {s['runs_resumed']} resumed from disk) |")
    if opt and opt.get("method") is None:
        lines += ["", f"Optimum: {opt.get('note', 'none')}"]
    elif opt:
        lines += ["", f"Optimum: {opt['method']} ({'converged' if opt['success'] else 'FAILED'})"
                  f", fuel {_f(opt['fuel_kg'], '.4f')} kg, tf {_f(opt['tf_s'], '.3f')} s; gap = "
                  "run fuel − optimum fuel (a negative gap is a run that did not land)."]
    return "\n".join(lines)


def plot_study(study: dict[str, Any], path: str | Path) -> Path:
    """Fuel gap against terminal speed error, and radius against speed error (per run,
    successes green)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = study["rows"]
    ok = np.array([r["success"] for r in rows], dtype=bool)
    gap = np.array([(r.get("certificate") or {}).get("fuel_gap_kg", math.nan) for r in rows])
    speed = np.array([r["terminal_errors"].get("speed_m_s", math.nan) for r in rows])
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    for mask, label, c in ((ok, "success", "tab:green"), (~ok, "no success", "tab:red")):
        a.scatter(np.maximum(speed[mask], 1e-6), gap[mask], s=14, c=c, label=label)
    a.set_xscale("log")
    a.set_xlabel("terminal speed error (m/s)")
    a.set_ylabel("fuel − certified optimum (kg)")
    a.axhline(0.0, color="k", lw=0.8)
    a.legend()
    radius = np.array([abs(r["terminal_errors"].get("radius_m", math.nan)) for r in rows])
    for mask, c in ((ok, "tab:green"), (~ok, "tab:red")):
        b.scatter(np.maximum(speed[mask], 1e-6), np.maximum(radius[mask], 1e-6), s=14, c=c)
    b.set_xscale("log")
    b.set_yscale("log")
    b.set_xlabel("terminal speed error (m/s)")
    b.set_ylabel("terminal radius error (m)")
    b.set_title("why runs fail: terminal errors", fontsize=9)
    ident = study["identity"]
    fig.suptitle(f"{ident['algorithm']} on {ident['problem']}: {len(rows)} runs, "
                 f"{int(ok.sum())} successes")
    fig.tight_layout()
    path = save_figure_atomic(fig, path, dpi=110)
    plt.close(fig)
    return path
