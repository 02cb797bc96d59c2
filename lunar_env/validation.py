"""Input checks for the public edges: each error names the field, the value and what is allowed."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["require_finite", "require_finite_positive", "require_range"]


def require_finite(name: str, value) -> None:
    """Raise ValueError unless every element of ``value`` is finite."""
    arr = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} = {value!r} is not finite; a finite number is required")


def require_finite_positive(name: str, value) -> None:
    """Raise ValueError unless ``value`` is a finite number > 0."""
    require_finite(name, value)
    if not float(value) > 0.0:
        raise ValueError(f"{name} = {value!r} is not allowed; it must be > 0")


def require_range(name: str, value) -> None:
    """Raise ValueError unless ``value`` is a finite (low, high) pair with low <= high."""
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r} must be a (low, high) pair of numbers") from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ValueError(f"{name} = {value!r} is not finite; a finite (low, high) is required")
    if lo > hi:
        raise ValueError(f"{name} = {value!r} is reversed; low must be <= high")
