"""Input checks for the public edges: each error names the field, the value and what is allowed.

Every check raises ``ValueError`` (``TypeError`` for a value of the wrong kind, e.g. a string
where a number is expected) whose message starts with the field's name, so a user sees *which*
argument to fix and what it may be.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = ["InvalidTypeError", "require_finite", "require_finite_positive", "require_range",
           "require_number", "require_integer", "require_bool", "require_option_keys"]


class InvalidTypeError(TypeError, ValueError):
    """A value of the wrong kind (a string where a number is expected, ...). Both a
    ``TypeError`` and a ``ValueError``, so callers catching either see it."""


def require_number(name: str, value) -> float:
    """``value`` as a Python float; a non-number (str, None, array of several values) raises
    :class:`InvalidTypeError` naming ``name``. No finiteness check (see :func:`require_finite`)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Real, np.ndarray)):
        raise InvalidTypeError(f"{name} = {value!r} is not a number; a real number is required")
    arr = np.asarray(value)
    if arr.size != 1 or arr.dtype.kind not in "iuf":
        raise InvalidTypeError(f"{name} = {value!r} is not a number; a real number is required")
    return float(arr.reshape(()))


def require_finite(name: str, value) -> None:
    """Raise ValueError unless every element of ``value`` is finite (TypeError if not numeric)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidTypeError(f"{name} = {value!r} is not numeric; finite numbers are required"
                        ) from None
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} = {value!r} is not finite; a finite number is required")


def require_finite_positive(name: str, value) -> float:
    """Raise unless ``value`` is a finite number > 0; returns it as a float."""
    v = require_number(name, value)
    if not math.isfinite(v):
        raise ValueError(f"{name} = {value!r} is not finite; a finite number > 0 is required")
    if not v > 0.0:
        raise ValueError(f"{name} = {value!r} is not allowed; it must be > 0")
    return v


def require_integer(name: str, value, minimum: int | None = None) -> int:
    """``value`` as an int; it must be integral (3 or 3.0, not 1.7, NaN, inf or True) and
    ``>= minimum`` when given."""
    if isinstance(value, (bool, np.bool_)):
        raise InvalidTypeError(f"{name} = {value!r} is a bool; an integer is required")
    v = require_number(name, value)
    if not math.isfinite(v) or v != math.floor(v):
        raise ValueError(f"{name} = {value!r} is not an integer; an integer"
                         + (f" >= {minimum}" if minimum is not None else "") + " is required")
    if minimum is not None and v < minimum:
        raise ValueError(f"{name} = {value!r} is not allowed; it must be >= {minimum}")
    return int(v)


def require_bool(name: str, value) -> bool:
    """``value`` as a bool: True/False (also numpy bools and the integers 0 and 1). Strings such
    as ``"no"`` are rejected (``bool("no")`` is True)."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, numbers.Integral) and value in (0, 1):
        return bool(value)
    raise InvalidTypeError(f"{name} = {value!r} is not a bool; True or False is required")


def require_option_keys(name: str, options, allowed) -> None:
    """Raise unless ``options`` is None or a mapping whose keys are all in ``allowed``."""
    if options is None:
        return
    if not hasattr(options, "keys"):
        raise InvalidTypeError(f"{name} = {options!r} must be a dict (or None)")
    unknown = sorted(map(str, set(options) - set(allowed)))
    if unknown:
        raise ValueError(f"{name}: unknown key(s) {unknown}; allowed: {sorted(allowed)}")


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
