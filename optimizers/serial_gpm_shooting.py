"""Alias of :mod:`optimizers.transcription.serial` (moved there; see CHANGELOG.md)."""

import sys

from .transcription import serial as _moved

sys.modules[__name__] = _moved
