"""``python -m guidance.campaign``: :func:`guidance.campaign.cli.main`."""

import sys

from guidance.campaign.cli import main

sys.exit(main())
