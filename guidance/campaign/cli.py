"""Command line of Monte Carlo campaigns: ``python -m guidance.campaign``.

::

    python -m guidance.campaign --env LunarSoftLanding-v0 --uncertainty standard --cases 1000 \\
        --laws ppo:runs/ppo/LunarSoftLanding-v0_1 open-loop feedback --workers 2
    python -m guidance.campaign --env LunarPinpointLanding-v2 --cases 200 --laws feedback \\
        --uncertainty '{"base": "standard", "thrust_scale": 0.05}' --json pinpoint.json

Every law flies the same cases (case k: reset seed ``seed + k``; the same plant and navigation
errors for every law). Law specs: ``NAME[:ARG][:KEY=VALUE,...]`` (:mod:`guidance.registry`;
``--list-laws`` prints the names). Results stream to ``--out`` (default ``results/campaign/<env>-
<uncertainty>-<cases>-<seed>``): a killed campaign resumes there, and a rerun with one more law
flies only that law. Writes ``campaign.json`` (the contract of
:func:`guidance.campaign.run.campaign_summary`), ``cases.csv`` and the plots. What is flown
and measured: :mod:`guidance.campaign.run`.

Every input is checked before any work, each bad one ending the command with one line
``python -m guidance.campaign: error: ...`` naming the option, and exit status 2: the numbers
and paths as they are parsed, the uncertainty model (at every error scale of the curve, in
the env), and every law, built once in this process. One process writes a campaign directory
at a time: a second run into the same ``--out`` refuses at once, naming the first one's PID
(``--wait`` waits for it instead); a directory of another campaign, or one whose
``identity.json`` is lost, is refused too. Ctrl-C or SIGTERM stops the workers, keeps every
finished task and exits 130 / 143 with one line; the same command then resumes.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

__all__ = ["main", "format_table"]


def format_table(summary: dict) -> str:
    """The campaign table as text (one row per law)."""
    pin = any("miss_p99_m" in v for v in summary["laws"].values())
    head = (f"{'law':<34s} {'success':>8s} {'95% CI':>13s} {'v p50':>6s} {'v p99':>6s} "
            f"{'v max':>7s} " + (f"{'miss p99':>9s} " if pin else "")
            + f"{'fuel p50':>8s} {'gap p50':>8s} {'gap p99':>8s} {'margin p1':>9s} {'µs/dec':>8s}")
    lines = [f"{summary['env']}, uncertainty '{summary['uncertainty']}', {summary['cases']} "
             f"cases, seed {summary['seed']}", head, "-" * len(head)]

    def f(v, fmt):
        return format(v, fmt) if v is not None else "—"

    for name, r in summary["laws"].items():
        lo, hi = r["success_ci95"]
        ci = f"[{100 * lo:.1f},{100 * hi:.1f}]"
        lines.append(
            f"{name[:34]:<34s} {100 * r['success_rate']:7.1f}% {ci:>13s} "
            f"{f(r['touchdown_speed_p50_m_s'], '6.2f')} {f(r['touchdown_speed_p99_m_s'], '6.2f')} "
            f"{f(r['touchdown_speed_max_m_s'], '7.1f')} "
            + (f"{f(r.get('miss_p99_m'), '9.1f')} " if pin else "")
            + f"{f(r['fuel_p50_kg'], '8.2f')} {f(r['fuel_gap_p50_pct'], '+8.2f')} "
            f"{f(r['fuel_gap_p99_pct'], '+8.2f')} {f(r['propellant_margin_p1_kg'], '9.2f')} "
            f"{f(r['us_per_decision'], '8.1f')}")
    curve = summary.get("robustness_curve") or {}
    if any(curve.values()):
        scales = [p["scale"] for p in next(iter(curve.values()))]
        lines.append("")
        lines.append("robustness curve: success rate (%) against error scale "
                     f"(× '{summary['uncertainty']}')")
        lines.append(f"{'law':<34s} " + " ".join(f"{s:>7g}" for s in scales))
        for name, pts in curve.items():
            lines.append(f"{name[:34]:<34s} "
                         + " ".join(f"{100 * p['success_rate']:7.1f}" for p in pts))
    return "\n".join(lines)


def _run_env_kwargs(laws: list[str]) -> dict:
    """The env arguments the laws require (:func:`guidance.registry.required_env_kwargs`: a
    learned policy flies the env it was trained on, e.g. 2.5 s decisions); ``{}`` if none
    does. Laws that require different arguments cannot share a campaign (ValueError: give
    ``--env-kwargs``)."""
    from guidance.registry import parse_law_spec, required_env_kwargs

    found: dict[str, dict] = {}
    for text in laws:
        kw = required_env_kwargs(parse_law_spec(text))
        if kw is not None:
            found[text] = {k: v for k, v in kw.items() if k != "uncertainty"}
    kinds = {json.dumps(v, sort_keys=True) for v in found.values()}
    if len(kinds) > 1:
        raise ValueError("the runs were trained with different env arguments ("
                         + "; ".join(f"{k}: {v}" for k, v in found.items())
                         + "); give --env-kwargs")
    return next(iter(found.values())) if found else {}


#: largest --cases, --chunk and --curve-cases (each case's rows are held in memory)
MAX_CASES = 10_000_000
#: largest --workers
MAX_WORKERS = 1024


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point (``python -m guidance.campaign``); Ctrl-C or SIGTERM at any
    point ends it with one line and status 130 / 143 (the tasks finished so far stay stored)."""
    from optimizers.common.cli import clean_interrupts

    with clean_interrupts():
        return _main(argv)


