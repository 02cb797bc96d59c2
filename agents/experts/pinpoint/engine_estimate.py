"""The engine's thrust-acceleration scale estimated from the navigation solution alone.

A guidance law does not know its engine's true thrust, Isp or the lander's true mass (issue 29's
plant errors); it knows its commands and the navigated state. Over one decision, the velocity
change the commanded thrust should give is the model's (the same equations of motion, integrated
from the navigated state with and without the thrust); the navigated velocity change minus the
model's thrust-free change is what the engine actually gave. Their least-squares ratio over the
flight is the scale of the thrust acceleration: the thrust error over the mass error, the one
number a constant-thrust extremal's feasibility depends on. Constant navigation biases cancel in
the differences; the per-decision navigation noise (0.1 m/s before the radar lock, against
~6 m/s of thrust per 2 s decision) averages to ~0.5 % in 25 decisions. As the accelerometers
of a real lander's navigation measure it, directly.
"""

from __future__ import annotations

import numpy as np

from lunar_env import integrators as integ
from lunar_env.dynamics import THROTTLE3

__all__ = ["ThrustScaleEstimator"]


class ThrustScaleEstimator:
    """Per-lander least-squares estimate of the thrust-acceleration scale (true / model).

    Call :meth:`observe` at every decision with the navigated states, before :meth:`record`
    stores the controls commanded from them; :attr:`scale` is the current estimate (1 until
    ``min_samples`` decisions of one flight have been seen).

    Parameters
    ----------
    params : Moon3DParams
        The nominal model (normalised).
    time_s : float
        The normalisation's time unit (s).
    velocity_m_s : float
        The normalisation's velocity unit (m/s).
    min_samples : int
        Decisions before the estimate is used.
    gate_m_s : float
        A decision whose residual against the current estimate exceeds this (m/s) is left
        out: the radar lock changes the navigation biases in one step (0.5 m/s before, a
        twentieth after, under ``standard``), which no engine does.
    substeps : int
        RK4 steps per decision of the model's prediction.
    """

    def __init__(self, params, time_s: float, velocity_m_s: float, *, min_samples: int = 5,
                 gate_m_s: float = 1.0, substeps: int = 4) -> None:
        self.params = params
        self.time_s = float(time_s)
        self.gate_nd = float(gate_m_s) / float(velocity_m_s)
        self.min_samples = int(min_samples)
        self.substeps = int(substeps)
        self.reset(0)

    def reset(self, n: int) -> None:
        """Forget everything; ``n`` landers."""
        self._sum_dr = np.zeros(n)
        self._sum_dd = np.zeros(n)
        self._count = np.zeros(n, dtype=np.int64)
        self._last: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None

    @property
    def scale(self) -> np.ndarray:
        """(N,) estimated thrust-acceleration scale (1 before ``min_samples`` decisions)."""
        ok = self._count >= self.min_samples
        return np.where(ok, self._sum_dr / np.where(ok, self._sum_dd, 1.0), 1.0)

    def _advance(self, state: np.ndarray, control: np.ndarray, dt_nd: np.ndarray) -> np.ndarray:
        """States (N, 7) after ``dt_nd`` (N,) holding ``control`` (N, 3): the env's RK4."""
        held = integ.PiecewisePolynomial.constant(control, np.zeros(len(dt_nd)), dt_nd)
        return integ.integrate(integ.MOON3D, state, t0_nd=0.0, dt_nd=dt_nd / self.substeps,
                               n_steps=self.substeps, control=held, params=self.params).y_end

    def observe(self, state_nd: np.ndarray, t_s: np.ndarray, active: np.ndarray) -> None:
        """Add the response to the previous decision's controls of the landers still flying."""
        if self._last is None:
            return
        x0, u0, t0, was = self._last
        dt_s = np.asarray(t_s, dtype=np.float64) - t0
        rows = was & np.asarray(active, dtype=bool) & (dt_s > 0.0)
        if not rows.any():
            return
        x0, u0 = x0[rows], u0[rows]
        dt_nd = dt_s[rows] / self.time_s
        coast = u0.copy()
        coast[:, THROTTLE3] = 0.0
        n = len(x0)  # the commanded and the thrust-free steps in one batch
        v = self._advance(np.concatenate([x0, x0]), np.concatenate([u0, coast]),
                          np.concatenate([dt_nd, dt_nd]))[:, 3:6]
        v_coast = v[n:]
        d = v[:n] - v_coast  # the model's thrust Δv
        r = np.asarray(state_nd, dtype=np.float64)[rows, 3:6] - v_coast  # the engine's
        s = self.scale[rows]
        keep = np.linalg.norm(r - s[:, None] * d, axis=1) <= self.gate_nd
        idx = np.flatnonzero(rows)[keep]
        self._sum_dr[idx] += np.sum(d[keep] * r[keep], axis=1)
        self._sum_dd[idx] += np.sum(d[keep] * d[keep], axis=1)
        self._count[idx] += 1

    def record(self, state_nd: np.ndarray, controls: np.ndarray, t_s: np.ndarray,
               active: np.ndarray) -> None:
        """The controls (α rad, β rad, throttle) (N, 3) commanded at this decision."""
        self._last = (np.array(state_nd, dtype=np.float64), np.array(controls, dtype=np.float64),
                      np.array(t_s, dtype=np.float64), np.array(active, dtype=bool))
