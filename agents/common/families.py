"""Which env family a scenario belongs to: the one place that knows every family.

A lazy, string-keyed registry (like Gymnasium's env registry): :data:`FAMILY_ENTRY_POINTS` names
each family's :class:`~agents.experts.family.EnvFamily` subclass as ``"module:Class"``, imported
on first use (one cached instance per family). It lives in the common room so that common code
(the observation features, the reward shaping) can ask the family too, without importing the
experts room, which builds on common; callers only call methods of the returned object.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["FAMILY_ENTRY_POINTS", "FAMILIES", "all_families", "family_named", "family_of"]

#: family name -> ``"module:Class"`` of its EnvFamily, in the order families are tried
FAMILY_ENTRY_POINTS: dict[str, str] = {
    "planar": "agents.experts.planar.family:PlanarFamily",
    "pinpoint": "agents.experts.pinpoint.family:PinpointFamily",
}

#: family names, in the order they are tried
FAMILIES = tuple(FAMILY_ENTRY_POINTS)

_INSTANCES: dict[str, Any] = {}


def family_named(name: str) -> Any:
    """The :class:`~agents.experts.family.EnvFamily` registered as ``name`` (imported and built
    on first use, then cached). Raises KeyError for an unregistered name."""
    fam = _INSTANCES.get(name)
    if fam is None:
        if name not in FAMILY_ENTRY_POINTS:
            raise KeyError(f"no env family {name!r}; registered families: "
                           f"{', '.join(FAMILIES)}")
        module, _, cls = FAMILY_ENTRY_POINTS[name].partition(":")
        fam = _INSTANCES[name] = getattr(importlib.import_module(module), cls)()
    return fam


def all_families() -> tuple[Any, ...]:
    """Every registered family, in :data:`FAMILIES` order."""
    return tuple(family_named(name) for name in FAMILIES)


def family_of(scenario_or_env) -> Any:
    """The :class:`~agents.experts.family.EnvFamily` of a scenario, or of an env or flight
    computer (its ``scenario``).

    Raises
    ------
    TypeError
        No registered family handles the scenario.
    """
    scenario = getattr(getattr(scenario_or_env, "unwrapped", scenario_or_env), "scenario",
                       scenario_or_env)
    for fam in all_families():
        if fam.handles(scenario):
            return fam
    raise TypeError(f"no env family handles scenario {getattr(scenario, 'name', scenario)!r} "
                    f"({type(scenario).__name__}); registered families: {', '.join(FAMILIES)}")
