"""Alias of :mod:`optimizers.transcription.collocation` (moved there; see CHANGELOG.md)."""

import sys

from .transcription import collocation as _moved

sys.modules[__name__] = _moved
