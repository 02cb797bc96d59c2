"""The engine's thrust-acceleration scale estimated from the navigation solution alone.

A guidance law does not know its engine's true thrust, Isp or the lander's true mass (issue 29's
plant errors); it knows its commands and the navigated state. Over one decision, the velocity
change the commanded thrust should give is the model's (the same equations of motion, integrated
from the navigated state with and without the thrust); the navigated velocity change minus the
model's thrust-free change is what the engine actually gave. Constant navigation biases cancel
in the differences; the per-decision navigation noise (0.1 m/s before the radar lock, against
~6 m/s of thrust per 2 s decision) averages out. As the accelerometers of a real lander's
navigation measure it, directly.

Their ratio is not one number over a flight. The flight computer's mass is the planned initial
mass minus the propellant burnt, so it is off by the initial mass error δ throughout, and the
true thrust acceleration is τ·m/(m + δ) times the model's at the believed mass m (τ: true /
nominal thrust): a lander 12 kg heavier than planned has 98.0 % of the model's acceleration at
600 kg and 96.3 % at 323 kg, near the end. Both τ and δ are estimated, by least squares on
τ·m·d − δ·r = m·r (d the model's thrust Δv, r the engine's, m the believed mass; the r
multiplying δ predicted from the current estimate) with the
gauging's prior on δ and a loose one on τ, and the scale is read at the current mass: a single
flight-average ratio lags the falling scale and the plan drifts long (measured on a development
case, issue 31: 0.972 estimated against 0.963 at the end, the stop drifting 500 m in 170 s).
"""

from __future__ import annotations

import numpy as np

from lunar_env import integrators as integ
from lunar_env.dynamics import THROTTLE3
from lunar_env.validation import require_finite_positive

__all__ = ["ThrustScaleEstimator"]


