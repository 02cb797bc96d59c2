"""What the flight computer needs of an env family: its guidance frame and its encoder.

The one place where guidance meets an env family's geometry. A :class:`GuidanceFamily` gives
the flight computer (:class:`guidance.law.FlightComputer`) the frame map of navigated states
(:mod:`guidance.frames`), the encoder of thrust commands into the env's actions, and the
vehicle's pointing bounds. Laws never ask for the family: they read ``nav.frame`` and return a
:class:`~guidance.law.ThrustCommand`. (The family's optimiser baselines are
:mod:`guidance.laws.baselines`; its plots :mod:`guidance.evaluation.plots`.)

Families are registered in :data:`GUIDANCE_FAMILIES` (a
:class:`lunar_env.families.FamilyRegistry`) by the modules that own them: ``planar``,
``pinpoint`` and ``pinpoint_touchdown`` here; an installed package adds its own through the
``lunar_env.guidance_families`` entry-point group, or by calling
``GUIDANCE_FAMILIES.register``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any

import numpy as np

from lunar_env.families import FamilyRegistry

__all__ = ["GuidanceFamily", "GUIDANCE_FAMILIES", "guidance_family"]


class GuidanceFamily(ABC):
    """The guidance side of an env family (see the module docstring)."""

    #: axes of the guidance frame (horizontal axes, then up)
    n_axes: int = 3
    #: the episode ends at touchdown on a landing site (the frame's target is the site on the
    #: surface): the explicit laws fly Apollo's phases to it (:class:`guidance.laws.apollo.
    #: DescentPhases`); elsewhere they fly to their target directly
    lands_on_site: bool = False

    @abstractmethod
    def frame_function(self, scenario) -> Callable[[np.ndarray], Any]:
        """``frame_of(state_nd (N, n_state)) -> LocalFrame`` of the scenario's navigated states
        (:mod:`guidance.frames`)."""

    @abstractmethod
    def encoder(self, scenario, throttled: bool) -> Callable:
        """``encode(direction (N, d), throttle (N,) or None) -> actions (N, n_act) float32``:
        the env's actions of a thrust command in the guidance frame."""

    @abstractmethod
    def target_radius_m(self, scenario) -> float:
        """Distance from the body's centre of the terminal surface the frame measures height
        to (m)."""

    def thrust_elevation_bounds_rad(self, scenario) -> tuple[float, float] | None:
        """Bounds of the thrust's elevation above the local horizontal (None: unbounded in the
        guidance plane)."""
        return None


#: the guidance families, by ``scenario.family``
GUIDANCE_FAMILIES: FamilyRegistry[GuidanceFamily] = FamilyRegistry(
    "guidance", entry_point_group="lunar_env.guidance_families")
GUIDANCE_FAMILIES.register("planar", "guidance.families.planar:PlanarGuidance")
GUIDANCE_FAMILIES.register("pinpoint", "guidance.families.pinpoint:PinpointGuidance")
GUIDANCE_FAMILIES.register("pinpoint_touchdown", "guidance.families.touchdown:TouchdownGuidance")


def guidance_family(obj) -> GuidanceFamily:
    """The :class:`GuidanceFamily` of a scenario, env or flight computer."""
    return GUIDANCE_FAMILIES.of(obj)
