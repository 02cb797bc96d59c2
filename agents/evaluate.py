"""Command line of the evaluation: ``python -m agents.evaluate``.

::

    python -m agents.evaluate --model runs/ppo/LunarSoftLanding-v0_1          # + baselines
    python -m agents.evaluate --model a/model.zip --model b/ --n-states 200 --out results/cmp
    python -m agents.evaluate --no-open-loop --expert-states 0 --model runs/ppo/...
    python -m agents.evaluate --laws apollo zem-zev gravity-turn apollo:kr=9,tgo_margin=0.02
    python -m agents.evaluate --env LunarPinpointLanding-v2 --env-kwargs \
        '{"throttle_channel": true}' --laws apollo zem-zev --n-states 200

``--laws`` takes law specs ``NAME[:ARG][:KEY=VALUE,...]`` (:mod:`guidance.registry`;
the explicit laws' options: :mod:`guidance.laws.apollo_specs`), flown beside the models.

What is flown and measured: :mod:`guidance.evaluation.compare`.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from agents.laws import SB3Law
from guidance.evaluation.compare import (
    DEFAULT_ENV_ID,
    DEFAULT_N_STATES,
    DEFAULT_SEED,
    compare,
)
from guidance.evaluation.report import markdown_table, publish_report, write_report
from guidance.law import GuidanceLaw
from guidance.registry import LawContext, build_law, law_names, parse_law_spec
from optimizers.common.cli import (
    check_env,
    count_type,
    output_dir_type,
    output_file_type,
    ray_address_type,
    seed_type,
    user_input_errors,
)

__all__ = ["main", "evaluate_run"]

#: largest --n-states, --expert-states and --trace-cases (each case is flown in one batch)
MAX_STATES = 1_000_000
#: largest --torch-threads and --optimum-workers
MAX_WORKERS = 1024


def evaluate_run(run_dir: str | Path, n_states: int = DEFAULT_N_STATES, seed: int = DEFAULT_SEED,
                 n_expert_states: int | None = None, open_loop: bool = True,
                 out_dir: str | Path | None = None) -> dict[str, Any]:
    """Evaluate a training run (its final model) against the baselines; print and save the table.

    Uses the run's env id and ``env_kwargs`` (from ``args.yml`` / ``config.yml``); writes into
    ``<run_dir>/evaluation`` unless ``out_dir`` is given.
    """
    from agents.common.runs import read_run

    run_dir = Path(run_dir)
    args, hp = read_run(run_dir)
    env_id = args["env"]
    law = SB3Law.from_path(run_dir, name=f"{args['algo'].upper()} ({run_dir.name})")
    report = compare(env_id, [law], n_states=n_states, seed=seed,
                     env_kwargs=hp.get("env_kwargs"), open_loop=open_loop,
                     n_expert_states=n_expert_states)
    paths = write_report(report, out_dir or run_dir / "evaluation")
    print()
    print(f"## {env_id}: {n_states} dispersed initial states (seed {seed})")
    print()
    print(markdown_table(report))
    print()
    print("Written: " + ", ".join(str(p) for p in paths.values()))
    return report


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
    p.add_argument("--laws", nargs="+", default=[], metavar="SPEC",
                   help="guidance laws by spec, NAME[:ARG][:KEY=VALUE,...] (e.g. apollo "
                        "zem-zev:kr=8 gravity-turn); known names: "
                        + ", ".join(law_names()))
    p.add_argument("--n-states", type=count_type(1, MAX_STATES), default=DEFAULT_N_STATES,
                   help=f"dispersed initial states, 1 to {MAX_STATES} (default "
                        f"{DEFAULT_N_STATES})")
    p.add_argument("--seed", type=seed_type, default=DEFAULT_SEED,
                   help=f"seed of the initial states, 0 to 2**63 - 1 (default {DEFAULT_SEED})")
    p.add_argument("--expert-states", type=count_type(0, MAX_STATES), default=None,
                   help="cases flown by the env family's closed-loop expert (default: the "
                        "family's, 20 planar, 200 pinpoint; 0: skip)")
    p.add_argument("--no-open-loop", action="store_true", help="skip the open-loop replay")
    p.add_argument("--trace-cases", type=count_type(0, MAX_STATES), default=3)
    p.add_argument("--out", type=output_dir_type, default=None,
                   help="output directory (default results/evaluate)")
    p.add_argument("--json", type=output_file_type, default=None,
                   help="also write the JSON report to this file")
    p.add_argument("--torch-threads", type=count_type(1, MAX_WORKERS), default=1,
                   help="torch threads for SB3 inference (default 1, as in training)")
    p.add_argument("--optimum-workers", type=count_type(1, MAX_WORKERS), default=1,
                   help="processes for the per-case optimum (pinpoint: cached on disk)")
    p.add_argument("--address", type=ray_address_type, default=None,
                   help="Ray cluster for the per-case optima ('auto', 'host:port', "
                        "'local'); default $RAY_ADDRESS, else --optimum-workers local processes")
    args = p.parse_args(argv)
    import torch

    from agents.common.runs import read_run, run_dir_of

    torch.set_num_threads(args.torch_threads)

    env_id = args.env
    env_kwargs = None
    laws: list[GuidanceLaw] = []
    for m in args.model:
        with user_input_errors(p, prefix=f"--model {m}"):
            run_dir = run_dir_of(m)
            ra, hp = read_run(run_dir)
            laws.append(SB3Law.from_path(m))
        if ra:
            if env_id is None:
                env_id = ra["env"]
            if env_kwargs is None:
                env_kwargs = hp.get("env_kwargs")
        if len(args.model) > 1:
            laws[-1].name = f"{laws[-1].name} ({run_dir.name})"
    env_id = env_id or DEFAULT_ENV_ID
    if args.env_kwargs:
        import json as _json

        try:
            extra = _json.loads(args.env_kwargs)
        except ValueError as exc:
            p.error(f"--env-kwargs {args.env_kwargs!r} is not JSON ({exc})")
        if not isinstance(extra, dict):
            p.error(f"--env-kwargs {args.env_kwargs!r} must be a JSON object")
        env_kwargs = {**(env_kwargs or {}), **extra}
    with user_input_errors(p):
        check_env(env_id, env_kwargs)
    if args.laws:
        laws += _laws_from_specs(p, args.laws, env_id, env_kwargs)
    import os

    from optimizers.common.executor import RAY_ADDRESS_ENV, get_executor

    executor = None
    if args.address or os.environ.get(RAY_ADDRESS_ENV) or args.optimum_workers > 1:
        executor = get_executor(args.address, args.optimum_workers)
    try:
        report = compare(env_id, laws, n_states=args.n_states, seed=args.seed,
                         env_kwargs=env_kwargs, open_loop=not args.no_open_loop,
                         n_expert_states=args.expert_states, trace_cases=args.trace_cases,
                         optimum_workers=args.optimum_workers, optimum_executor=executor)
    finally:
        if executor is not None:
            executor.close()
    publish_report(report, args.out or Path("results") / "evaluate", args.json)
    return 0


def _laws_from_specs(parser: argparse.ArgumentParser, specs: list[str], env_id: str,
                     env_kwargs: dict | None) -> list[GuidanceLaw]:
    """The laws of ``--laws`` (a bad spec is a usage error naming it). Laws that need the
    per-case optimum (``open-loop``) are refused: :func:`compare` flies it itself."""
    import gymnasium as gym

    import lunar_env  # noqa: F401  (registers the env ids)

    env = gym.make(env_id, **(env_kwargs or {}))
    try:
        context = LawContext(env_id=env_id, env_kwargs=dict(env_kwargs or {}),
                             scenario=env.unwrapped.scenario)
    finally:
        env.close()
    laws = []
    for text in specs:
        try:
            spec = parse_law_spec(text)
            laws.append(build_law(spec, context))
        except ValueError as exc:
            parser.error(f"--laws {text!r}: {exc}")
    return laws



if __name__ == "__main__":
    raise SystemExit(main())