class ThrustScaleEstimator:
    """Per-lander estimate of the thrust-acceleration scale (true / model) at the believed mass.

    Call :meth:`observe` at every decision with the navigated states, before :meth:`record`
    stores the controls commanded from them; :attr:`scale` is the current estimate (1 until
    ``min_samples`` decisions of one flight have been seen), :attr:`thrust_scale` and
    :attr:`mass_error_kg` its two parameters.

    Parameters
    ----------
    params : Moon3DParams
        The nominal model (normalised).
    time_s : float
        The normalisation's time unit (s).
    velocity_m_s : float
        The normalisation's velocity unit (m/s).
    mass_kg : float
        The normalisation's mass unit (kg).
    min_samples : int
        Decisions before the estimate is used.
    gate_m_s : float
        A decision whose residual against the current estimate exceeds this (m/s) is left
        out: the radar lock changes the navigation biases in one step (0.5 m/s before, a
        twentieth after, under ``standard``), which no engine does.
    velocity_noise_m_s : float
        1σ of a navigated velocity change's noise per axis (m/s; ``standard``: 0.1 m/s on
        each of two decisions).
    mass_sigma_kg : float
        1σ of the initial mass error the gauging leaves (kg; ``standard``: 6 kg), the prior
        on δ.
    thrust_sigma : float
        1σ of the prior on τ around 1 (loose: 2.5 times ``standard``'s 2 %).
    substeps : int
        RK4 steps per decision of the model's prediction.
    """

    def __init__(self, params, time_s: float, velocity_m_s: float, mass_kg: float, *,
                 min_samples: int = 5, gate_m_s: float = 1.0,
                 velocity_noise_m_s: float = 0.14, mass_sigma_kg: float = 6.0,
                 thrust_sigma: float = 0.05, substeps: int = 4) -> None:
        self.params = params
        self.time_s = float(time_s)
        self.gate_nd = float(gate_m_s) / float(velocity_m_s)
        self.noise_nd = (require_finite_positive("velocity_noise_m_s", velocity_noise_m_s)
                         / float(velocity_m_s))
        self.mass_kg = float(mass_kg)
        # the prior, as information on (τ, δ_nd) about (1, 0)
        self._prior = np.diag([
            1.0 / require_finite_positive("thrust_sigma", thrust_sigma) ** 2,
            (self.mass_kg / require_finite_positive("mass_sigma_kg", mass_sigma_kg)) ** 2])
        self.min_samples = int(min_samples)
        self.substeps = int(substeps)
        self.reset(0)

    def reset(self, n: int) -> None:
        """Forget everything; ``n`` landers."""
        self._info = np.zeros((n, 2, 2))  # normal equations of (τ, δ_nd), prior excluded
        self._rhs = np.zeros((n, 2))
        self._mass_nd = np.ones(n)  # the believed mass at the last observation
        self._count = np.zeros(n, dtype=np.int64)
        self._last: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None

    def reset_rows(self, rows) -> None:
        """Forget what was learnt of landers ``rows`` (their new episodes' engines are others):
        their samples, and the decision the next observation would be the response to."""
        rows = np.atleast_1d(np.asarray(rows, dtype=np.int64))
        if not len(rows):
            return
        self._info[rows] = 0.0
        self._rhs[rows] = 0.0
        self._count[rows] = 0
        if self._last is not None:
            was = self._last[3].copy()
            was[rows] = False
            self._last = (*self._last[:3], was)

    def _parameters(self) -> np.ndarray:
        """(N, 2): (τ, δ_nd) of each lander, the prior's (1, 0) before any sample."""
        info = self._info + self._prior
        rhs = self._rhs + self._prior @ np.array([1.0, 0.0])
        return np.linalg.solve(info, rhs[..., None])[..., 0]

    @property
    def thrust_scale(self) -> np.ndarray:
        """(N,) estimated true / nominal thrust τ (1 before ``min_samples`` decisions)."""
        ok = self._count >= self.min_samples
        return np.where(ok, self._parameters()[:, 0], 1.0)

    @property
    def mass_error_kg(self) -> np.ndarray:
        """(N,) estimated true minus believed mass δ (kg; 0 before ``min_samples``)."""
        ok = self._count >= self.min_samples
        return np.where(ok, self._parameters()[:, 1] * self.mass_kg, 0.0)

    @property
    def scale(self) -> np.ndarray:
        """(N,) estimated thrust-acceleration scale τ·m/(m + δ) at the last believed mass m
        (1 before ``min_samples`` decisions)."""
        ok = self._count >= self.min_samples
        tau, delta = self._parameters().T
        m = self._mass_nd
        return np.where(ok, tau * m / np.maximum(m + delta, 1e-9 * m), 1.0)

    def _advance(self, state: np.ndarray, control: np.ndarray, dt_nd: np.ndarray) -> np.ndarray:
        """States (N, 7) after ``dt_nd`` (N,) holding ``control`` (N, 3): the env's RK4."""
        held = integ.PiecewisePolynomial.constant(control, np.zeros(len(dt_nd)), dt_nd)
        return integ.integrate(integ.MOON3D, state, t0_nd=0.0, dt_nd=dt_nd / self.substeps,
                               n_steps=self.substeps, control=held, params=self.params).y_end

    def observe(self, state_nd: np.ndarray, t_s: np.ndarray, active: np.ndarray) -> None:
        """Add the response to the previous decision's controls of the landers still flying."""
        state_nd = np.asarray(state_nd, dtype=np.float64)
        active = np.asarray(active, dtype=bool)
        self._mass_nd = np.where(active, state_nd[:, 6], self._mass_nd)
        if self._last is None:
            return
        x0, u0, t0, was = self._last
        dt_s = np.asarray(t_s, dtype=np.float64) - t0
        rows = was & active & (dt_s > 0.0)
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
        d = v[:n] - v_coast  # the model's thrust Δv at the believed mass
        r = state_nd[rows, 3:6] - v_coast  # the engine's
        s = self.scale[rows]
        keep = np.linalg.norm(r - s[:, None] * d, axis=1) <= self.gate_nd
        idx = np.flatnonzero(rows)[keep]
        d, r, s = d[keep], r[keep], s[keep]
        m = 0.5 * (x0[keep, 6] + state_nd[idx, 6])  # the believed mass over the step
        # τ·m·d − δ·r = m·r per axis, with r in the δ column predicted (s·d) rather than
        # measured: the two columns are nearly parallel, so the noise of a measured r there
        # biases δ (errors in variables: measured, 22 kg on a flight without a mass error);
        # the equation's noise is m times the noise of r
        a = np.stack([m[:, None] * d, -s[:, None] * d], axis=2)  # (k, 3, 2)
        w = 1.0 / (m * self.noise_nd) ** 2
        self._info[idx] += w[:, None, None] * np.einsum("kai,kaj->kij", a, a)
        self._rhs[idx] += w[:, None] * np.einsum("kai,ka->ki", a, m[:, None] * r)
        self._count[idx] += 1

    def record(self, state_nd: np.ndarray, controls: np.ndarray, t_s: np.ndarray,
               active: np.ndarray) -> None:
        """The controls (α rad, β rad, throttle) (N, 3) commanded at this decision."""
        self._last = (np.array(state_nd, dtype=np.float64), np.array(controls, dtype=np.float64),
                      np.array(t_s, dtype=np.float64), np.array(active, dtype=bool))
