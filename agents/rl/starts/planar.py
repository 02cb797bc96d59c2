"""The planar family's curriculum starts: states along the Pontryagin optima."""

from __future__ import annotations

import numpy as np

from agents.rl.starts import StartFamily

__all__ = ["PlanarStarts"]


class PlanarStarts(StartFamily):
    """Start states of the planar soft landing."""

    def start_pool(self, scenario, n_trajectories: int, seed: int, n_points: int = 101,
                   progress: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """States at ``n_points`` equal times along the Pontryagin optimum of each dispersed
        start (touchdown excluded), shape (n_ok, n_points, 5), and their times (s)."""
        from optimizers.indirect.batch import solve_many

        rows = scenario.sample_initial(np.random.default_rng(seed), int(n_trajectories))
        sols = [s for s in solve_many(scenario, rows, progress=progress) if s.success]
        if not sols:
            raise RuntimeError("no optimal trajectory converged; cannot build the curriculum")
        states, times = [], []
        for sol in sols:
            t = np.linspace(0.0, sol.tf_s, n_points + 1)[:-1]
            states.append(sol.state_costate_at(t)[:, :5])
            times.append(t)
        return np.asarray(states), np.asarray(times)
