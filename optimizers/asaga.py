"""Alias of :mod:`optimizers.evolutionary.asaga` (moved there; see CHANGELOG.md)."""

import sys

from .evolutionary import asaga as _moved

sys.modules[__name__] = _moved