def _parser() -> argparse.ArgumentParser:
    from guidance.campaign.run import DEFAULT_SCALES
    from optimizers.common.cli import (
        MAX_SEED,
        count_type,
        output_dir_type,
        output_file_type,
        ray_address_type,
        real_type,
        seed_type,
    )

    p = argparse.ArgumentParser(prog="python -m guidance.campaign",
                                description=__doc__.split("\n")[0])
    p.add_argument("--env", default="LunarSoftLanding-v0")
    p.add_argument("--uncertainty", default="standard",
                   help="set name (none, standard, stress) or a JSON dict of its fields "
                        "(with optional \"base\" and \"scale\")")
    p.add_argument("--cases", type=count_type(1, MAX_CASES), default=1000,
                   help=f"cases 0..N-1, 1 to {MAX_CASES} (default 1000)")
    p.add_argument("--laws", nargs="+", default=None,
                   help="law specs NAME[:ARG][:KEY=VALUE,...]; e.g. ppo:RUN dagger:RUN "
                        "open-loop feedback")
    p.add_argument("--list-laws", action="store_true", help="print the law names and exit")
    p.add_argument("--import", dest="imports", action="append", default=[], metavar="MODULE",
                   help="import a module or .py file that registers laws "
                        "(guidance.register_law) before anything else, in every worker too "
                        "(repeatable)")
    p.add_argument("--env-kwargs", default=None,
                   help="JSON dict of env arguments (default: those the runs among --laws were "
                        "trained with, else none)")
    p.add_argument("--seed", type=seed_type, default=0,
                   help=f"case k is reset with seed + k; 0 to {MAX_SEED} (default 0)")
    p.add_argument("--chunk", type=count_type(1, MAX_CASES), default=100,
                   help="cases per task (default 100)")
    p.add_argument("--scales", type=real_type(0.0), nargs="*", default=list(DEFAULT_SCALES),
                   help="error scales of the robustness curve, finite and >= 0 (none: no "
                        "curve)")
    p.add_argument("--curve-cases", type=count_type(1, MAX_CASES), default=200,
                   help="cases flown at each scale of the robustness curve (default 200)")
    p.add_argument("--workers", type=count_type(0, MAX_WORKERS), default=1,
                   help=f"local processes, 0 (this one) to {MAX_WORKERS} (default 1)")
    p.add_argument("--address", type=ray_address_type, default=None,
                   help="Ray cluster ('local', 'auto', 'host:port'); default $RAY_ADDRESS, "
                        "else --workers local processes")
    p.add_argument("--out", type=output_dir_type, default=None,
                   help="campaign directory (resumable; one process writes it at a time)")
    p.add_argument("--wait", action="store_true",
                   help="wait for another campaign writing --out to finish (default: refuse)")
    p.add_argument("--json", type=output_file_type, default=None,
                   help="also write the JSON summary here")
    p.add_argument("--no-plots", action="store_true")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def _main(argv: list[str] | None) -> int:
    from guidance.campaign.run import (
        CampaignConfig,
        check_laws,
        check_scales,
        curve_scales,
        run_campaign,
    )
    from guidance.registry import import_law_modules, law_summaries, parse_law_spec
    from lunar_env.uncertainty import resolve_uncertainty
    from optimizers.common.cli import check_env, clean_interrupts, user_input_errors
    from optimizers.common.executor import ResultStore, get_executor
    from optimizers.common.lock import DirectoryBusy, DirectoryLock

    p = _parser()
    args = p.parse_args(argv)
    with user_input_errors(p, prefix="--import"):
        import_law_modules(args.imports)
    if args.list_laws:
        for name, summary in law_summaries().items():
            print(f"{name:<14s} {summary}".rstrip())
        return 0
    if not args.laws:
        p.error("--laws is required (e.g. --laws open-loop feedback); --list-laws names them")
    # every input checked here, before any work; each bad one is one line naming its option
    with user_input_errors(p, prefix="--laws"):
        for text in args.laws:
            parse_law_spec(text)
    with user_input_errors(p, errors=(TypeError,), prefix="--uncertainty"):
        unc = args.uncertainty
        if unc.lstrip().startswith("{"):
            unc = json.loads(unc)
        unc = resolve_uncertainty(unc)
    with user_input_errors(p, prefix="--scales"):
        curve_scales(unc, args.scales)
    with user_input_errors(p, errors=(TypeError,), prefix="--env-kwargs"):
        env_kwargs = json.loads(args.env_kwargs) if args.env_kwargs else None
        if env_kwargs is not None and not isinstance(env_kwargs, dict):
            raise ValueError(f"{args.env_kwargs!r} is not a JSON dict")
    with user_input_errors(p, prefix="--laws"):
        if env_kwargs is None:
            env_kwargs = _run_env_kwargs(args.laws)
    with user_input_errors(p, prefix="--env"):
        check_env(args.env)
    with user_input_errors(p, prefix="--env-kwargs"):
        check_env(args.env, env_kwargs)
    with user_input_errors(p, errors=(TypeError,)):
        config = CampaignConfig(env_id=args.env, uncertainty=unc, cases=args.cases,
                                seed=args.seed, laws=tuple(args.laws), env_kwargs=env_kwargs,
                                chunk=args.chunk, scales=tuple(args.scales),
                                curve_cases=args.curve_cases,
                                imports=tuple(str(Path(m).resolve()) if m.endswith(".py")
                                              else m for m in args.imports))
    with user_input_errors(p, prefix="--uncertainty"):
        check_env(args.env, {**env_kwargs, "uncertainty": config.uncertainty})
    with user_input_errors(p, prefix="--scales"):
        check_scales(config)
    with user_input_errors(p, errors=(TypeError,), prefix="--laws"):
        check_laws(config)
    out = Path(args.out or f"results/campaign/{args.env}-{config.uncertainty.name}-"
                           f"{args.cases}-{args.seed}")
    # one writer per campaign directory, held to the end; a directory of another campaign (or
    # one whose identity is lost) refused before any work
    with user_input_errors(p, errors=(DirectoryBusy, OSError), prefix=f"--out {out}"):
        lock = DirectoryLock(out, wait=args.wait, what="campaign").acquire()
    try:
        with user_input_errors(p, errors=(OSError,), prefix=f"--out {out}"):
            ResultStore(out / "store", identity=config.identity(), fmt="json")
        with user_input_errors(p, errors=(ConnectionError, ImportError), prefix="--address"):
            ex = get_executor(args.address, args.workers)
        with ex, clean_interrupts(ex):
            print(f"campaign -> {out}", flush=True)
            result = run_campaign(config, out, executor=ex, plots=not args.no_plots,
                                  json_file=args.json, progress=not args.no_progress)
    finally:
        lock.release()
    print(format_table(result.summary))
    print(f"\n{result.wall_s:.0f} s; {out / 'campaign.json'}, {out / 'cases.csv'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
