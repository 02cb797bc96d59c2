"""Guidance laws by name: the ``--laws`` syntax of the campaign and the evaluation.

A *law spec* is a short string, ``NAME[:ARG][:KEY=VALUE[,KEY=VALUE...]]``::

    open-loop                               each case's optimum (nominal plant), replayed
    feedback                                the family's re-planning expert (Pontryagin / GPM)
    feedback:thrust_reserve=0.05,stop_above_m=4,estimate_thrust=1
                                            pinpoint, throttled: the expert with a thrust
                                            reserve (:mod:`guidance.laws.feedback`)
    apollo                                  explicit guidance: Apollo (k_r = 12), ``zem-zev``
                                            (k_r = 6), ``gravity-turn``
    apollo:kr=10,tgo_margin=0.02,lead=2.2   a law with options (syntax and options of the
                                            explicit laws: :mod:`guidance.laws.apollo_specs`)
    convex:every=2,nodes=40                 SCvx re-planning every 2 s on 40 nodes
    ppo:runs/ppo/LunarSoftLanding-v0_1      a trained SB3 run (ppo, sac, td3, recurrent-ppo, bc,
                                            dagger; registered by :mod:`agents.laws`)

A part with ``=`` holds options (``key=value`` pairs, comma-separated); a part without is the
law's argument (a path).

**Registration.** A law name is registered by the module that owns the law, as Gymnasium's
``register``: :func:`register_law` with a factory ``factory(spec, context) -> law`` (or a lazy
``"module:function"`` string, imported on first use), which raises ``ValueError`` naming a bad
argument or option. The built-in laws register in :mod:`guidance.laws`; the learned ones in
:mod:`agents.laws`; an installed package registers its own through the entry-point group
``lunar_env.laws`` (name = law name, value = ``"module:function"``), and a user's module simply
calls :func:`register_law` when it is imported (``python -m guidance.campaign --import
mylaws`` imports it, in every worker too)::

    from guidance import GuidanceLaw, ThrustCommand, register_law

    class Hover(GuidanceLaw):
        name = "hover"
        def act(self, nav):
            return ThrustCommand(-nav.frame.g)

    register_law("hover", lambda spec, context: Hover())

A factory may carry three attributes: ``env_kwargs(spec)`` (the env arguments its law must
fly with, :func:`required_env_kwargs`), ``identity(spec)`` (what its law's flights depend on
besides the spec, e.g. a model file's SHA-256, :func:`law_identity`: a campaign keys the law's
results by it) and ``validate(spec, context)`` (the checks of the argument and options, where
building the law needs what only a campaign computes, :func:`validate_law`).
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any

from lunar_env.families import load_entry_point

__all__ = ["LawSpec", "LawContext", "register_law", "registered_law", "law_names",
           "law_summaries", "required_env_kwargs", "law_identity", "validate_law", "build_law",
           "parse_law_spec",
           "import_law_modules", "flag", "require_no_argument", "LAW_ENTRY_POINT_GROUP"]

#: the ``importlib.metadata`` entry-point group of installed packages' laws
LAW_ENTRY_POINT_GROUP = "lunar_env.laws"
_NAME = re.compile(r"^[a-z][a-z0-9_.-]*$")


@dataclass(frozen=True)
class _Registration:
    factory: Callable | str
    summary: str


_REGISTRY: dict[str, _Registration] = {}
_loaded = {"builtins": False, "entry_points": False}


def register_law(name: str, factory: Callable | str, *, summary: str = "",
                 replace: bool = False) -> None:
    """Register a law name for law specs (:func:`build_law`, ``--laws``).

    Parameters
    ----------
    name : str
        Lower case: letters, digits, ``_ . -`` (the spec's ``NAME``).
    factory : callable or str
        ``factory(spec: LawSpec, context: LawContext) -> law``, or ``"module:function"``
        naming one (imported on first use).
    summary : str
        One line for ``--list-laws``.
    replace : bool
        Overwrite an existing registration (default: refused).

    Raises
    ------
    ValueError
        A malformed name, a factory that is neither callable nor a string, or a name taken.
    """
    if not isinstance(name, str) or not _NAME.match(name):
        raise ValueError(f"law name {name!r} must be lower case letters, digits, '_', '.' or "
                         "'-', starting with a letter")
    if not (callable(factory) or isinstance(factory, str)):
        raise ValueError(f"factory of law {name!r} must be callable or 'module:function', "
                         f"not {factory!r}")
    if name in _REGISTRY and not replace and not _same(_REGISTRY[name].factory, factory):
        raise ValueError(f"law {name!r} is registered already; pass replace=True to overwrite")
    _REGISTRY[name] = _Registration(factory, str(summary))


def _qualified(factory: Callable | str) -> str:
    if isinstance(factory, str):
        return factory
    return f"{getattr(factory, '__module__', '')}:{getattr(factory, '__qualname__', '')}"


def _same(a: Callable | str, b: Callable | str) -> bool:
    """Two registrations of one factory (an entry point's string and the function it names
    count as one, so a module may register what its package's entry point declares)."""
    return a is b or _qualified(a) == _qualified(b)


def _load_registrations() -> None:
    """The built-in laws (:mod:`guidance.laws`, and :mod:`agents.laws` when installed) and the
    installed packages' entry points, registered once."""
    if not _loaded["builtins"]:
        _loaded["builtins"] = True
        importlib.import_module("guidance.laws")
    if not _loaded["entry_points"]:
        _loaded["entry_points"] = True
        for ep in metadata.entry_points(group=LAW_ENTRY_POINT_GROUP):
            if ep.name not in _REGISTRY:
                _REGISTRY[ep.name] = _Registration(ep.value, "")


def registered_law(name: str) -> Callable:
    """The factory registered as ``name`` (imported if lazy).

    Raises
    ------
    ValueError
        ``name`` is not registered (the message lists the registered names).
    """
    _load_registrations()
    if name not in _REGISTRY:
        raise ValueError(f"unknown law {name!r}; known laws: {', '.join(law_names())}")
    reg = _REGISTRY[name]
    if isinstance(reg.factory, str):
        reg = _Registration(load_entry_point(reg.factory), reg.summary)
        _REGISTRY[name] = reg
    return reg.factory


def required_env_kwargs(spec: LawSpec) -> dict | None:
    """The env arguments the law of ``spec`` must fly with (a learned policy: those it was
    trained with), or None where it flies any. A factory declares them through an attribute
    ``env_kwargs(spec) -> dict or None``."""
    fn = getattr(registered_law(spec.name), "env_kwargs", None)
    return None if fn is None else fn(spec)


def law_identity(spec: LawSpec) -> dict[str, Any]:
    """What the flights of the law of ``spec`` depend on, for stores of results: its full spec
    (:meth:`LawSpec.resolved`: the label drops a run's directories, so two runs of one name in
    two folders share a label) and whatever its factory declares through an attribute
    ``identity(spec) -> dict`` (a learned law: the bytes of its model file, so a run retrained
    in place is another law). JSON-ready."""
    ident: dict[str, Any] = {"spec": spec.resolved()}
    fn = getattr(registered_law(spec.name), "identity", None)
    if fn is not None:
        ident.update(fn(spec))
    return ident


def validate_law(spec: LawSpec, context: LawContext) -> None:
    """Check ``spec``'s argument and options before any flight: the factory's attribute
    ``validate(spec, context)`` where it declares one (a law whose construction needs what
    only a campaign computes, e.g. the per-case optimum), else the law is built once and
    dropped.

    Raises
    ------
    ValueError
        What the factory raises for a bad argument or option (named).
    """
    factory = registered_law(spec.name)
    check = getattr(factory, "validate", None)
    if check is not None:
        check(spec, context)
    else:
        factory(spec, context)


def import_law_modules(modules) -> None:
    """Import users' law modules (each registers its laws when imported): a module name, or
    the path of a ``.py`` file.

    Raises
    ------
    ValueError
        A module that cannot be imported (named, with the reason).
    """
    import importlib.util
    import sys
    from pathlib import Path

    for mod in modules or ():
        text = str(mod)
        try:
            if text.endswith(".py") or "/" in text:
                path = Path(text).resolve()
                if not path.is_file():
                    raise FileNotFoundError(f"no file {text}")
                name = f"lunar_user_laws.{path.stem}"
                if name in sys.modules:
                    continue
                spec = importlib.util.spec_from_file_location(name, path)
                module = importlib.util.module_from_spec(spec)
                sys.modules[name] = module
                spec.loader.exec_module(module)
            else:
                importlib.import_module(text)
        except ValueError:
            raise
        except Exception as exc:  # any import failure becomes one line naming the module
            raise ValueError(f"cannot import law module {text!r}: {type(exc).__name__}: {exc}"
                             ) from None


def require_no_argument(spec: LawSpec) -> None:
    """``ValueError`` if the spec has an argument (a law that takes only options)."""
    if spec.argument is not None:
        raise ValueError(f"law {spec.text or spec.name!r} takes no argument (got "
                         f"{spec.argument!r}); options are KEY=VALUE")


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

    def resolved(self) -> str:
        """The spec in full: the argument as an absolute path with links resolved where it
        names an existing file or directory (as given otherwise), the options sorted."""
        import os

        parts = [self.name]
        if self.argument is not None:
            arg = self.argument
            parts.append(os.path.realpath(arg) if os.path.exists(arg) else arg)
        if self.options:
            parts.append(",".join(f"{k}={v}" for k, v in sorted(self.options.items())))
        return ":".join(parts)

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
    _load_registrations()
    return sorted(_REGISTRY)


def law_summaries() -> dict[str, str]:
    """Registered law name -> its one-line summary, sorted by name."""
    _load_registrations()
    return {k: _REGISTRY[k].summary for k in sorted(_REGISTRY)}


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
    if name not in law_names():
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
    """The law (:class:`~guidance.law.GuidanceLaw` or :class:`~guidance.law.PrivilegedLaw`) a
    spec names, built by its registered factory."""
    if isinstance(spec, str):
        spec = parse_law_spec(spec)
    return registered_law(spec.name)(spec, context)
