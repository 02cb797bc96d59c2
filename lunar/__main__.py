"""``python -m lunar``: :func:`lunar.cli.main`."""

import sys

from lunar.cli import main

sys.exit(main())
