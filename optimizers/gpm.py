"""Alias of :mod:`optimizers.transcription.gpm` (moved there; see CHANGELOG.md)."""

import sys

from .transcription import gpm as _moved

sys.modules[__name__] = _moved
