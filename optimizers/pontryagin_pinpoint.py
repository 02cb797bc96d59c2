"""Alias of :mod:`optimizers.indirect.pinpoint` (moved there; see CHANGELOG.md)."""

import sys

from .indirect import pinpoint as _moved

sys.modules[__name__] = _moved
