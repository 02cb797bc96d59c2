"""Alias of :mod:`optimizers.indirect.planar` (moved there; see CHANGELOG.md)."""

import sys

from .indirect import planar as _moved

sys.modules[__name__] = _moved
