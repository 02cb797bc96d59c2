"""Which env family a scenario belongs to: the one place that knows every family."""

from __future__ import annotations

from agents.experts.family import EnvFamily

__all__ = ["family_of", "FAMILIES"]


def _families() -> tuple[EnvFamily, ...]:
    # imported here, not at the top: each family module pulls in its optimisers (numba, CasADi),
    # and a caller asking for one family should not pay for the other's import
    from agents.experts.pinpoint.family import PinpointFamily
    from agents.experts.planar.family import PlanarFamily

    return (PlanarFamily(), PinpointFamily())


#: family names, in the order they are tried
FAMILIES = ("planar", "pinpoint")


def family_of(scenario_or_env) -> EnvFamily:
    """The :class:`~agents.experts.family.EnvFamily` of a scenario, or of an env (its
    ``scenario``).

    Raises
    ------
    TypeError
        No registered family handles the scenario.
    """
    scenario = getattr(getattr(scenario_or_env, "unwrapped", scenario_or_env), "scenario",
                       scenario_or_env)
    for fam in _families():
        if fam.handles(scenario):
            return fam
    raise TypeError(f"no env family handles scenario {getattr(scenario, 'name', scenario)!r} "
                    f"({type(scenario).__name__}); registered families: {', '.join(FAMILIES)}")
