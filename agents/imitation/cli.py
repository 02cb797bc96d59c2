"""Command line of the imitation room: ``python -m agents.imitation bc|dagger|evaluate``.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.common.runs import MAX_SB3_SEED, write_text_atomic
from agents.imitation.bc import _new_run_dir, train_bc
from agents.imitation.dagger import train_dagger
from optimizers.common.cli import (
    check_env,
    count_type,
    input_path_type,
    output_dir_type,
    output_file_type,
    seed_type,
    user_input_errors,
)

DEFAULT_ENV_ID = "LunarSoftLanding-v0"
_HP_FILE = Path(__file__).parents[1] / "hyperparams" / "imitation.yml"
#: largest --n-states, --expert-states and --eval-states
MAX_STATES = 1_000_000
#: largest --torch-threads
MAX_THREADS = 1024


# ----------------------------------------------------------------------------- CLI


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m agents.imitation",
                                description="Behaviour cloning and DAgger from optimal landings.")
    sub = p.add_subparsers(dest="mode", required=True)
    for mode in ("bc", "dagger"):
        s = sub.add_parser(mode, help=f"train by {mode.upper()}")
        s.add_argument("--env", default=DEFAULT_ENV_ID)
        s.add_argument("--dataset", default=None,
                       help="dataset .npz (lunar dataset), or minari:<dataset id> "
                            "for a Minari dataset of the env")
        s.add_argument("--hyperparams-file", type=input_path_type, default=str(_HP_FILE))
        s.add_argument("--config", default="default", help="profile: default or e.g. quick")
        s.add_argument("--quick", action="store_true", help="same as --config quick")
        s.add_argument("--hyperparams", "-params", nargs="+", default=[], metavar="KEY=VALUE")
        s.add_argument("--seed", type=count_type(0, MAX_SB3_SEED), default=None,
                       help=f"random seed, 0 to {MAX_SB3_SEED} (default: drawn)")
        s.add_argument("--log-folder", "-f", type=output_dir_type, default="runs")
        s.add_argument("--run-dir", type=output_dir_type, default=None)
        s.add_argument("--resume", type=input_path_type, default=None, metavar="RUN_DIR")
        s.add_argument("--device", default="cpu")
        s.add_argument("--torch-threads", type=count_type(1, MAX_THREADS), default=1)
        s.add_argument("--no-progress", action="store_true")
        s.add_argument("--no-tensorboard", action="store_true")
        s.add_argument("--eval-states", type=count_type(0, MAX_STATES), default=0,
                       help="evaluate the final policy on this many dispersed states "
                            "(agents.evaluate; 0: skip)")
        s.add_argument("--eval-seed", type=seed_type, default=2026)
        if mode == "dagger":
            s.add_argument("--init", type=input_path_type, default=None,
                           help="initial policy (BC run dir or PPO zip); default: BC first")
    e = sub.add_parser("evaluate", help="compare policies with agents.evaluate")
    e.add_argument("--env", default=DEFAULT_ENV_ID)
    e.add_argument("--model", action="append", default=[], metavar="NAME=PATH",
                   help="policy name and run dir / zip (repeatable)")
    e.add_argument("--n-states", type=count_type(1, MAX_STATES), default=1000)
    e.add_argument("--seed", type=seed_type, default=2026)
    e.add_argument("--expert-states", type=count_type(0, MAX_STATES), default=None,
                   help="cases flown by the env family's closed-loop expert (default: the "
                        "family's, 20 planar, 200 pinpoint; 0: skip)")
    e.add_argument("--no-open-loop", action="store_true")
    e.add_argument("--out", type=output_dir_type, default="results/imitation")
    e.add_argument("--json", type=output_file_type, default=None)
    return p


def _resolve(args) -> tuple[dict[str, Any], dict[str, Any]]:
    from agents.hyperparams import apply_overrides, load_hyperparams, parse_override

    profile = "quick" if args.quick else args.config
    hp = load_hyperparams(args.hyperparams_file, args.env, profile)
    hp = apply_overrides(hp, dict(parse_override(t) for t in args.hyperparams))
    for key in ("policy_kwargs", "bc") + (("dagger",) if args.mode == "dagger" else ()):
        if key not in hp:
            raise ValueError(f"{args.hyperparams_file}: entry {args.env!r} lacks {key!r}")
    run = {k: v for k, v in vars(args).items()}
    run["config"] = profile
    run["algo"] = "ppo"  # the saved model is a PPO zip (agents.evaluate / train.py read this)
    if run["seed"] is None:
        run["seed"] = int(np.random.default_rng().integers(0, 2**31 - 1))
    return hp, run


def _run_env_kwargs(path: str | Path, env_id: str) -> dict[str, Any]:
    """The run's ``env_kwargs`` without entries equal to the env's defaults (so that runs with
    ``{}`` and ``{dt_s: 1.0}`` share one env configuration)."""
    import gymnasium as gym

    import lunar_env  # noqa: F401
    from agents.common.runs import read_run

    kw = dict(read_run(path)[1].get("env_kwargs") or {})
    env = gym.make(env_id, **kw)
    defaults = env.unwrapped.task_defaults()
    env.close()
    return {k: v for k, v in kw.items() if not (k in defaults and defaults[k] == v)}


def _evaluate_cli(args, parser: argparse.ArgumentParser) -> int:
    """Compare named policies with :func:`guidance.evaluation.compare.compare`.

    Policies trained with different env settings (e.g. PPO's 5 s decisions, imitation's 1 s)
    each fly their own env configuration from the same seeded initial states (the dispersion
    draw does not depend on the step length); one :func:`compare` call per configuration, rows
    merged into one table. The optimiser baselines (open-loop replay, closed-loop expert) run
    with the first configuration; the open-loop replay also with every other one.
    """
    from agents.laws import SB3Law
    from guidance.evaluation.compare import compare
    from guidance.evaluation.report import publish_report

    groups: dict[str, tuple[dict[str, Any], list]] = {}
    with user_input_errors(parser):
        check_env(args.env)
    for item in args.model:
        if "=" not in item:
            parser.error(f"--model {item!r}: expected NAME=PATH")
        name, path = item.split("=", 1)
        with user_input_errors(parser, prefix=f"--model {item}"):
            kw = _run_env_kwargs(path, args.env)
            law = SB3Law.from_path(path, name=name)
        key = json.dumps(kw, sort_keys=True)
        groups.setdefault(key, (kw, []))[1].append(law)
    if not groups:
        groups["{}"] = ({}, [])
    reports = []
    for g, (kw, pols) in enumerate(groups.values()):
        rep = compare(args.env, pols, n_states=args.n_states, seed=args.seed, env_kwargs=kw,
                      open_loop=not args.no_open_loop,
                      n_expert_states=args.expert_states if g == 0 else 0)
        if len(groups) > 1:
            tag = ", ".join(f"{k}={v}" for k, v in sorted(kw.items())) or "env defaults"
            for row, res in zip(rep["rows"], rep["results"], strict=True):
                row["policy"] = f"{row['policy']} [{tag}]"
                res.name = row["policy"]
        reports.append(rep)
    report = dict(reports[0])
    report["rows"] = [r for rep in reports for r in rep["rows"]]
    report["results"] = [r for rep in reports for r in rep["results"]]
    report["env_kwargs_groups"] = [kw for kw, _ in groups.values()]
    publish_report(report, args.out, args.json)
    return 0


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point (``python -m agents.imitation``)."""
    import torch as th

    parser = build_parser()
    args = parser.parse_args(argv)
    if args.mode == "evaluate":
        return _evaluate_cli(args, parser)
    th.set_num_threads(args.torch_threads)
    argv_list = list(sys.argv[1:] if argv is None else argv)
    if args.resume:
        run_dir = Path(args.resume)
        if not (run_dir / "args.yml").exists():
            parser.error(f"--resume {run_dir}: not a run directory (args.yml missing)")
        run = yaml.safe_load((run_dir / "args.yml").read_text())
        hp = yaml.safe_load((run_dir / "config.yml").read_text())
        if run["mode"] != args.mode:
            parser.error(f"--resume {run_dir}: it is a {run['mode']} run, not {args.mode}")
        run["no_progress"] = args.no_progress
        cmd_file = run_dir / "command.txt"
        write_text_atomic(cmd_file, (cmd_file.read_text() if cmd_file.exists() else "")
                          + shlex.join([sys.executable, "-m", "agents.imitation", *argv_list])
                          + "\n")
        resume = True
    else:
        if args.dataset is None:
            parser.error("--dataset is required (make one with lunar dataset)")
        from agents.imitation.sources import open_dataset, run_env_kwargs

        with user_input_errors(parser):
            check_env(args.env)
            hp, run = _resolve(args)
            dataset = open_dataset(args.dataset)
            if dataset.meta["env_id"] != args.env:
                raise ValueError(f"--dataset {args.dataset} is for {dataset.meta['env_id']!r}, "
                                 f"not --env {args.env!r}")
            # the dataset's env arguments, with the entry's env_kwargs (a profile's or
            # --hyperparams env_kwargs.KEY=VALUE) over them: saved in config.yml, so that the
            # roll-outs, the selection and every later load of the run fly the same env
            hp["env_kwargs"] = run_env_kwargs(args.env, dataset.meta.get("env_kwargs"),
                                              hp.get("env_kwargs"))
            if args.mode == "dagger":  # the teacher, before a run directory exists
                from agents.imitation.families import IMITATION_FAMILIES
                from agents.imitation.teachers import parse_teacher
                from lunar_env import get_scenario

                IMITATION_FAMILIES.of(get_scenario(dataset.meta["scenario"])).check_teacher(
                    parse_teacher(hp["dagger"].get("teacher")))
            from agents.imitation.policy import imitation_history

            imitation_history(hp, args.mode)  # a history the run cannot take, refused here
        from agents.common.runs import claim_run_dir

        try:  # both created atomically: concurrent runs never share a directory
            run_dir = (claim_run_dir(args.run_dir) if args.run_dir
                       else _new_run_dir(args.log_folder, args.mode, args.env))
        except FileExistsError as exc:
            parser.error(str(exc))
        run["run_dir"] = str(run_dir)
        write_text_atomic(run_dir / "config.yml", yaml.safe_dump(hp, sort_keys=True))
        write_text_atomic(run_dir / "args.yml", yaml.safe_dump(run, sort_keys=True))
        write_text_atomic(run_dir / "command.txt",
                          shlex.join([sys.executable, "-m", "agents.imitation", *argv_list])
                          + "\n")
        resume = False
    print(f"Run directory: {run_dir}  (mode={run['mode']}, env={run['env']}, "
          f"config={run['config']}, seed={run['seed']})")
    if run["mode"] == "bc":
        train_bc(hp, run, run_dir, resume=resume)
    else:
        train_dagger(hp, run, run_dir, resume=resume)
    n_eval = int(run.get("eval_states") or 0)
    if n_eval > 0:
        from agents.evaluate import evaluate_run

        evaluate_run(run_dir, n_states=n_eval, seed=int(run.get("eval_seed", 2026)))
    return 0
