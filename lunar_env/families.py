"""Per-family registries: what each room of the project knows of an env family, registered by
the module that owns it.

An *env family* is a kind of landing problem with its own state and geometry: the planar soft
landing (``"planar"``) and the 3D pinpoint landing (``"pinpoint"``). A scenario names its family
(``scenario.family``). Each consumer owns a narrow protocol and one :class:`FamilyRegistry` of
it: the per-case optimum (:mod:`optimizers.optimum`), the guidance frame, encoder and expert laws
(:mod:`guidance.families`), the evaluation plots (:mod:`guidance.evaluation.plots`), the RL start
states and observation features (:mod:`agents.rl`), the imitation recipes and teachers
(:mod:`agents.imitation.families`). A new family is a new ``family`` name and one registration in
each registry it needs; code that asks a registry never branches on the family itself.

Registration follows Gymnasium's ``register``: an object, a factory, or a lazy
``"module:attribute"`` string (imported and called on first use, so that a registry does not
import the modules it names)::

    from lunar_env.families import FamilyRegistry
    PLOTS = FamilyRegistry("plot")
    PLOTS.register("planar", "mypackage.plots:PlanarPlots")
    PLOTS.of(env).plot_flight(...)

A registry may also name an entry-point group (``importlib.metadata``): installed packages
register families there without being imported by hand.
"""

from __future__ import annotations

import importlib
from importlib import metadata
from typing import Any, Generic, TypeVar

__all__ = ["FamilyRegistry", "family_name", "load_entry_point"]

T = TypeVar("T")


def load_entry_point(spec: str) -> Any:
    """The attribute ``"module:attribute"`` names (imported now).

    Raises
    ------
    ValueError
        ``spec`` is not ``"module:attribute"``, or the module has no such attribute.
    ModuleNotFoundError
        The module cannot be imported.
    """
    module, sep, attr = str(spec).partition(":")
    if not sep or not module or not attr:
        raise ValueError(f"entry point {spec!r} must be 'module:attribute'")
    mod = importlib.import_module(module)
    obj = mod
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise ValueError(f"entry point {spec!r}: module {module!r} has no {attr!r}") from None
    return obj


def family_name(obj: Any) -> str:
    """The env family of a scenario, or of an env, vector env or flight computer (their
    ``scenario``).

    Raises
    ------
    TypeError
        The object has no scenario with a ``family``.
    """
    scenario = getattr(getattr(obj, "unwrapped", obj), "scenario", obj)
    name = getattr(scenario, "family", None)
    if not isinstance(name, str):
        raise TypeError(f"{getattr(scenario, 'name', scenario)!r} ({type(scenario).__name__}) "
                        "names no env family (a landing scenario has a 'family' attribute)")
    return name


class FamilyRegistry(Generic[T]):
    """One object per env family, for one consumer (see the module docstring).

    Parameters
    ----------
    kind : str
        What the registry holds, for messages (``"optimum"``, ``"guidance"``, ...).
    entry_point_group : str, optional
        An ``importlib.metadata`` entry-point group whose entries (name = family, value =
        ``"module:attribute"``) are registered on the first lookup of an unknown family.
    """

    def __init__(self, kind: str, entry_point_group: str | None = None) -> None:
        self.kind = kind
        self.entry_point_group = entry_point_group
        self._factories: dict[str, type[T] | str | T] = {}
        self._instances: dict[str, T] = {}
        self._entry_points_loaded = False

    def register(self, family: str, obj: type[T] | str | T, *, replace: bool = False) -> None:
        """Register ``family``'s object: an instance, a class (built without arguments on first
        use), or a lazy ``"module:attribute"`` of either.

        Raises
        ------
        ValueError
            ``family`` is not a non-empty string, or is registered already (``replace=True``
            overwrites it).
        """
        if not isinstance(family, str) or not family:
            raise ValueError(f"family {family!r} must be a non-empty string")
        if family in self._factories and not replace:
            raise ValueError(f"a {self.kind} family {family!r} is registered already; pass "
                             "replace=True to overwrite it")
        self._factories[family] = obj
        self._instances.pop(family, None)

    def names(self) -> tuple[str, ...]:
        """The registered families, in registration order."""
        self._load_entry_points()
        return tuple(self._factories)

    def get(self, family: str) -> T:
        """The object of ``family`` (built on first use, then cached).

        Raises
        ------
        KeyError
            ``family`` is not registered (the message lists those that are).
        """
        inst = self._instances.get(family)
        if inst is not None:
            return inst
        if family not in self._factories:
            self._load_entry_points()
        if family not in self._factories:
            raise KeyError(f"no {self.kind} family {family!r}; registered: "
                           f"{', '.join(self._factories) or 'none'}")
        obj = self._factories[family]
        if isinstance(obj, str):
            obj = load_entry_point(obj)
        if isinstance(obj, type):
            obj = obj()
        self._instances[family] = obj
        return obj

    def of(self, obj: Any) -> T:
        """The object of the family of a scenario, env or flight computer
        (:func:`family_name`)."""
        return self.get(family_name(obj))

    def _load_entry_points(self) -> None:
        if self._entry_points_loaded or not self.entry_point_group:
            return
        self._entry_points_loaded = True
        for ep in metadata.entry_points(group=self.entry_point_group):
            if ep.name not in self._factories:
                self._factories[ep.name] = ep.value
