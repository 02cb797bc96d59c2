"""``lunar``: one command line for the project's jobs, each a subcommand.

::

    lunar train [--env ID] [--config NAME] ...        train an SB3 agent (train.py)
    lunar evaluate --model RUN [--laws SPEC ...]      laws against the per-case optimum
    lunar campaign --laws SPEC ... [--import MOD]     Monte Carlo campaign under errors
    lunar dataset --n 1000 [--env ID]                 certified optimal-landing datasets
    lunar imitation bc|dagger|evaluate ...            behaviour cloning and DAgger
    lunar reproduce zhu2007|peng2012|... [--quick]    a paper's reproduction
    lunar study asaga zhu2007 --runs 100              a many-seed optimiser study
    lunar zoo                                         write the RL Baselines3 Zoo files

``lunar SUBCOMMAND --help`` prints a subcommand's options. Each subcommand is also a module
(``python -m agents.train``, ``python -m guidance.campaign``, ...; the table below).
"""

from __future__ import annotations

import importlib
import sys

__all__ = ["main", "SUBCOMMANDS"]

#: subcommand -> (module whose ``main(argv)`` runs it, one line of help)
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "train": ("agents.train", "train an SB3 agent on an env (as python train.py)"),
    "evaluate": ("agents.evaluate", "fly runs and laws against the per-case optimum"),
    "campaign": ("guidance.campaign.cli", "Monte Carlo campaign of laws under errors"),
    "dataset": ("agents.imitation.make_dataset", "certified optimal-landing datasets"),
    "imitation": ("agents.imitation.cli", "behaviour cloning and DAgger"),
    "reproduce": ("optimizers.reproduce.__main__", "reproduce a paper's results"),
    "study": ("optimizers.study.__main__", "many-seed optimiser study on the executor"),
    "zoo": ("agents.rl.zoo", "write the RL Baselines3 Zoo hyperparameter files"),
}


def _usage() -> str:
    lines = ["usage: lunar SUBCOMMAND [options]   (lunar SUBCOMMAND --help)", "",
             "subcommands:"]
    lines += [f"  {name:<10s} {text}" for name, (_, text) in SUBCOMMANDS.items()]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``lunar`` console script: run ``argv[0]``'s subcommand with the rest
    of ``argv``. An unknown or missing subcommand prints the usage and exits 2."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(_usage())
        return 0 if argv else 2
    name, rest = argv[0], argv[1:]
    if name not in SUBCOMMANDS:
        print(_usage(), file=sys.stderr)
        print(f"\nlunar: error: unknown subcommand {name!r}; choose one of "
              f"{', '.join(SUBCOMMANDS)}", file=sys.stderr)
        return 2
    module = importlib.import_module(SUBCOMMANDS[name][0])
    return int(module.main(rest) or 0)


if __name__ == "__main__":
    sys.exit(main())
