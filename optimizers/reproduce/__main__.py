"""Dispatch ``python -m optimizers.reproduce <scenario> [options]``."""

from __future__ import annotations

import argparse
import importlib
import sys

from . import SCENARIOS


def main(argv: list[str] | None = None) -> int:
    """Run the reproduction named by the first argument with the remaining ones; an unknown or
    missing scenario is a usage error (``prog: error: ...``, exit status 2)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    p = argparse.ArgumentParser(
        prog="python -m optimizers.reproduce",
        usage="python -m optimizers.reproduce <scenario> [--quick] [--json FILE] ...",
        description="Reproduce a paper's results; 'python -m optimizers.reproduce <scenario> "
                    "--help' lists the scenario's options.")
    p.add_argument("scenario", choices=sorted(SCENARIOS), metavar="scenario",
                   help="one of: " + ", ".join(sorted(SCENARIOS)))
    p.parse_args(argv[:1])  # --help (exit 0), or a missing / unknown scenario (exit 2)
    module = importlib.import_module(SCENARIOS[argv[0]])
    return int(module.main(argv[1:]) or 0)


if __name__ == "__main__":
    sys.exit(main())
