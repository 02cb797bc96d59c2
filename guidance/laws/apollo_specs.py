"""``--laws`` factories of the explicit laws (:mod:`guidance.registry`).

Syntax (``NAME[:KEY=VALUE,...]``, no argument)::

    apollo                       augmented Apollo with k_r = 12 ([K74])
    zem-zev                      augmented Apollo with k_r = 6 ([GHW])
    apollo:kr=10                 any gain in [6, 24]
    apollo:kr=9,tgo_margin=0.02,lead=2.2
    zem-zev:tgo=rocket           another t_go rule (matched, matched-short, rocket, countdown)
    zem-zev:rotation=0           3D: leave the Moon's Coriolis/centrifugal terms out
    apollo:tgo=rocket,terminal=4 a constant-thrust finish against the velocity (t_go ≤ 4 s)
    apollo:tgo=rocket,tgo_margin=0.02,aim=5   aim 5 m above the gate (3D, constant thrust)
    apollo:low_gate=50,rate=1.5  LunarPinpointLanding-v3: another low gate and descent rate
    zem-zev:high_gate=0          v3: brake straight to the low gate (no high gate)
    zem-zev:phased=0             v3: aim at the site itself, no phases
    gravity-turn                 thrust opposite the surface-relative velocity

Options of ``apollo`` / ``zem-zev``:

==============  =============================================================  =======
key             meaning                                                        default
==============  =============================================================  =======
``kr``          gain k_r ∈ [6, 24]                                             12 / 6
``tgo_margin``  μ in t_go = (1 + μ)·t_rule, ∈ [−0.5, 1]                        0
``lead``        lead time τ (s) ∈ [0, 10] (Luminary: 2.2)                      0
``tgo``         t_go rule (:data:`~guidance.laws.apollo.TGO_RULES`)            matched
                (``countdown`` on a throttled engine)
``rotation``    1/0: the Moon's rotation terms in the known acceleration (3D)  1
``terminal``    constant thrust: t_go (s) ∈ [0, 60] below which the law        0 (off)
                thrusts against the velocity (gravity-turn finish)
``aim``         aim point (m) ∈ [0, 100] above the terminal surface            0
==============  =============================================================  =======

``min_time_slack=M`` (``LunarPinpointLanding-v3``, m ∈ (0, 50000]; default off): a lander whose
measured engine's minimum-time stop lies less than M short of the site (or beyond it) flies
the minimum-time Pontryagin feedback to touchdown for the rest of its descent
(:class:`~guidance.laws.min_time_touchdown.MinimumTimeHandover`; 5000 is the measured
choice there)::

    zem-zev:min_time_slack=5000

Phases (``LunarPinpointLanding-v3``, where the episode ends at touchdown on the site; the
defaults, their sources and reasons: :class:`~guidance.laws.apollo.DescentPhases`):

===============  ============================================================  ==========
key              meaning                                                       default
===============  ============================================================  ==========
``phased``       1/0: fly Apollo's phases (braking, approach, terminal         1 (v3)
                 descent); 0 aims at the site directly
``high_gate``    height of the high gate (m): 0 (none) or in                   2000
                 (low_gate, 10000]
``hg_angle``     the high gate's elevation seen from the low gate (°)          10
                 ∈ [2, 45]
``hg_speed``     speed at the high gate (m/s) ∈ (0, 1000]                      250
``low_gate``     height of the low gate above the site (m) ∈ [5, 500]          15
``rate``         terminal descent's rate of descent (m/s) ∈ [0.2, 2.9]         1
``switch``       t_go (s) ∈ [0.5, 20] at which a gate counts as reached        2
``rate_tau``     time constant of the rate-of-descent loop (s) ∈ [0.5, 20]     2
``h_tau``        time constant of the horizontal-velocity nulling (s)          3
                 ∈ [0.5, 30]
``tilt``         largest tilt from the vertical in terminal descent (°)        45
                 ∈ [0, 60]
===============  ============================================================  ==========

``gravity-turn`` takes ``rotation`` only. The engine (constant thrust or throttled) is the
env's: ``throttle_channel`` in the env keyword arguments.
"""

