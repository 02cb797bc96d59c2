"""The engine's thrust-acceleration scale, measured by the IMU.

A guidance law does not know its engine's true thrust, Isp or the lander's true mass; it knows
its commands, the navigated state and what the accelerometers measure: the specific force, the
thrust acceleration along the thrust axis (``nav.sensors["imu"]``, the mean over the last
decision). Apollo's throttle routine computed the present thrust the same way, as the mass
estimate times the measured acceleration, so a weak engine was known within one guidance
cycle.

The thrust-acceleration scale is the measured acceleration at full throttle over the model's,
T/m̂, at the believed mass m̂: the last decision's measured specific force divided by the
throttle flown, brought from the step's middle mass to the present one. It folds the thrust
error τ and the mass error δ together, τ·m̂/(m̂ + δ), which is what a plan at the believed mass
needs; it is re-measured every decision, so it follows the scale as the propellant burns.
"""

from __future__ import annotations

import numpy as np

from lunar_env.validation import require_finite_positive

__all__ = ["ThrustScaleEstimator", "PlanEstimateFollowsFlight", "MIN_MEASURED_THROTTLE"]

#: below this throttle the last decision's measurement is not used (the accelerometers' bias
#: would dominate a nearly idle engine's acceleration)
MIN_MEASURED_THROTTLE = 0.05


class ThrustScaleEstimator:
    """Per-lander thrust-acceleration scale (true / model at the believed mass) from the IMU.

    Call :meth:`observe` at every decision with the IMU's reading and the believed masses,
    then :meth:`record` with the throttle flown from it; :attr:`scale` is the latest estimate
    (1 until a decision at a throttle of at least :data:`MIN_MEASURED_THROTTLE` has been
    measured).

    Parameters
    ----------
    thrust_n : float
        The nominal maximum thrust (N).
    """

    def __init__(self, thrust_n: float) -> None:
        self.thrust_n = require_finite_positive("thrust_n", thrust_n)
        self.reset(0)

    def reset(self, n: int) -> None:
        """Forget everything; ``n`` landers."""
        self._scale = np.ones(n)
        self._throttle = np.full(n, np.nan)
        self._mass_kg = np.full(n, np.nan)
        self._measured = np.zeros(n, dtype=bool)

    def reset_rows(self, rows) -> None:
        """Forget landers ``rows`` (their new episodes' engines are others)."""
        rows = np.atleast_1d(np.asarray(rows, dtype=np.int64))
        self._scale[rows] = 1.0
        self._throttle[rows] = np.nan
        self._mass_kg[rows] = np.nan
        self._measured[rows] = False

    @property
    def scale(self) -> np.ndarray:
        """(N,) the engine's thrust acceleration at full throttle over the model's T/m̂."""
        return self._scale

    @property
    def measured(self) -> np.ndarray:
        """(N,) bool: the lander's scale has been measured (else it is the model's, 1)."""
        return self._measured

    def observe(self, imu_m_s2: np.ndarray, mass_kg: np.ndarray, active: np.ndarray) -> None:
        """The response to the last decision: the IMU's specific force (N, d) (m/s²) measured
        over it, and the believed masses (N,) (kg) now, of the landers ``active``."""
        meas = np.linalg.norm(np.asarray(imu_m_s2, dtype=np.float64), axis=1)
        thr = self._throttle
        ok = (np.asarray(active, dtype=bool) & np.isfinite(thr)
              & (np.nan_to_num(thr) >= MIN_MEASURED_THROTTLE) & (meas > 0.0))
        if ok.any():
            m = np.asarray(mass_kg, dtype=np.float64)
            # the step's mean acceleration is the thrust over its middle mass
            mid = 0.5 * (self._mass_kg[ok] + m[ok])
            self._scale[ok] = meas[ok] / thr[ok] * mid / self.thrust_n
            self._measured |= ok

    def record(self, throttle: np.ndarray, mass_kg: np.ndarray, active: np.ndarray) -> None:
        """The throttles (N,) flown from the believed masses (N,) (kg) at this decision."""
        a = np.asarray(active, dtype=bool)
        self._throttle = np.where(a, np.asarray(throttle, dtype=np.float64), np.nan)
        self._mass_kg = np.where(a, np.asarray(mass_kg, dtype=np.float64), np.nan)

    def record_flown(self, computer, actions: np.ndarray, mass_kg: np.ndarray,
                     active: np.ndarray) -> None:
        """:meth:`record` of the throttles the env's engine flies for ``actions`` (N, n_act)
        (``computer.controls_from_actions``; full thrust without a throttle channel): what a
        law calls when another policy flew this decision (a DAgger student), so that the next
        reading is divided by the throttle that produced it, not by the law's own command."""
        controls = computer.controls_from_actions(np.asarray(actions, dtype=np.float64))
        throttle = controls[:, -1] if computer.throttled else np.ones(len(controls))
        self.record(throttle, mass_kg, active)


class PlanEstimateFollowsFlight:
    """The ``flown`` of a re-planning law with an engine estimate (convex re-planning, the
    touchdown re-planning law): ``estimator`` (a :class:`ThrustScaleEstimator`, or None
    without an IMU), ``computer`` and ``_mass_ref_kg`` (the believed mass is the navigated
    state's last component times it), set at ``reset``."""

    estimator: ThrustScaleEstimator | None
    _mass_ref_kg: float

    def flown(self, nav, actions: np.ndarray) -> None:
        """Another policy flew ``actions`` (N, n_act) at the decision of ``nav`` (this law
        is a DAgger teacher flying along): the thrust estimate records the throttle those
        actions gave the engine, not the plan's."""
        if self.estimator is not None and "imu" in nav.sensors:
            self.estimator.record_flown(self.computer, actions,
                                        nav.state_nd[:, -1] * self._mass_ref_kg, nav.active)
