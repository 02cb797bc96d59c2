"""Guidance laws by name: the ``--laws`` syntax of the campaign and the evaluation.

A *law spec* is a short string, ``NAME[:ARG][:KEY=VALUE[,KEY=VALUE...]]``::

    ppo:runs/ppo/LunarSoftLanding-v0_1      a trained SB3 run (ppo, sac, td3) or its model .zip
    dagger:runs/imitation/LunarSoftLanding-v0_dagger   an imitation run (bc, dagger)
    open-loop                               each case's optimum (nominal plant), replayed
    feedback                                the family's re-planning expert (Pontryagin / GPM)
    feedback:thrust_reserve=0.05,stop_above_m=4,estimate_thrust=1
                                            pinpoint, throttled: the expert with a thrust
                                            reserve (:mod:`agents.experts.laws`)
    apollo                                  explicit guidance: Apollo (k_r = 12), ``zem-zev``
                                            (k_r = 6), ``gravity-turn``
    apollo:kr=10,tgo_margin=0.02,lead=2.2   a law with options (syntax and options of the
                                            explicit laws: :mod:`agents.experts.explicit.specs`)
    convex:every=2,nodes=40                 SCvx re-planning every 2 s on 40 nodes

A part with ``=`` holds options (``key=value`` pairs, comma-separated); a part without is the
law's argument (a path). The registry :data:`LAW_ENTRY_POINTS` maps each name to a factory
``"module:function"``, imported on first use (like :mod:`agents.common.families`), so that the
common room names laws of every room without importing them. A factory is called as
``factory(spec, context) -> GuidanceLaw`` and raises ``ValueError`` naming a bad argument or
option.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

__all__ = ["LawSpec", "LawContext", "LAW_ENTRY_POINTS", "law_names", "build_law",
           "parse_law_spec", "flag"]

#: law name -> ``"module:function"`` of its factory ``factory(spec, context) -> GuidanceLaw``
LAW_ENTRY_POINTS: dict[str, str] = {
    "ppo": "agents.common.sb3_law:law_from_spec",
    "sac": "agents.common.sb3_law:law_from_spec",
    "td3": "agents.common.sb3_law:law_from_spec",
    "bc": "agents.common.sb3_law:law_from_spec",
    "dagger": "agents.common.sb3_law:law_from_spec",
    "open-loop": "agents.experts.laws:open_loop_from_spec",
    "feedback": "agents.experts.laws:feedback_from_spec",
    "apollo": "agents.experts.explicit.specs:apollo_from_spec",
    "zem-zev": "agents.experts.explicit.specs:zem_zev_from_spec",
    "gravity-turn": "agents.experts.explicit.specs:gravity_turn_from_spec",
    "convex": "agents.experts.convex:convex_from_spec",
}


def flag(text: str) -> bool:
    """A boolean option's value (``spec.option(key, flag, default)``): 1/true/yes/on or
    0/false/no/off, any case; ``ValueError`` otherwise."""
    t = str(text).strip().lower()
    if t in ("1", "true", "yes", "on"):
        return True
    if t in ("0", "false", "no", "off"):
        return False
    raise ValueError(f"{text!r} is not 1/true/yes/on or 0/false/no/off")


@dataclass(frozen=True)
class LawSpec:
    """A parsed law spec (see the module docstring).

    Attributes
    ----------
    name : str
        Registry name (lower case), e.g. ``"ppo"``.
    argument : str or None
        The positional argument (a run directory or model file), if any.
    options : dict[str, str]
        ``key=value`` options, values as written (each factory converts and checks them).
    text : str
        The spec as given (the law's default label).
    """

    name: str
    argument: str | None = None
    options: dict[str, str] = field(default_factory=dict)
    text: str = ""

    def label(self) -> str:
        """The name shown in tables: the spec without a run path's directories."""
        if self.argument is None:
            return self.text or self.name
        tail = self.argument.rstrip("/").rsplit("/", 1)[-1]
        opts = ",".join(f"{k}={v}" for k, v in self.options.items())
        return f"{self.name}:{tail}" + (f":{opts}" if opts else "")

    def option(self, key: str, convert: Callable[[str], Any], default: Any) -> Any:
        """Option ``key`` converted by ``convert`` (``default`` if absent); ``ValueError``
        naming the law, the option and its value if the conversion fails."""
        if key not in self.options:
            return default
        raw = self.options[key]
        try:
            return convert(raw)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"law {self.text or self.name!r}: option {key}={raw!r} is not "
                             f"valid ({exc})") from None

    def require_known_options(self, allowed: tuple[str, ...]) -> None:
        """``ValueError`` naming any option not in ``allowed``."""
        unknown = sorted(set(self.options) - set(allowed))
        if unknown:
            raise ValueError(f"law {self.text or self.name!r}: unknown option(s) "
                             f"{', '.join(unknown)}; allowed: {', '.join(allowed) or 'none'}")


