"""Alias of :mod:`optimizers.transcription.direct_shooting` (moved there; see CHANGELOG.md)."""

import sys

from .transcription import direct_shooting as _moved

sys.modules[__name__] = _moved