from __future__ import annotations

from guidance.explicit import K_R_APOLLO, K_R_ZEM_ZEV
from guidance.law import GuidanceLaw
from guidance.laws.apollo import AugmentedApolloLaw, DescentPhases, GravityTurnLaw
from guidance.registry import flag

__all__ = ["apollo_from_spec", "zem_zev_from_spec", "gravity_turn_from_spec"]

#: option key -> :class:`~guidance.laws.apollo.DescentPhases` field
_PHASE_OPTIONS = {"high_gate": "high_gate_m", "hg_angle": "high_gate_angle_deg",
                  "hg_speed": "high_gate_speed_m_s", "low_gate": "low_gate_m",
                  "rate": "rate_m_s", "switch": "switch_s",
                  "rate_tau": "rate_tau_s",
                  "h_tau": "horizontal_tau_s", "tilt": "max_tilt_deg"}
_OPTIONS = ("kr", "tgo_margin", "lead", "tgo", "rotation", "terminal", "aim", "phased",
            "min_time_slack", *_PHASE_OPTIONS)


def _phases(spec):
    """The ``phases`` argument of :class:`AugmentedApolloLaw` from the spec's options."""
    phased = spec.option("phased", flag, None)
    given = {field: spec.option(key, float, None) for key, field in _PHASE_OPTIONS.items()
             if key in spec.options}
    if phased is False and given:
        keys = ", ".join(k for k in _PHASE_OPTIONS if k in spec.options)
        raise ValueError(f"law {spec.text!r}: {keys} are options of the phases; phased=0 "
                         "flies none")
    if given:
        return DescentPhases(**given)
    return phased


def _no_argument(spec) -> None:
    if spec.argument is not None:
        raise ValueError(f"law {spec.text!r} takes no argument (got {spec.argument!r}); "
                         "options are KEY=VALUE")


def _augmented(spec, default_k_r: float, context) -> GuidanceLaw:
    from guidance.laws.min_time_touchdown import spec_slack, with_handover

    spec.require_known_options(_OPTIONS)
    _no_argument(spec)
    try:
        slack = spec_slack(spec)  # before the minimum-time law's first solve
        law = AugmentedApolloLaw(
            k_r=spec.option("kr", float, default_k_r),
            tgo_margin=spec.option("tgo_margin", float, 0.0),
            lead_s=spec.option("lead", float, 0.0),
            tgo_rule=spec.option("tgo", str, None),
            include_rotation=spec.option("rotation", flag, True),
            terminal_s=spec.option("terminal", float, 0.0),
            aim_above_m=spec.option("aim", float, 0.0),
            phases=_phases(spec),
            name=spec.text or spec.name)
        return with_handover(law, slack, spec, context)
    except ValueError as exc:
        msg = str(exc)  # the spec's own checks name the law already
        raise ValueError(msg if msg.startswith("law ") else
                         f"law {spec.text or spec.name!r}: {msg}") from None


def apollo_from_spec(spec, context) -> GuidanceLaw:
    """``apollo[:kr=..,tgo_margin=..,lead=..,tgo=..,rotation=..]`` (k_r = 12 by default)."""
    return _augmented(spec, K_R_APOLLO, context)


def zem_zev_from_spec(spec, context) -> GuidanceLaw:
    """``zem-zev[:...]``: the augmented Apollo law with k_r = 6 by default (same options)."""
    return _augmented(spec, K_R_ZEM_ZEV, context)


def gravity_turn_from_spec(spec, context) -> GuidanceLaw:
    """``gravity-turn[:rotation=1|0]``."""
    spec.require_known_options(("rotation",))
    _no_argument(spec)
    return GravityTurnLaw(include_rotation=spec.option("rotation", flag, True),
                          name=spec.text or spec.name)
