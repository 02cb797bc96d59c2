"""Factories of the non-learned laws every env family has (:mod:`agents.common.law_specs`):
``open-loop`` (each case's optimum replayed) and ``feedback`` (the family's re-planning
expert, re-solving from the navigation solution with the nominal model)."""

from __future__ import annotations

from agents.common.families import family_of
from agents.common.law import GuidanceLaw

__all__ = ["open_loop_from_spec", "feedback_from_spec"]


def open_loop_from_spec(spec, context) -> GuidanceLaw:
    """``open-loop``: the family's replay of each case's nominal-plant optimum from the
    navigated start (``context.nominal_optimum()``). No options."""
    spec.require_known_options(())
    if spec.argument is not None:
        raise ValueError(f"law {spec.text!r} takes no argument")
    if context.nominal_optimum is None:
        raise ValueError("law 'open-loop' needs the per-case optimum; fly it in a campaign or "
                         "an evaluation, which compute it")
    law = family_of(context.scenario).open_loop_law(context.nominal_optimum())
    law.name = "open-loop"
    return law


def feedback_from_spec(spec, context) -> GuidanceLaw:
    """``feedback``: the family's closed-loop expert (planar: Pontryagin re-planning; pinpoint:
    compiled Pontryagin re-planning) on the navigation solution and the nominal model. No
    options."""
    spec.require_known_options(())
    if spec.argument is not None:
        raise ValueError(f"law {spec.text!r} takes no argument")
    law = family_of(context.scenario).expert_law(context.scenario)
    law.name = "feedback"
    return law
