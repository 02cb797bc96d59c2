"""Alias of :mod:`optimizers.transcription.polynomial_shooting` (moved there; see CHANGELOG.md)."""

import sys

from .transcription import polynomial_shooting as _moved

sys.modules[__name__] = _moved
