"""Alias of :mod:`optimizers.indirect.planar` (moved there; see CHANGELOG.md).

``python -m optimizers.pontryagin`` still runs the command line, now
``python -m optimizers.indirect.cli``.
"""

import sys

if __name__ == "__main__":
    from optimizers.indirect.cli import main

    raise SystemExit(main())

from .indirect import planar as _moved  # noqa: E402

sys.modules[__name__] = _moved
