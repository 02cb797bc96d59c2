"""Factories of the non-learned laws every env family has (:mod:`guidance.registry`):
``open-loop`` (each case's optimum replayed) and ``feedback`` (the family's re-planning
expert, re-solving from the navigation solution with the nominal model)."""

from __future__ import annotations

from guidance.law import GuidanceLaw
from guidance.laws.baselines import BASELINE_FAMILIES
from guidance.registry import flag, require_no_argument
from lunar_env.families import family_name

__all__ = ["open_loop_from_spec", "feedback_from_spec"]


def open_loop_from_spec(spec, context) -> GuidanceLaw:
    """``open-loop``: the family's replay of each case's nominal-plant optimum from the
    navigated start (``context.nominal_optimum()``). No options."""
    spec.require_known_options(())
    require_no_argument(spec)
    if context.nominal_optimum is None:
        raise ValueError("law 'open-loop' needs the per-case optimum; fly it in a campaign or "
                         "an evaluation, which compute it")
    law = BASELINE_FAMILIES.of(context.scenario).open_loop_law(context.nominal_optimum())
    law.name = "open-loop"
    return law


def _check_open_loop(spec, context) -> None:
    """What :func:`open_loop_from_spec` checks before it asks for the per-case optimum."""
    spec.require_known_options(())
    require_no_argument(spec)


open_loop_from_spec.validate = _check_open_loop


def feedback_from_spec(spec, context) -> GuidanceLaw:
    """``feedback``: the family's closed-loop expert (planar: Pontryagin re-planning; pinpoint:
    compiled Pontryagin re-planning; touchdown: the certified optimum re-planned every
    ``every=10`` s, none in the last ``min_tgo=15`` s of a plan) on the navigation solution
    and the nominal model.
    Option ``thrust_reserve=R`` (pinpoint, throttled env): plan and fly at throttle 1 − R,
    full thrust when long, 1 − 2R when short by more than ``switch_m=50`` m; the extremals
    stop ``stop_above_m=0`` m above the target; ``estimate_thrust=1`` scales the throttle by
    the engine's estimated thrust; ``terminal_window=1`` flies the last seconds as a window
    that crosses the gate below 5 m/s over a band of heights, instead of the fall from the stop
    (:class:`guidance.laws.pontryagin_pinpoint.PinpointReserveExpert`)."""
    if family_name(context.scenario) == "pinpoint_touchdown":
        return _touchdown_feedback(spec, context)
    spec.require_known_options(("thrust_reserve", "switch_m", "stop_above_m",
                                "estimate_thrust", "terminal_window"))
    require_no_argument(spec)
    reserve = spec.option("thrust_reserve", float, None)
    if reserve is None and {"switch_m", "stop_above_m", "estimate_thrust",
                            "terminal_window"} & set(spec.options):
        raise ValueError(f"law {spec.text!r}: switch_m, stop_above_m, estimate_thrust and "
                         "terminal_window are options of thrust_reserve")
    if reserve is not None:
        from guidance.laws.pontryagin_pinpoint import PinpointReserveExpert

        if family_name(context.scenario) != "pinpoint":
            raise ValueError(f"law {spec.text!r}: thrust_reserve is built for the pinpoint "
                             f"envs (LunarPinpointLanding-v*), not {context.env_id}")
        if not context.env_kwargs.get("throttle_channel", False):
            raise ValueError(f"law {spec.text!r}: thrust_reserve needs the throttle channel "
                             "(--env-kwargs '{\"throttle_channel\": true}')")
        law = PinpointReserveExpert(context.scenario, reserve,
                                    switch_m=spec.option("switch_m", float, 50.0),
                                    stop_above_m=spec.option("stop_above_m", float, 0.0),
                                    estimate_thrust=spec.option("estimate_thrust", flag,
                                                                False),
                                    terminal_window=spec.option("terminal_window", flag,
                                                                False))
        law.name = spec.text
        return law
    law = BASELINE_FAMILIES.of(context.scenario).expert_law(context.scenario)
    law.name = "feedback"
    return law


def _touchdown_feedback(spec, context) -> GuidanceLaw:
    """``feedback[:every=S,min_tgo=S]`` on the touchdown family: the certified optimum
    re-planned from the navigation solution every S seconds
    (:class:`guidance.laws.touchdown_baselines.TouchdownReplanningLaw`)."""
    from guidance.laws.touchdown_baselines import (
        DEFAULT_MIN_TGO_S,
        DEFAULT_REPLAN_S,
        TouchdownReplanningLaw,
    )

    spec.require_known_options(("every", "min_tgo"))
    require_no_argument(spec)
    try:
        law = TouchdownReplanningLaw(context.scenario,
                                     every_s=spec.option("every", float, DEFAULT_REPLAN_S),
                                     min_tgo_s=spec.option("min_tgo", float, DEFAULT_MIN_TGO_S))
    except ValueError as exc:
        msg = str(exc)
        raise ValueError(msg if msg.startswith("law ") else f"law {spec.text!r}: {msg}"
                         ) from None
    law.name = spec.text if spec.options else "feedback"
    return law
