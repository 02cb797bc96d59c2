"""Hyperparameter search: ``python train.py --optimize`` (RL Zoo's flag), Optuna on the executor.

::

    python train.py --optimize --n-trials 40 -n 500000              # local pool, all cores
    python train.py --optimize --n-trials 200 --address auto         # trials on a Ray cluster
    python train.py --optimize --quick --n-trials 4                  # smoke run (seconds/trial)
    python train.py --optimize ... --storage postgresql://host/db    # several machines, one study

Each trial trains PPO with the shipped entry of the env (``agents/hyperparams/ppo.yml``, the
``--config``/``--quick`` profile, ``--hyperparams`` overrides) with the sampled values merged
over it, through :func:`agents.rl.training.train` itself (same curriculum, features, shaping,
normalisation), for ``n_timesteps`` (``-n``) steps. ``--n-evaluations`` times during training
the deterministic policy flies ``--eval-states`` dispersed initial states (seed
``--tune-seed``, not the final evaluation's 2026) and the score is reported to Optuna; the
pruner stops hopeless trials. The last score is the trial's value.

Score (maximised) = success rate − (mean fuel of the successful landings in kg) / 1000 −
(1 − success rate) · min(mean touchdown speed of the failed cases / 1000 m/s, 1). Success (the
env's own criterion) dominates; 1 kg of propellant costs as much as 0.1 % of success, which
separates policies that land equally often (their fuel differs by a few kg); the last term ranks
policies that do not land yet (early trials, short budgets) by how hard they hit, so the sampler
and the pruner have a signal before the first landing.

Decision: Optuna with shared storage, not Ray Tune + OptunaSearch.

- The trials are tasks of :mod:`optimizers.common.executor` like every other scale-out job
  here: the local process pool by default, Ray with ``--address``, resumable the same way
  (finished trials are stored per key and skipped by a rerun). Ray Tune would be a second
  scheduler with its own result directories, checkpoints and resume semantics, and would make
  Ray mandatory for a search (it is an optional extra).
- Each task opens the study from the storage, asks for one trial (sampler: TPE seeded per
  trial index, so trials differ and a rerun proposes the same), trains, reports intermediate
  scores and tells the outcome. The pruner and the sampler see every other worker's trials
  through the storage — Optuna's documented way to parallelise, and it also lets several
  drivers on several machines join one study.
- Storage: a journal file (``JournalFileBackend``, file-locked appends; default
  ``<out>/study.journal``) on one machine or a shared filesystem; an RDB URL (``--storage
  sqlite:///…``, ``postgresql://…``) for a cluster without one.

Outputs in ``<log-folder>/optimize/<env id>_<k>/``: ``study.journal``, ``trials/`` (one train run
directory per trial), ``trials.md`` (table of every trial), ``best.yml`` — the best trial's full
configuration as a Zoo entry keyed by the env id, usable as
``python train.py --hyperparams-file <out>/best.yml``.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from stable_baselines3.common.callbacks import BaseCallback

__all__ = ["sample_ppo_params", "score", "TrialEvalCallback", "run_trial", "optimize",
           "make_storage", "best_entry"]

_TUNE_SEED = 7


def sample_ppo_params(trial, n_envs: int) -> dict[str, Any]:
    """PPO hyperparameters proposed by ``trial`` (the RL Zoo's ``sample_ppo_params``, narrowed
    to the ranges that train on this task). ``batch_size`` divides ``n_steps · n_envs``."""
    n_steps = trial.suggest_categorical("n_steps", [64, 128, 256, 512])
    batch_choices = [b for b in (64, 128, 256, 512, 1024) if b <= n_steps * n_envs]
    batch_size = trial.suggest_categorical("batch_size", [64, 128, 256, 512, 1024])
    if batch_size not in batch_choices:  # keep the categorical space fixed for TPE; clip
        batch_size = max(batch_choices)
    return {
        "n_steps": n_steps,
        "batch_size": batch_size,
        "learning_rate": trial.suggest_float("learning_rate", 1e-5, 2e-3, log=True),
        "gamma": trial.suggest_categorical("gamma", [0.99, 0.995, 0.999]),
        "gae_lambda": trial.suggest_categorical("gae_lambda", [0.9, 0.95, 0.98]),
        "n_epochs": trial.suggest_categorical("n_epochs", [3, 5, 10]),
        "clip_range": trial.suggest_categorical("clip_range", [0.1, 0.2, 0.3]),
        "ent_coef": trial.suggest_float("ent_coef", 1e-8, 1e-2, log=True),
        "policy_kwargs.log_std_init": trial.suggest_float("log_std_init", -3.0, -0.5),
        "policy_kwargs.net_arch": {"small": {"pi": [64, 64], "vf": [64, 64]},
                                   "medium": {"pi": [128, 128], "vf": [128, 128]}}[
            trial.suggest_categorical("net_arch", ["small", "medium"])],
        "policy_kwargs.activation_fn": trial.suggest_categorical("activation_fn",
                                                                 ["tanh", "relu"]),
    }


def score(is_success: np.ndarray, fuel_used_kg: np.ndarray,
          touchdown_speed_m_s: np.ndarray) -> float:
    """Success rate − mean fuel (kg) of the successful landings / 1000 − (failure rate) ·
    min(mean touchdown speed of the failures / 1000 m/s, 1) (module docstring)."""
    ok = np.asarray(is_success, dtype=bool)
    if ok.size == 0:
        return -1.0
    rate = float(ok.mean())
    fuel = float(np.mean(np.asarray(fuel_used_kg)[ok])) if ok.any() else 0.0
    crash = 0.0
    if not ok.all():
        v = np.asarray(touchdown_speed_m_s, dtype=float)[~ok]
        v = np.where(np.isfinite(v), v, 1000.0)  # never touched down: as bad as it gets
        crash = min(float(np.mean(v)) / 1000.0, 1.0)
    return rate - fuel / 1000.0 - (1.0 - rate) * crash


def make_storage(url: str):
    """An Optuna storage from a URL: an RDB URL (``sqlite:///…``, ``postgresql://…``) or a
    journal file path (anything else)."""
    import optuna

    if "://" in url:
        return optuna.storages.RDBStorage(url)
    from optuna.storages.journal import JournalFileBackend

    Path(url).parent.mkdir(parents=True, exist_ok=True)
    return optuna.storages.JournalStorage(JournalFileBackend(str(url)))


def _sampler(name: str, seed: int, n_startup: int):
    import optuna

    if name == "random":
        return optuna.samplers.RandomSampler(seed=seed)
    if name == "tpe":
        return optuna.samplers.TPESampler(n_startup_trials=n_startup, seed=seed,
                                          multivariate=True)
    raise ValueError(f"sampler = {name!r}; use 'tpe' or 'random'")


def _pruner(name: str, n_startup: int, n_evaluations: int):
    import optuna

    if name == "median":
        return optuna.pruners.MedianPruner(n_startup_trials=n_startup,
                                           n_warmup_steps=n_evaluations // 3)
    if name == "halving":
        return optuna.pruners.SuccessiveHalvingPruner(min_resource=1, reduction_factor=4)
    if name == "none":
        return optuna.pruners.NopPruner()
    raise ValueError(f"pruner = {name!r}; use 'median', 'halving' or 'none'")


class TrialEvalCallback(BaseCallback):
    """Score the policy during a trial, report each score to Optuna and stop the training when
    the pruner says so (the RL Zoo's ``TrialEvalCallback``).

    Parameters
    ----------
    trial : optuna.Trial
        The trial the scores are reported to (``trial.report(score, k)``, k = 1, 2, ...).
    evaluate : callable
        ``evaluate(model) -> float``: the score of the model's policy (higher is better).
    eval_every : int
        Env steps between evaluations: one at the first step at or past each multiple of it
        (at most one a step).
    n_evaluations : int
        Evaluations planned; the trial is never pruned at the last one (its score is the
        trial's value).

    Attributes
    ----------
    n_evals : int
        Evaluations made.
    last : float
        The last score (``-inf`` before the first).
    pruned : bool
        The pruner stopped the training.
    """

    def __init__(self, trial, evaluate: Callable[[Any], float], eval_every: int,
                 n_evaluations: int, verbose: int = 0) -> None:
        super().__init__(verbose)
        self.trial = trial
        self.evaluate = evaluate
        self.eval_every = int(eval_every)
        self.n_evaluations = int(n_evaluations)
        self.next_eval = self.eval_every
        self.n_evals = 0
        self.last = -math.inf
        self.pruned = False

    def _on_step(self) -> bool:
        if self.model.num_timesteps < self.next_eval:
            return True
        self.next_eval += self.eval_every
        self.n_evals += 1
        self.last = self.evaluate(self.model)
        self.trial.report(self.last, self.n_evals)
        if self.n_evals < self.n_evaluations and self.trial.should_prune():
            self.pruned = True
            return False
        return True


def run_trial(storage_url: str, study_name: str, index: int, hp_base: dict, run_base: dict,
              out_dir: str, search: dict) -> dict[str, Any]:
    """One trial (an executor task): ask the study for parameters, train, report, tell.

    Returns ``{"index", "number", "state", "value", "params", "hyperparams", "run_dir"}``.
    """
    import optuna

    from agents.hyperparams import apply_overrides
    from agents.laws import SB3Law
    from agents.rl.training import train
    from guidance.flight import rollout

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    seed = int(run_base["seed"]) + int(index)
    study = optuna.load_study(
        study_name=study_name, storage=make_storage(storage_url),
        sampler=_sampler(search["sampler"], seed, search["n_startup_trials"]),
        pruner=_pruner(search["pruner"], search["n_startup_trials"], search["n_evaluations"]))
    trial = study.ask()
    trial.set_user_attr("task_index", int(index))
    hp = apply_overrides(hp_base, sample_ppo_params(trial, int(hp_base["n_envs"])))
    run = dict(run_base, seed=seed, no_progress=True, no_tensorboard=True, verbose=0,
               save_freq=int(hp["n_timesteps"]))  # one checkpoint per trial, at the end
    run_dir = Path(out_dir) / "trials" / f"task_{int(index):04d}_trial_{trial.number:04d}"
    run_dir.mkdir(parents=True, exist_ok=True)
    n_eval = int(search["n_evaluations"])
    eval_every = max(int(hp["n_timesteps"]) // n_eval, 1)
    env_id = run["env"]

    def evaluate(model) -> float:
        policy = SB3Law(model, model.get_vec_normalize_env(),
                        obs_features=hp.get("obs_features"), history=hp.get("history"))
        res = rollout(env_id, policy, int(search["eval_states"]), _TUNE_SEED,
                      hp.get("env_kwargs"), trace_cases=0)
        return score(res.is_success, res.fuel_used_kg, res.touchdown_speed_m_s)

    cb = TrialEvalCallback(trial, evaluate, eval_every, n_eval)
    try:
        model, _ = train(hp, run, run_dir, callbacks=[cb])
        if cb.pruned:
            study.tell(trial, state=optuna.trial.TrialState.PRUNED)
            state, value = "PRUNED", cb.last
        else:
            value = evaluate(model) if cb.n_evals < n_eval else cb.last
            study.tell(trial, value)
            state = "COMPLETE"
    except Exception:
        study.tell(trial, state=optuna.trial.TrialState.FAIL)
        raise
    return {"index": int(index), "number": int(trial.number), "state": state,
            "value": float(value), "params": dict(trial.params), "hyperparams": hp,
            "run_dir": str(run_dir)}


def best_entry(env_id: str, hp: dict, trial: dict, search: dict) -> str:
    """The best trial's configuration as a Zoo YAML entry keyed by ``env_id`` (with a comment
    saying where it came from)."""
    head = (f"# train.py --optimize: best of {search['n_trials']} trials (trial "
            f"{trial['number']}, score {trial['value']:.4f} (agents.rl.search.score) on "
            f"{search['eval_states']} states, seed {_TUNE_SEED}, {hp['n_timesteps']} steps)\n")
    return head + yaml.safe_dump({env_id: hp}, sort_keys=True)


def optimize(hp: dict, run: dict, *, n_trials: int, sampler: str = "tpe",
             pruner: str = "median", n_startup_trials: int = 5, n_evaluations: int = 5,
             eval_states: int = 64, storage: str | None = None, study_name: str | None = None,
             out_dir: str | Path | None = None, address: str | None = None,
             workers: int | None = None, progress: bool = True) -> dict[str, Any]:
    """Run (or resume) a search; returns ``{"best", "trials", "out", "best_yml"}``.

    Raises
    ------
    ValueError
        Bad counts, an algorithm other than PPO, unknown sampler/pruner names.
    ImportError
        Optuna is not installed (``pip install -e ".[optuna]"``).
    """
    try:
        import optuna
    except ImportError:
        raise ImportError("train.py --optimize needs Optuna: pip install -e \".[optuna]\"") \
            from None
    from agents.common.runs import next_run_dir, write_text_atomic
    from optimizers.common.executor import ResultStore, Task, TaskKey, get_executor, run_tasks

    if run["algo"] != "ppo":
        raise ValueError(f"--optimize samples PPO hyperparameters; algo = {run['algo']!r} is "
                         "not supported yet")
    for name, v in dict(n_trials=n_trials, n_evaluations=n_evaluations,
                        eval_states=eval_states).items():
        if int(v) < 1:
            raise ValueError(f"{name} = {v!r} must be >= 1")
    _sampler(sampler, 0, 1), _pruner(pruner, 1, 1)  # validate the names here, not in a worker
    out = Path(out_dir) if out_dir else next_run_dir(Path(run.get("log_folder") or "runs")
                                                     / "optimize", run["env"])
    out.mkdir(parents=True, exist_ok=True)
    storage_url = storage or str(out / "study.journal")
    study_name = study_name or f"{run['env']}-ppo"
    search = {"sampler": sampler, "pruner": pruner, "n_startup_trials": int(n_startup_trials),
              "n_evaluations": int(n_evaluations), "eval_states": int(eval_states),
              "n_trials": int(n_trials)}
    study = optuna.create_study(study_name=study_name, storage=make_storage(storage_url),
                                direction="maximize", load_if_exists=True)
    # trials left RUNNING by an interrupted driver never finish: mark them failed
    for t in study.get_trials(states=(optuna.trial.TrialState.RUNNING,)):
        study._storage.set_trial_state_values(t._trial_id, optuna.trial.TrialState.FAIL)
    identity = {"env": run["env"], "algo": run["algo"], "hp_base": hp, "seed": run["seed"],
                "study_name": study_name, "search": {k: v for k, v in search.items()
                                                     if k != "n_trials"}}
    store = ResultStore(out / "tasks", identity)
    write_text_atomic(out / "search.yml", yaml.safe_dump(
        {"search": search, "storage": storage_url, "study_name": study_name, "base": hp,
         "run": {k: v for k, v in run.items() if isinstance(v, str | int | float | bool)}},
        sort_keys=True))
    run_base = {k: run[k] for k in ("algo", "env", "seed", "device", "torch_threads")
                if k in run}
    tasks = [Task(TaskKey(f"optuna-{study_name}", int(run["seed"]), i), run_trial,
                  (storage_url, study_name, i, copy.deepcopy(hp), run_base, str(out), search))
             for i in range(int(n_trials))]
    with get_executor(address, workers) as ex:
        print(f"Optuna search {study_name!r}: {n_trials} trials of {hp['n_timesteps']} steps on "
              f"{ex.describe()}; storage {storage_url}; out {out}", flush=True)
        results, _ = run_tasks(tasks, ex, store, progress="trials" if progress else False)
    trials = sorted(results.values(), key=lambda r: r["index"])
    complete = [t for t in trials if t["state"] == "COMPLETE"]
    if not complete:
        raise RuntimeError(f"no trial completed ({len(trials)} pruned or failed); see {out}")
    best = max(complete, key=lambda t: t["value"])
    best_hp = copy.deepcopy(best["hyperparams"])
    best_yml = out / "best.yml"
    write_text_atomic(best_yml, best_entry(run["env"], best_hp, best, search))
    lines = ["| task | trial | state | score | " + " | ".join(sorted(best["params"])) + " |",
             "|---" * (4 + len(best["params"])) + "|"]
    for t in trials:
        vals = " | ".join(f"{t['params'].get(k, '')}" if not isinstance(t["params"].get(k), float)
                          else f"{t['params'][k]:.3g}" for k in sorted(best["params"]))
        lines.append(f"| {t['index']} | {t['number']} | {t['state']} | {t['value']:.4f} | "
                     f"{vals} |")
    table = "\n".join(lines)
    write_text_atomic(out / "trials.md", table + "\n")
    print()
    print(table)
    print()
    print(f"Best: trial {best['number']} (task {best['index']}), score {best['value']:.4f}; "
          f"entry written to {best_yml}\nTrain it: python train.py --hyperparams-file "
          f"{best_yml}")
    return {"best": best, "trials": trials, "out": str(out), "best_yml": str(best_yml)}