@dataclass
class LawContext:
    """What a factory may use to build a law for one campaign or evaluation.

    Attributes
    ----------
    env_id : str
    env_kwargs : dict
        The env's keyword arguments (nominal scenario, settings; the uncertainty model is the
        env's business, never the law's).
    scenario : object
        The nominal scenario (``env.unwrapped.scenario``).
    nominal_optimum : callable or None
        ``nominal_optimum() -> PerCaseOptimum``: each case's optimum for the nominal plant from
        the start the flight computer believes (the navigated initial state); computed on first
        call by the campaign (the open-loop law replays it).
    extra : dict
        Anything else a caller hands to its factories (e.g. ``workers``).
    """

    env_id: str
    env_kwargs: dict[str, Any]
    scenario: Any
    nominal_optimum: Callable[[], Any] | None = None
    extra: dict[str, Any] = field(default_factory=dict)


def law_names() -> list[str]:
    """The registered law names, sorted."""
    return sorted(LAW_ENTRY_POINTS)


def parse_law_spec(text: str) -> LawSpec:
    """Parse ``NAME[:ARG][:KEY=VALUE,...]`` (see the module docstring).

    Raises
    ------
    ValueError
        Empty text, an unknown name (the registered ones are listed), a malformed option, or
        two arguments.
    """
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"law spec {text!r} is empty; expected NAME[:ARG][:KEY=VALUE,...] with "
                         f"NAME one of {', '.join(law_names())}")
    text = text.strip()
    name, _, rest = text.partition(":")
    name = name.strip().lower()
    if name not in LAW_ENTRY_POINTS:
        raise ValueError(f"unknown law {name!r} in {text!r}; known laws: "
                         f"{', '.join(law_names())}")
    argument: str | None = None
    options: dict[str, str] = {}
    # an argument may itself hold ':' (a Windows path is not supported); options come last
    parts = rest.split(":") if rest else []
    for part in parts:
        if "=" in part and "/" not in part.split("=", 1)[0]:
            for item in part.split(","):
                key, eq, value = item.partition("=")
                key = key.strip()
                if not eq or not key or not value.strip():
                    raise ValueError(f"law {text!r}: option {item!r} is not KEY=VALUE")
                if key in options:
                    raise ValueError(f"law {text!r}: option {key!r} given twice")
                options[key] = value.strip()
        elif part:
            if argument is not None:
                raise ValueError(f"law {text!r} has two arguments ({argument!r}, {part!r}); "
                                 "expected NAME[:ARG][:KEY=VALUE,...]")
            argument = part
    return LawSpec(name=name, argument=argument, options=options, text=text)


def build_law(spec: str | LawSpec, context: LawContext):
    """The :class:`~agents.common.law.GuidanceLaw` a spec names, built by its registered
    factory; its ``name`` is the spec's :meth:`LawSpec.label` unless the factory set one."""
    if isinstance(spec, str):
        spec = parse_law_spec(spec)
    module, _, fn = LAW_ENTRY_POINTS[spec.name].partition(":")
    factory = getattr(importlib.import_module(module), fn)
    return factory(spec, context)
