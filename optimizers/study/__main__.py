"""``python -m optimizers.study ALGORITHM PROBLEM --runs N [--address ...]`` (see the package)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..common.cli import (
    MAX_SEED,
    clean_interrupts,
    count_type,
    output_file_type,
    ray_address_type,
    seed_type,
    user_input_errors,
)
from ..common.lock import DirectoryBusy, DirectoryLock
from . import default_out, markdown_table, plot_study, run_study, study_identity
from .registry import ALGORITHMS, PROBLEMS, make_algorithm, make_problem, quick_settings

#: largest --runs (each run is a task held in memory until the study ends)
MAX_RUNS = 100_000
#: largest --workers
MAX_WORKERS = 1024


def _parse_sets(items: list[str], flag: str, parser) -> dict:
    import yaml

    out = {}
    for item in items:
        if "=" not in item:
            parser.error(f"{flag} {item!r}: expected KEY=VALUE")
        k, v = item.split("=", 1)
        out[k.strip()] = yaml.safe_load(v)
    return out


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point; Ctrl-C or SIGTERM at any point ends it with one line and
    status 130 / 143 (the runs finished so far stay stored)."""
    with clean_interrupts():
        return _main(argv)


def _main(argv: list[str] | None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m optimizers.study",
        description="N seeded runs of an optimiser on a problem, on a local process pool or a "
                    "Ray cluster: success rate, fuel gap to the certified optimum, wall time, a "
                    "plot; resumes after an interruption.")
    p.add_argument("algorithm", nargs="?", help=f"one of {sorted(ALGORITHMS)}")
    p.add_argument("problem", nargs="?", help=f"one of {sorted(PROBLEMS)}")
    p.add_argument("--runs", type=count_type(1, MAX_RUNS), default=None,
                   help=f"number of seeded runs, 1 to {MAX_RUNS} (default 10; quick 4)")
    p.add_argument("--seed", type=seed_type, default=0,
                   help=f"master seed, 0 to {MAX_SEED} (default 0)")
    p.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                   help="algorithm settings (values parsed as YAML), e.g. n_generations=1000")
    p.add_argument("--problem-set", nargs="*", default=[], metavar="KEY=VALUE",
                   help="problem arguments, e.g. n_steps=200")
    p.add_argument("--address", type=ray_address_type, default=None,
                   help="Ray cluster address ('auto', 'host:port', 'local' for a private "
                        "instance); default: $RAY_ADDRESS, else the local process pool")
    p.add_argument("--workers", type=count_type(0, MAX_WORKERS), default=None,
                   help="local pool processes (default: all cores; 0: in this process)")
    p.add_argument("--out", default=None, help="study directory (default "
                   "results/study/<algorithm>_<problem>_seed<seed>)")
    p.add_argument("--json", type=output_file_type, default=None,
                   help="also write the summary and rows to this file")
    p.add_argument("--quick", action="store_true",
                   help="smoke run: 4 runs with the algorithm's quick settings")
    p.add_argument("--no-certify", action="store_true",
                   help="skip the certified optimum and the DOP853 replays")
    p.add_argument("--no-plot", action="store_true")
    p.add_argument("--no-progress", action="store_true")
    p.add_argument("--list", action="store_true", help="list the algorithms and problems")
    args = p.parse_args(argv)
    if args.list:
        print("algorithms: " + ", ".join(sorted(ALGORITHMS)))
        print("problems:   " + ", ".join(sorted(PROBLEMS)))
        return 0
    if not args.algorithm or not args.problem:
        p.error("give ALGORITHM and PROBLEM (see --list)")
    if args.algorithm not in ALGORITHMS:
        p.error(f"unknown algorithm {args.algorithm!r}; available: {sorted(ALGORITHMS)}")
    if args.problem not in PROBLEMS:
        p.error(f"unknown problem {args.problem!r}; available: {sorted(PROBLEMS)}")
    n_runs = args.runs if args.runs is not None else (4 if args.quick else 10)
    settings = quick_settings(args.algorithm) if args.quick else {}
    settings.update(_parse_sets(args.set, "--set", p))
    problem_kwargs = _parse_sets(args.problem_set, "--problem-set", p)
    # the settings and problem arguments are built once here: an unknown key or a bad value is
    # a usage error (exit 2), not a traceback from inside the study
    with user_input_errors(p, errors=(TypeError,), prefix=f"--set {settings}"):
        make_algorithm(args.algorithm, **settings)
    with user_input_errors(p, errors=(TypeError,), prefix=f"--problem-set {problem_kwargs}"):
        make_problem(args.problem, **problem_kwargs)
    out = Path(args.out) if args.out is not None else default_out(
        args.algorithm, args.problem, args.seed, "_quick" if args.quick else "")
    # one writer per study directory, and a directory of another study refused, before any work
    with user_input_errors(p, errors=(DirectoryBusy, OSError), prefix=f"--out {out}"):
        lock = DirectoryLock(out, what="study").acquire()
    try:
        with user_input_errors(p, errors=(OSError,), prefix=f"--out {out}"):
            from ..common.store import ResultStore

            ResultStore(out, study_identity(args.algorithm, args.problem, seed=args.seed,
                                            settings=settings, problem_kwargs=problem_kwargs,
                                            certify_runs=not args.no_certify))
        return _run(p, args, n_runs, settings, problem_kwargs, out)
    finally:
        lock.release()


def _run(p, args, n_runs: int, settings: dict, problem_kwargs: dict, out: Path) -> int:
    from ..common.executor import get_executor

    with user_input_errors(p, errors=(ConnectionError, ImportError), prefix="--address"):
        ex = get_executor(args.address, args.workers)
    with ex, clean_interrupts(ex):
        print(f"{args.algorithm} on {args.problem}: {n_runs} runs on {ex.describe()}; results "
              f"stream to {out}/results/", flush=True)
        study = run_study(args.algorithm, args.problem, n_runs, seed=args.seed,
                          settings=settings, problem_kwargs=problem_kwargs, executor=ex,
                          out=out, certify_runs=not args.no_certify,
                          progress=not args.no_progress)
    table = markdown_table(study)
    out = Path(study["out"])
    (out / "table.md").write_text(table + "\n")
    from ..common.checkpoint import atomic_write_bytes

    payload = {k: study[k] for k in ("identity", "summary", "optimum", "rows", "complete")}
    text = json.dumps(payload, indent=1, default=float)
    atomic_write_bytes(out / "study.json", text.encode())
    if args.json:
        atomic_write_bytes(args.json, text.encode())
    written = [out / "table.md", out / "study.json"]
    if not args.no_plot:
        written.append(plot_study(study, out / "study.png"))
    print()
    print(table)
    print()
    print("Written: " + ", ".join(str(w) for w in written))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
