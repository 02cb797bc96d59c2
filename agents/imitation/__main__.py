"""``python -m agents.imitation``: see :mod:`agents.imitation.cli`."""

from agents.imitation.cli import main

raise SystemExit(main())
