"""guidance: the guidance-law contract, the flight loop, the non-learned laws and Monte Carlo
campaigns (no torch, no SB3).

::

    from guidance import GuidanceLaw, ThrustCommand, fly, register_law

The layers: ``guidance`` builds on :mod:`optimizers` (the per-case optima, re-planning problems)
and :mod:`lunar_env` (the envs); :mod:`agents` (what learns) builds on it.
"""

from guidance.flight import PolicyResult, Rollout, fly, initial_states, make_vec, rollout
from guidance.frames import LocalFrame
from guidance.law import (
    ActionSequenceLaw,
    CallableLaw,
    FlightComputer,
    GuidanceLaw,
    Law,
    Navigation,
    PrivilegedLaw,
    ThrustCommand,
    Truth,
    law_label,
)
from guidance.registry import (
    LawContext,
    LawSpec,
    build_law,
    import_law_modules,
    law_names,
    parse_law_spec,
    register_law,
)

__all__ = ["ActionSequenceLaw", "CallableLaw", "FlightComputer", "GuidanceLaw", "Law",
           "LawContext", "LawSpec", "LocalFrame", "Navigation", "PolicyResult",
           "PrivilegedLaw", "Rollout", "ThrustCommand", "Truth", "build_law", "fly",
           "import_law_modules", "initial_states", "law_label", "law_names", "make_vec",
           "parse_law_spec", "register_law", "rollout"]
