"""Dispatch ``python -m optimizers.reproduce <scenario> [options]``."""

from __future__ import annotations

import importlib
import sys

from . import SCENARIOS


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help") or argv[0] not in SCENARIOS:
        known = ", ".join(sorted(SCENARIOS))
        print(f"usage: python -m optimizers.reproduce <scenario> [--quick] [--json FILE]\n"
              f"scenarios: {known}")
        return 0 if argv and argv[0] in ("-h", "--help") else 2
    module = importlib.import_module(SCENARIOS[argv[0]])
    return int(module.main(argv[1:]) or 0)


if __name__ == "__main__":
    sys.exit(main())
