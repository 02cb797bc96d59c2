"""Train a Stable-Baselines3 policy on a lunar-descent environment with one command.

::

    python train.py                                   # PPO, LunarSoftLanding-v0, shipped config,
                                                      # then the comparison table vs the optimum
    python train.py --quick                           # the few-thousand-step CI configuration
    python train.py --algo sac --env LunarPinpointLanding-v0 --seed 3
    python train.py --algo recurrent-ppo --env LunarPinpointLanding-v2   # LSTM policy (sb3-contrib)
    python train.py --env LunarPinpointLanding-v2 --history 8     # last 8 inputs and actions
    python train.py -n 200000 --hyperparams n_steps=512 policy_kwargs.activation_fn=relu
    python train.py --resume runs/ppo/LunarSoftLanding-v0_1   # continue an interrupted run
    python train.py --optimize --n-trials 40 -n 500000         # Optuna search (agents.rl.search)

Layout follows the RL Baselines3 Zoo: hyperparameters come from ``agents/hyperparams/<algo>.yml``
keyed by env id (``--config quick`` / ``--quick`` selects the ``<env id>@quick`` profile), and
command-line flags override them. Each run directory ``<log-folder>/<algo>/<env id>_<k>/`` holds

- ``config.yml`` (the hyperparameters actually used), ``args.yml`` (every argument, including the
  seed drawn when none was given), ``command.txt`` (the command line);
- ``checkpoints/rl_model_<steps>_steps.zip`` with ``rl_model_vecnormalize_<steps>_steps.pkl``
  (and the replay buffer for SAC/TD3), written at rollout boundaries;
- ``tb/`` TensorBoard logs, ``model.zip`` and ``vecnormalize.pkl`` (the final model);
- ``evaluation/`` the comparison against the optimiser baselines (``agents.evaluate``).

Agents-side additions selected by YAML keys of the entry (recorded in ``config.yml``):
``curriculum`` (start states from optimal trajectories, :mod:`agents.rl.curriculum`),
``obs_features`` (derived inputs appended to the observation, :mod:`agents.features`;
re-applied
by :class:`agents.laws.SB3Law` when a run is loaded) and ``reward_shaping``
(potential-based, policy-invariant, training only, :mod:`agents.rl.shaping`). The env's own
observation and reward are never changed.

Memory: ``--algo recurrent-ppo`` trains sb3-contrib's ``RecurrentPPO`` (an LSTM policy; the
``memory`` extra; :mod:`agents.common.recurrent`) from ``agents/hyperparams/recurrent-ppo.yml``;
``history: k`` (YAML) or ``--history k`` gives any policy its last k inputs and actions
(:mod:`agents.features.history`). Both are recorded in the run and restored when it is loaded
as a law (:class:`agents.laws.SB3Law`), by the evaluation and by campaigns.

Training runs on the natively batched vector env (all landers stepped in one call of the dynamics
core) through the SB3 adapter :func:`agents.common.vec_env.make_sb3_vec_env`, not on a
``SubprocVecEnv`` of single envs. Envs that are not ours (any other Gymnasium id) fall back to
SB3's ``make_vec_env``.

Resuming: ``--resume RUN_DIR`` reloads the newest checkpoint (model, optimiser state,
``VecNormalize`` statistics, replay buffer, timestep counter) and continues with
``reset_num_timesteps=False`` until the run's ``n_timesteps``; an interrupted run (Ctrl-C or
SIGTERM) writes a checkpoint before exiting. Checkpoints are taken between rollouts, after the
algorithm trained on the last one, so every counted step is trained on exactly once (a SIGKILL
loses at most the steps since the last checkpoint); the learning-rate schedule continues where it
stopped.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.common.runs import (
    MAX_SB3_SEED,
    claim_run_dir,
    load_trained,
    next_run_dir,
    read_run,
    resumable_checkpoint,
    write_text_atomic,
)
from agents.features.history import MAX_HISTORY, validate_history
from agents.hyperparams import (
    ALGOS,
    apply_overrides,
    default_hyperparams_path,
    load_hyperparams,
    parse_override,
    resolve_algo_kwargs,
)
from agents.rl.race import race_pending, race_trained_to_end, seed_race
from agents.rl.training import DEFAULT_ENV_ID, make_training_env, train
from optimizers.common.cli import (
    check_env,
    count_type,
    input_path_type,
    output_dir_type,
    ray_address_type,
    seed_type,
    user_input_errors,
)

__all__ = ["main", "build_parser", "train", "make_training_env", "load_trained", "next_run_dir",
           "DEFAULT_ENV_ID"]


#: largest env-step count (-n, --save-freq, --summary-every)
MAX_STEPS = 10**12
#: largest count of states, trials, envs, threads and workers
MAX_STATES = 1_000_000
MAX_WORKERS = 1024


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="train.py",
        description="Train an SB3 agent (PPO by default) on a lunar-descent env, then compare it "
                    "with the optimiser baselines.")
    p.add_argument("--algo", default="ppo", choices=ALGOS, help="RL algorithm (default: ppo)")
    p.add_argument("--env", default=DEFAULT_ENV_ID, help=f"env id (default: {DEFAULT_ENV_ID})")
    p.add_argument("--hyperparams-file", "--conf-file", dest="hyperparams_file", default=None,
                   type=input_path_type,
                   help="Zoo-style YAML keyed by env id (default: agents/hyperparams/<algo>.yml)")
    p.add_argument("--config", default="default",
                   help="profile of the YAML entry: 'default' or e.g. 'quick' (<env>@quick)")
    p.add_argument("--quick", action="store_true", help="same as --config quick")
    p.add_argument("--hyperparams", "-params", nargs="+", default=[], metavar="KEY=VALUE",
                   help="override hyperparameters (values parsed as YAML; dotted keys nest)")
    p.add_argument("-n", "--n-timesteps", type=count_type(1, MAX_STEPS), default=None,
                   help="override n_timesteps")
    p.add_argument("--n-envs", type=count_type(1, MAX_WORKERS), default=None,
                   help="override n_envs")
    p.add_argument("--history", type=count_type(1, MAX_HISTORY), default=None, metavar="K",
                   help=f"give the policy its last K inputs and actions, 1 to {MAX_HISTORY} "
                        "(overrides the entry's history)")
    p.add_argument("--seed", type=count_type(0, MAX_SB3_SEED), default=None,
                   help=f"random seed, 0 to {MAX_SB3_SEED} (default: drawn and recorded in "
                        "args.yml)")
    p.add_argument("--log-folder", "-f", type=output_dir_type, default="runs",
                   help="parent of the run directories")
    p.add_argument("--run-dir", type=output_dir_type, default=None,
                   help="explicit run directory (must not exist)")
    p.add_argument("--resume", type=input_path_type, default=None, metavar="RUN_DIR",
                   help="continue the run in RUN_DIR from its newest checkpoint")
    p.add_argument("--init-from", type=input_path_type, default=None, metavar="MODEL",
                   help="start a new run from this model's policy weights (run dir or .zip, "
                        "e.g. a behaviour-cloning run of agents.imitation) and its "
                        "VecNormalize statistics; to keep those fixed, as a fine-tuned policy "
                        "needs, set normalize.update=false")
    p.add_argument("--save-freq", type=count_type(1, MAX_STEPS), default=None,
                   help="checkpoint every this many env steps (default: n_timesteps/20)")
    p.add_argument("--device", default="cpu", help="torch device (default: cpu)")
    p.add_argument("--torch-threads", type=count_type(1, MAX_WORKERS), default=1,
                   help="torch intra-op threads (default 1: the env batch uses the other core)")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    p.add_argument("--no-tensorboard", action="store_true", help="do not write TensorBoard logs")
    p.add_argument("--eval-states", type=count_type(0, MAX_STATES), default=None,
                   help="dispersed initial states for the final comparison (0: skip; "
                        "default 1000, 16 with --quick)")
    p.add_argument("--eval-seed", type=seed_type, default=2026,
                   help="seed of the evaluation set of initial states")
    p.add_argument("--eval-expert-states", type=count_type(0, MAX_STATES), default=None,
                   help="states the (slow) closed-loop re-planning expert is run on "
                        "(default: agents.evaluate's default)")
    p.add_argument("--no-eval", action="store_true", help="same as --eval-states 0")
    p.add_argument("--verbose", "-v", type=count_type(0, 2), default=0,
                   help="SB3 verbosity (default 0: progress bar and a one-line summary every "
                        "5 %% of training; 1 adds SB3's full logger table after every rollout, "
                        "which TensorBoard always gets)")
    p.add_argument("--summary-every", type=count_type(0, MAX_STEPS), default=None,
                   metavar="STEPS",
                   help="env steps between console summary lines (default n_timesteps/20; "
                        "0: none)")
    o = p.add_argument_group("hyperparameter search (Optuna on the executor; agents.rl.search)")
    o.add_argument("--optimize", "--optimize-hyperparameters", "-optimize", action="store_true",
                   help="search PPO hyperparameters instead of training once; writes the best "
                        "as a YAML entry (<log-folder>/optimize/<env>_<k>/best.yml)")
    o.add_argument("--n-trials", type=count_type(1, MAX_STATES), default=20,
                   help="trials (default 20)")
    o.add_argument("--sampler", default="tpe", choices=("tpe", "random"))
    o.add_argument("--pruner", default="median", choices=("median", "halving", "none"))
    o.add_argument("--n-startup-trials", type=count_type(0, MAX_STATES), default=5,
                   help="random trials before TPE, and trials before the pruner acts")
    o.add_argument("--n-evaluations", type=count_type(1, MAX_STATES), default=5,
                   help="evaluations (pruning points) per trial")
    o.add_argument("--tune-states", type=count_type(1, MAX_STATES), default=64,
                   help="dispersed initial states each evaluation flies")
    o.add_argument("--storage", default=None,
                   help="Optuna storage: RDB URL or journal file (default <out>/study.journal)")
    o.add_argument("--study-name", default=None)
    o.add_argument("--address", type=ray_address_type, default=None,
                   help="Ray cluster for the trials ('auto', 'host:port', 'local'); default "
                        "$RAY_ADDRESS, else a local process pool")
    o.add_argument("--workers", type=count_type(0, MAX_WORKERS), default=None,
                   help="local processes for the trials (default: all cores)")
    return p


# ----------------------------------------------------------------------------- environments


# ----------------------------------------------------------------------------- training


def _quick_expert_states(env_id: str, env_kwargs: dict[str, Any] | None) -> int:
    """Cases the closed-loop expert flies in a quick run's evaluation: the family's
    ``quick_expert_cases`` (2; none on ``LunarPinpointLanding-v3``, whose re-planned landing
    costs ~1 min), at most its ``default_expert_cases`` (its full default, 20 or 200
    re-planned flights, would outlast the quick training). Other Gymnasium ids: 2 (the
    evaluation refuses them anyway)."""
    import gymnasium as gym

    import lunar_env  # noqa: F401  (registers the ids)
    from guidance.laws.baselines import BASELINE_FAMILIES

    env = gym.make(env_id, **(env_kwargs or {}))  # checked by check_env before
    try:
        scenario = getattr(env.unwrapped, "scenario", None)
    finally:
        env.close()
    if scenario is None or getattr(scenario, "family", None) not in BASELINE_FAMILIES.names():
        return 2
    family = BASELINE_FAMILIES.get(scenario.family)
    quick = int(family.quick_expert_cases)
    default = family.default_expert_cases
    return quick if default is None else min(quick, int(default))


def _resolve_args(args: argparse.Namespace) -> tuple[dict[str, Any], dict[str, Any]]:
    """Merge YAML, profile and CLI overrides; return (hyperparameters, run arguments)."""
    profile = "quick" if args.quick else args.config
    hp_file = args.hyperparams_file or str(default_hyperparams_path(args.algo))
    check_env(args.env)
    hp = load_hyperparams(hp_file, args.env, profile)
    overrides = dict(parse_override(t) for t in args.hyperparams)
    if args.n_timesteps is not None:
        overrides["n_timesteps"] = args.n_timesteps
    if args.n_envs is not None:
        overrides["n_envs"] = args.n_envs
    if args.history is not None:
        overrides["history"] = args.history
    hp = apply_overrides(hp, overrides)
    for key in ("n_timesteps", "n_envs"):
        if key not in hp:
            raise ValueError(f"{hp_file}: entry {args.env!r} lacks {key!r}")
    if args.init_from and "obs_features" not in overrides:
        # The initial policy fixes the network's inputs: a run fine-tuned from it observes what
        # it observed (e.g. a behaviour-cloning policy trained on the env's raw observation).
        init_hp = read_run(args.init_from)[1]
        init_feats = list(init_hp.get("obs_features") or [])
        if list(hp.get("obs_features") or []) != init_feats:
            print(f"--init-from {args.init_from}: obs_features set to {init_feats} (those of the "
                  "initial policy)")
            hp["obs_features"] = init_feats
    if args.init_from and "history" not in overrides:
        # so does its history: the stacked inputs are the network's first layer
        init_history = read_run(args.init_from)[1].get("history")
        if hp.get("history") != init_history:
            print(f"--init-from {args.init_from}: history set to {init_history} (that of the "
                  "initial policy)")
            hp["history"] = init_history
    if hp.get("added_action_init") is not None and not args.init_from:
        raise ValueError(f"added_action_init={hp['added_action_init']!r} fills the action "
                         "channels an --init-from policy lacks: give --init-from, or drop it")
    hp["n_timesteps"] = int(float(hp["n_timesteps"]))
    hp["n_envs"] = int(hp["n_envs"])
    if hp["n_timesteps"] < 1:
        raise ValueError(f"n_timesteps={hp['n_timesteps']} must be >= 1")
    if hp["n_envs"] < 1:
        raise ValueError(f"n_envs={hp['n_envs']} must be >= 1")
    # the algorithm's arguments (names resolved, removed keys refused) before any run directory
    resolve_algo_kwargs(hp, args.algo, n_actions=1)
    check_env(args.env, hp.get("env_kwargs"))
    if hp.get("obs_features"):
        from agents.features import validate_features

        validate_features(hp["obs_features"])
    hp["history"] = validate_history(hp.get("history"))
    if hp["history"] is None:
        del hp["history"]  # a run without history records none
    run = dict(vars(args))
    run["config"] = profile
    if run["eval_states"] is None:
        run["eval_states"] = 16 if profile == "quick" else 1000
    if run["eval_expert_states"] is None and profile == "quick":
        run["eval_expert_states"] = _quick_expert_states(args.env, hp.get("env_kwargs"))
    run["hyperparams_file"] = hp_file
    if run["seed"] is None:
        run["seed"] = int(np.random.default_rng().integers(0, 2**31 - 1))
    return hp, run


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point (``python train.py``, ``python -m agents.train``)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    argv_list = list(sys.argv[1:] if argv is None else argv)
    if args.resume:
        run_dir = Path(args.resume)
        if not (run_dir / "args.yml").exists() or not (run_dir / "config.yml").exists():
            parser.error(f"--resume {run_dir}: not a run directory (args.yml/config.yml missing)")
        run, hp = read_run(run_dir)
        # validate before anything is rewritten (a failed resume changes nothing); a run still
        # in its seed race resumes its candidates from their own checkpoints instead
        if not race_pending(hp, run_dir):
            try:
                resumable_checkpoint(run_dir, needs_vecnormalize=bool(hp.get("normalize")),
                                     log=lambda msg: None)
            except FileNotFoundError as exc:
                parser.error(f"--resume {run_dir}: {exc}")
        if args.n_timesteps is not None:  # allow extending a finished run
            hp["n_timesteps"] = int(args.n_timesteps)
        for key in ("no_progress", "no_eval", "eval_states", "eval_expert_states"):
            if f"--{key.replace('_', '-')}" in argv_list:
                run[key] = getattr(args, key)

        def on_resumed(run_dir=run_dir, hp=hp):
            # written only once the checkpoint has loaded: a failed resume changes nothing
            if args.n_timesteps is not None:
                write_text_atomic(run_dir / "config.yml", yaml.safe_dump(hp, sort_keys=True))
            cmd_file = run_dir / "command.txt"
            command = cmd_file.read_text() if cmd_file.exists() else ""
            write_text_atomic(cmd_file, command + shlex.join([sys.executable, *sys.argv]) + "\n")

        resume = True
    elif args.optimize:
        from agents.rl.search import optimize

        with user_input_errors(parser):
            hp, run = _resolve_args(args)
        try:
            optimize(hp, run, n_trials=args.n_trials, sampler=args.sampler, pruner=args.pruner,
                     n_startup_trials=args.n_startup_trials, n_evaluations=args.n_evaluations,
                     eval_states=args.tune_states, storage=args.storage,
                     study_name=args.study_name, out_dir=args.run_dir, address=args.address,
                     workers=args.workers, progress=not args.no_progress)
        except KeyboardInterrupt:
            print("\nInterrupted; rerun the same command (with --run-dir of this search) to "
                  "continue: finished trials are kept.", file=sys.stderr)
            return 130
        return 0
    else:
        with user_input_errors(parser):
            hp, run = _resolve_args(args)
        if args.run_dir:
            try:  # claimed atomically: two processes never share an explicit --run-dir
                run_dir = claim_run_dir(args.run_dir)
            except FileExistsError as exc:
                parser.error(str(exc))
        else:  # created atomically: concurrent runs never share a directory
            run_dir = next_run_dir(Path(args.log_folder) / args.algo, args.env)
        run["run_dir"] = str(run_dir)
        write_text_atomic(run_dir / "config.yml", yaml.safe_dump(hp, sort_keys=True))
        write_text_atomic(run_dir / "args.yml", yaml.safe_dump(run, sort_keys=True))
        write_text_atomic(run_dir / "command.txt", shlex.join([sys.executable, *sys.argv]) + "\n")
        resume = False
        on_resumed = None
    print(f"Run directory: {run_dir}  (algo={run['algo']}, env={run['env']}, "
          f"config={run['config']}, seed={run['seed']})")
    try:
        if race_pending(hp, run_dir):
            # a few seeds side by side to the end; the winner's final policy is the run's
            run = seed_race(hp, run, run_dir)
            resume = True
        if not race_trained_to_end(hp, run_dir):
            train(hp, run, run_dir, resume=resume, on_resumed=on_resumed)
    except KeyboardInterrupt:
        if race_pending(hp, run_dir):
            print(f"\nInterrupted during the seed race; continue with: python train.py "
                  f"--resume {run_dir}", file=sys.stderr)
        return 130
    n_eval = 0 if run.get("no_eval") else int(run.get("eval_states") or 0)
    if n_eval > 0:
        from agents.evaluate import evaluate_run

        evaluate_run(run_dir, n_states=n_eval, seed=int(run.get("eval_seed", 2026)),
                     n_expert_states=run.get("eval_expert_states"))
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    raise SystemExit(main())
