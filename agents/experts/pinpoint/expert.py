"""The 3D pinpoint expert (``LunarPinpointLanding-v*``): :class:`PinpointPontryaginExpert`, the
optimal feedback of :mod:`optimizers.indirect.pinpoint_feedback` as a guidance law, and the
labeller of the pinpoint datasets and of DAgger."""

from __future__ import annotations

import numpy as np

from agents.common.law import FlightComputer, GuidanceLaw, Navigation
from lunar_env.envs.pinpoint_landing import action_from_angles
from optimizers.indirect.pinpoint_feedback import (
    PinpointFeedback,
)

__all__ = ["PinpointPontryaginExpert", "PINPOINT_LABEL_STATUSES"]

#: statuses of :class:`PinpointPontryaginExpert` decisions that are the extremal's law, hence
#: labels; "stale" and "fallback" (no converged solve) are guesses and are not
PINPOINT_LABEL_STATUSES = ("optimal", "nearest", "hold")


class PinpointPontryaginExpert(GuidanceLaw):
    """Closed-loop optimal feedback for ``LunarPinpointLanding-v*``: at every decision the
    minimum-time extremal from the lander's current state (:class:`optimizers.indirect.
    pinpoint_feedback.PinpointFeedback`, compiled Pontryagin shooting warm-started from the
    previous decision's extremal, ~1-15 ms), flown over the env step as its mean angle.

    A guidance law on the navigation solution (:meth:`act`), and the labeller of the pinpoint
    datasets and of DAgger (:meth:`labels`, which the privileged teachers call with the truth).
    Where the target is out of reach (a lander too
    fast to stop at it), the extremal to the nearest reachable stop on the track is flown;
    the per-decision statuses are counted in :attr:`status_counts`.

    Parameters
    ----------
    scenario : PinpointScenario
    feedback_kwargs : forwarded to :class:`PinpointFeedback` (``step_s``, ``hold_s``, ...).
    """

    name = "Pontryagin feedback expert"

    def __init__(self, scenario, **feedback_kwargs) -> None:
        self.scenario = scenario
        self.feedback = PinpointFeedback(scenario, **feedback_kwargs)
        self.status_counts: dict[str, int] = {}

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        """New flights: forget the previous extremals, and keep them above the gate where the
        env counts it (its ``gate_range_m``: near the target in v2, everywhere in v0/v1)."""
        super().reset(computer, case_ids)
        self.feedback.reset()
        self.feedback.gate_floor_range_m = computer.gate_range_m

    def angles(self, states_nd: np.ndarray, t_s: np.ndarray, dt_s: float,
               active: np.ndarray | None = None) -> np.ndarray:
        """(α, β) (rad), (B, 2), of the extremals from states (B, 7) at episode times (B,)."""
        ang = self.feedback(states_nd, t_s, dt_s, active)
        act = np.ones(len(ang), dtype=bool) if active is None else np.asarray(active, bool)
        for st, a in zip(self.feedback.last_status, act, strict=True):
            if a:
                self.status_counts[st] = self.status_counts.get(st, 0) + 1
        return ang

    def labels(self, state_nd: np.ndarray, t_s: np.ndarray, active: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The expert's decision at normalised states (B, 7) and episode times (B,) (s).

        Returns ``(angles, actions, is_label)``: (α, β) (rad) and the env actions (float32),
        both (B, 2), and (B,) bool: the row is active (``active``; None: all) and its status is
        one of :data:`PINPOINT_LABEL_STATUSES`. Call :meth:`reset` first.
        """
        ang = self.angles(state_nd, t_s, self.computer.dt_s, active)
        sc = self.scenario
        actions = action_from_angles(ang[:, 0], ang[:, 1], sc.alpha_bounds_rad,
                                     sc.beta_bounds_rad).astype(np.float32)
        is_label = np.isin(np.asarray(self.last_status), PINPOINT_LABEL_STATUSES)
        if active is not None:
            is_label &= np.asarray(active, dtype=bool)
        return ang, actions, is_label

    def act(self, nav: Navigation) -> np.ndarray:
        return self.computer.at_full_thrust(self.labels(nav.state_nd, nav.t_s, nav.active)[1])

    @property
    def last_status(self) -> list[str]:
        return self.feedback.last_status
