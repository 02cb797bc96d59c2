"""The pinpoint family's curriculum starts: states along the minimum-fuel extremals, and their
position and velocity perturbation."""

from __future__ import annotations

import numpy as np

from agents.rl.starts import StartFamily
from lunar_env.validation import require_number, require_option_keys

__all__ = ["PinpointStarts"]


class PinpointStarts(StartFamily):
    """Start states of the 3D pinpoint landing."""

    def start_pool(self, scenario, n_trajectories: int, seed: int, n_points: int = 101,
                   progress: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """States along the minimum-fuel extremal of each dispersed start (compiled Pontryagin
        shooting, ~10 ms a case, warm-started along the draw), ``n_points`` per extremal (the
        gate excluded), shape (n_ok, n_points, 7), and their times (s). The extremals are the
        per-case optima of the serial GPM + shooting (fuel within 0.01 kg,
        tests/optimizers/test_pinpoint_feedback.py), at a hundredth of the cost.
        """
        from optimizers.indirect.pinpoint_feedback import (
            TARGET_REACHED_M,
            PinpointFeedback,
            extremal_path,
            solve_extremal,
        )

        rows = scenario.sample_initial(np.random.default_rng(seed), int(n_trajectories))
        fb = PinpointFeedback(scenario)
        s = scenario.scaling()
        states, times = [], []
        guess = None
        it = rows
        if progress:
            from tqdm.auto import tqdm

            it = tqdm(rows, desc=f"optimal start pool {scenario.name}", unit="case")
        for r in it:
            x0 = scenario.state_nd(r, scaling=s)
            sol = fb.solve(x0, guess)
            if sol is None or abs(sol.beyond_m) >= TARGET_REACHED_M:
                continue
            guess = sol.z
            # re-solved on the grid it is sampled on (the endpoint depends on the grid)
            step = sol.tgo_s / (4 * n_points)
            fine = solve_extremal(fb.k, x0, sol.z, step_s=step, min_steps=1)
            if not fine.converged:
                continue
            t, path = extremal_path(fb.k, x0, fine.z, step_s=step, min_steps=1)
            keep = np.arange(n_points) * 4  # n_points states, the last (the gate) excluded
            states.append(path[keep, :7])
            times.append(t[keep])
        if not states:
            raise RuntimeError("no optimal trajectory converged; cannot build the curriculum")
        return np.asarray(states), np.asarray(times)

    def start_noise_nd(self, scenario, noise: dict[str, float]) -> tuple[float, float]:
        """Validated ``{position_m, velocity_m_s}`` start perturbation, as standard deviations
        in the scenario's normalised units."""
        require_option_keys("start_noise", noise, ("position_m", "velocity_m_s"))
        pos, vel = (require_number(f"start_noise {k}", noise.get(k, 0.0))
                    for k in ("position_m", "velocity_m_s"))
        for key, v in (("position_m", pos), ("velocity_m_s", vel)):
            if not (np.isfinite(v) and v >= 0.0):
                raise ValueError(f"start_noise {key}={v!r} must be finite and >= 0")
        s = scenario.scaling()
        return pos / s.length_m, vel / s.velocity_m_s

    def perturb_starts(self, states_nd: np.ndarray, sigma_nd: tuple[float, float],
                       rng: np.random.Generator) -> np.ndarray:
        """Gaussian position and velocity errors (σ from :meth:`start_noise_nd`) added to
        curriculum starts (M, 7); a copy."""
        y = np.array(states_nd, dtype=np.float64, copy=True)
        sig_r, sig_v = sigma_nd
        y[:, 0:3] += rng.normal(0.0, sig_r, (len(y), 3))
        y[:, 3:6] += rng.normal(0.0, sig_v, (len(y), 3))
        return y
