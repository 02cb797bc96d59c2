"""Start-state curriculum from optimal trajectories (a reverse curriculum for the landing envs).

Why: the soft landing is a thin target for exploration. The lander's engine only steers, the
propellant margin over the optimum is ~8 % (277 of 300 kg for ``zhu2007``), and a policy that
wastes a few percent of its thrust on exploration noise runs dry and crashes. Almost every
episode of an untrained policy ends in a crash at hundreds of m/s, so PPO sees almost no signal
of what a landing looks like (measured: 0 successes in 2·10⁶ steps from the dispersion alone).

What: with probability ``p`` an episode does not start from the scenario's dispersion but from a
point of a minimum-fuel trajectory (Pontryagin, :func:`optimizers.indirect.batch.solve_many`) of a
dispersed case, at a uniformly drawn fraction of its flight time, with the episode clock set to
that time (so the observation's time feature is consistent). Late starts teach the endgame first;
``p`` decays linearly from ``start_prob`` to 0 over the first ``anneal_fraction`` of training, so
the last part of training — and every evaluation — uses the true initial-state distribution
(Florensa et al. 2017, "Reverse curriculum generation"; Salimans & Chen 2018, "Learning
Montezuma's Revenge from a single demonstration"). The policy is never shown an optimal action:
only states to start from.

Soft landing: Pontryagin optima. Pinpoint landing: the env's per-case optimum of
:mod:`optimizers.optimum.pinpoint` (serial GPM + direct shooting, cached), its shooting nodes
as the
pool.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnvWrapper

from agents.rl.starts import START_FAMILIES
from lunar_env.validation import require_finite_positive, require_integer, require_number

__all__ = ["ErrorScaleCurriculum", "OptimalStartCurriculum", "optimal_start_pool"]


def optimal_start_pool(scenario, n_trajectories: int, seed: int, n_points: int = 101,
                       progress: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """States along minimum-fuel trajectories of ``n_trajectories`` dispersed cases, from the
    scenario's env family (:meth:`agents.rl.starts.StartFamily.start_pool`).

    Returns
    -------
    states_nd : ndarray, shape (n_ok, n_points, n_state)
        Normalised states at ``n_points`` equally spaced times of each converged solution (the
        last point, touchdown or the gate, excluded: nothing is left to learn there).
    times_s : ndarray, shape (n_ok, n_points)
        Time since the case's initial state (s).
    """
    return START_FAMILIES.of(scenario).start_pool(scenario, n_trajectories, seed, n_points=n_points,
                                          progress=progress)


class OptimalStartCurriculum(VecEnvWrapper):
    """Start a share of the episodes from states on optimal trajectories (see module docstring).

    :param venv: an :class:`agents.common.vec_env.LanderSB3VecEnv` of ``LunarSoftLanding-v0``
        (it must be the innermost env: the wrapper sets the native batch's state).
    :param total_timesteps: training length; ``p`` reaches 0 at ``anneal_fraction`` of it.
    :param start_prob: ``p`` at the start of training.
    :param anneal_fraction: fraction of training over which ``p`` decays linearly to 0.
    :param n_trajectories: dispersed cases solved to build the pool of start states.
    :param min_time_fraction, max_time_fraction: start times are drawn uniformly in this
        fraction of each optimal flight time.
    :param seed: seed of the cases and of the draws.
    :param pool_seed: seed of the pool's cases if not ``seed``. The pinpoint entry in
        ``ppo.yml`` fixes it, so that every training seed starts from the same optimal
        trajectories (the draws of start points along them still follow ``seed``).
    :param start_noise: ``None`` or ``{position_m, velocity_m_s}`` (pinpoint env): Gaussian
        perturbations (σ per Cartesian component) added to every curriculum start, so that
        the policy also starts *off* the optimal trajectories and learns to recover (the
        states its own errors lead to), as DART (Laskey et al. 2017) does for imitation.
    :param progress: progress bar while solving.

    Every finished episode's ``info`` gets ``start_fraction``: the fraction of the optimal
    flight time it started at, NaN for a start from the dispersion (the evaluation's
    distribution), so that a log can tell the two apart.
    """

    def __init__(self, venv, total_timesteps: int, start_prob: float = 0.8,
                 anneal_fraction: float = 0.7, n_trajectories: int = 256,
                 min_time_fraction: float = 0.0, max_time_fraction: float = 1.0,
                 seed: int = 0, pool_seed: int | None = None,
                 start_noise: dict[str, float] | None = None, progress: bool = True) -> None:
        super().__init__(venv)
        native = getattr(venv, "native", None)
        if native is None or not hasattr(native, "scenario"):
            raise TypeError("OptimalStartCurriculum wraps the LanderSB3VecEnv of "
                            "agents.common.vec_env.make_sb3_vec_env directly")
        if not (0.0 <= start_prob <= 1.0):
            raise ValueError(f"start_prob={start_prob!r} must be in [0, 1]")
        if not (0.0 < anneal_fraction <= 1.0):
            raise ValueError(f"anneal_fraction={anneal_fraction!r} must be in (0, 1]")
        if not (0.0 <= min_time_fraction < max_time_fraction <= 1.0):
            raise ValueError("need 0 <= min_time_fraction < max_time_fraction <= 1, got "
                             f"{min_time_fraction!r}, {max_time_fraction!r}")
        self.native = native
        self.total_timesteps = int(total_timesteps)
        self.start_prob = float(start_prob)
        self.anneal_fraction = float(anneal_fraction)
        self.min_time_fraction = float(min_time_fraction)
        self.max_time_fraction = float(max_time_fraction)
        self.rng = np.random.default_rng(seed + 7919)
        t0 = time.perf_counter()
        self.pool_states, self.pool_times = optimal_start_pool(
            native.scenario, n_trajectories, seed if pool_seed is None else int(pool_seed),
            progress=progress)
        self.pool_build_s = time.perf_counter() - t0
        self.family = START_FAMILIES.of(native.scenario)
        self.start_noise_nd = (self.family.start_noise_nd(native.scenario, start_noise)
                               if start_noise else None)
        self.num_timesteps = 0
        self.n_curriculum_starts = 0
        self.n_starts = 0
        self.start_fraction = np.full(self.num_envs, np.nan)

    @property
    def current_prob(self) -> float:
        """``p`` at the current training step."""
        frac = self.num_timesteps / max(self.total_timesteps * self.anneal_fraction, 1.0)
        return self.start_prob * max(0.0, 1.0 - frac)

    def _restart(self, idx: np.ndarray, obs: np.ndarray) -> np.ndarray:
        """Move sub-envs ``idx`` (just reset) to pool states with probability ``p``."""
        self.n_starts += len(idx)
        self.start_fraction[idx] = np.nan
        p = self.current_prob
        if p <= 0.0 or len(idx) == 0:
            return obs
        pick = idx[self.rng.random(len(idx)) < p]
        if len(pick) == 0:
            return obs
        n_traj, n_pts = self.pool_times.shape
        k = self.rng.integers(0, n_traj, len(pick))
        lo = int(np.floor(self.min_time_fraction * n_pts))
        hi = max(int(np.ceil(self.max_time_fraction * n_pts)), lo + 1)
        j = self.rng.integers(lo, hi, len(pick))
        self.start_fraction[pick] = j / n_pts
        y = self.pool_states[k, j]
        if self.start_noise_nd is not None:
            y = self.family.perturb_starts(y, self.start_noise_nd, self.rng)
        t_s = self.pool_times[k, j]
        self.native.set_states(pick, y, t_s)
        obs = np.array(obs, copy=True)
        # the sensor channels after the task's (sensors=("imu",)) keep the reset's reading: a
        # lander that has flown no step of its episode reads the sensor's errors alone
        n_task = self.native.task.n_base_obs
        obs[pick, :n_task] = self.native.observation_from_state(y, t_s)[:, :n_task]
        self.n_curriculum_starts += len(pick)
        return obs

    def reset(self) -> np.ndarray:
        obs = self.venv.reset()
        return self._restart(np.arange(self.num_envs), obs)

    def step_wait(self):
        obs, rew, done, infos = self.venv.step_wait()
        self.num_timesteps += self.num_envs
        if done.any():
            idx = np.flatnonzero(done)
            for i in idx:
                infos[i]["start_fraction"] = float(self.start_fraction[i])
            obs = self._restart(idx, obs)
        return obs, rew, done, infos


class ErrorScaleCurriculum(VecEnvWrapper):
    """Anneal the env's plant and navigation errors in: every σ of its uncertainty model is
    multiplied by a scale (:meth:`lunar_env.envs.base.LanderVectorEnv.set_error_scale`) that
    grows from ``start_scale`` to ``final_scale`` (1 by default, so the end of training flies
    the full model; above 1, training holds a margin over the model a campaign judges).
    Evaluation envs are not wrapped: checkpoints are judged at the env's own model (× 1).

    Two schedules, and their maximum when both are given:

    - **by step count** (the default): the scale grows linearly from ``start_scale`` to
      ``final_scale`` over the first ``anneal_fraction`` of training, then stays there;
    - **by success** (``success_threshold`` set): the scale starts at ``start_scale`` and
      rises by ``scale_step`` (up to ``final_scale``) each time ``window_episodes`` training
      episodes in a row (all finished episodes, curriculum starts included) have landed at a
      rate of at least ``success_threshold``; a window that lands less leaves it where it is
      (it never falls). The step-count schedule stays as a floor, so a policy that stops
      improving still meets ``final_scale`` by ``anneal_fraction``; ``anneal_fraction:
      None`` removes the floor (the scale then ends wherever the policy's landings took it,
      and :attr:`current_scale` at the end says how far that was).

    Why: under the full ``standard`` set a pinpoint policy that has not yet learnt to land
    almost never reaches the gate slowly enough to meet the success bonus (two seeds of the
    shipped entry trained under it landed 0 of 100 cases, even without errors); with smaller
    errors first, the policy learns the landing and then its margins, as the start curriculum
    teaches the endgame first. The step-count
    schedule can outrun the policy (a seed that landed 5.6 % of its training episodes at ×0.6
    lost them all by ×1): the success schedule raises the errors only as fast as the policy
    keeps landing.

    :param venv: a vector env whose innermost env is the native
        :class:`~lunar_env.envs.base.LanderVectorEnv` with an uncertainty model (reached as
        ``venv.native``).
    :param total_timesteps: the training length the schedule refers to.
    :param start_scale: the scale at step 0, in [0, ``final_scale``].
    :param final_scale: the scale the schedules end at, > 0 (1: the env's own model).
    :param anneal_fraction: the share of training, in (0, 1], after which the scale is
        ``final_scale``;
        ``None`` (only with ``success_threshold``): no step-count schedule.
    :param success_threshold: ``None`` (step count only) or the training success rate, in
        (0, 1], a window must reach for the scale to rise.
    :param scale_step: the rise per successful window, in (0, 1].
    :param window_episodes: finished episodes per window, >= 1.

    The success schedule's state (:meth:`state_dict`) is saved with every checkpoint and
    restored by ``--resume`` (:func:`agents.rl.training.train`).
    """

    #: the scale is re-applied when it has moved by this much (each change rebuilds the task)
    STEP = 0.01

    def __init__(self, venv, total_timesteps: int, start_scale: float = 0.0,
                 anneal_fraction: float | None = 0.5, success_threshold: float | None = None,
                 scale_step: float = 0.05, window_episodes: int = 1000,
                 final_scale: float = 1.0) -> None:
        super().__init__(venv)
        native = getattr(venv, "native", None)
        if native is None or not hasattr(native, "set_error_scale"):
            raise TypeError("ErrorScaleCurriculum needs the native lunar_env vector env inside "
                            "(agents.common.vec_env.make_sb3_vec_env)")
        final_scale = require_finite_positive("final_scale", final_scale)
        start_scale = require_number("start_scale", start_scale)
        if not (0.0 <= start_scale <= final_scale):
            raise ValueError(f"start_scale={start_scale!r} must be in [0, final_scale="
                             f"{final_scale!r}]")
        if success_threshold is not None and not (0.0 < success_threshold <= 1.0):
            raise ValueError(f"success_threshold={success_threshold!r} must be None or in (0, 1]")
        if anneal_fraction is None:
            if success_threshold is None:
                raise ValueError("anneal_fraction=None (no step-count schedule) needs a "
                                 "success_threshold: the scale would never move")
        elif not (0.0 < anneal_fraction <= 1.0):
            raise ValueError(f"anneal_fraction={anneal_fraction!r} must be in (0, 1] or None")
        if not (0.0 < scale_step <= 1.0):
            raise ValueError(f"scale_step={scale_step!r} must be in (0, 1]")
        self.native = native
        self.total_timesteps = int(total_timesteps)
        self.start_scale = float(start_scale)
        self.final_scale = float(final_scale)
        self.anneal_fraction = None if anneal_fraction is None else float(anneal_fraction)
        self.success_threshold = None if success_threshold is None else float(success_threshold)
        self.scale_step = float(scale_step)
        self.window_episodes = require_integer("window_episodes", window_episodes, minimum=1)
        self.num_timesteps = 0
        self.success_scale = self.start_scale
        self._window: list[bool] = []
        # always set once: the env refuses it (by name) when it flies without errors
        native.set_error_scale(self.current_scale)

    @property
    def step_scale(self) -> float:
        """The step-count schedule's scale at the current training step (``start_scale``
        without one)."""
        if self.anneal_fraction is None:
            return self.start_scale
        frac = self.num_timesteps / max(self.total_timesteps * self.anneal_fraction, 1.0)
        return min(self.final_scale,
                   self.start_scale + (self.final_scale - self.start_scale) * frac)

    @property
    def current_scale(self) -> float:
        """The error scale at the current training step (the larger of the two schedules)."""
        if self.success_threshold is None:
            return self.step_scale
        return max(self.step_scale, self.success_scale)

    def apply(self) -> None:
        """Set the env's error scale to :attr:`current_scale` if it moved by :attr:`STEP` (or
        reached ``final_scale``)."""
        k = self.current_scale
        if abs(k - self.native.error_scale) >= self.STEP or (
                k == self.final_scale != self.native.error_scale):
            self.native.set_error_scale(k)

    def record_episodes(self, successes) -> None:
        """Count finished episodes' verdicts for the success schedule (no-op without it)."""
        if self.success_threshold is None:
            return
        for ok in successes:
            self._window.append(bool(ok))
            if len(self._window) >= self.window_episodes:
                if np.mean(self._window) >= self.success_threshold:
                    self.success_scale = min(self.final_scale,
                                             self.success_scale + self.scale_step)
                self._window.clear()

    def state_dict(self) -> dict[str, Any]:
        """The success schedule's state (plain YAML types), for checkpoints."""
        return {"success_scale": float(self.success_scale),
                "window": [bool(x) for x in self._window]}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` (a resumed run), then apply the scale."""
        scale = float(state["success_scale"])
        if not (0.0 <= scale <= self.final_scale):
            raise ValueError(f"success_scale={scale!r} in the saved state must be in "
                             f"[0, final_scale={self.final_scale!r}]")
        self.success_scale = scale
        self._window = [bool(x) for x in state.get("window", [])]
        self.apply()

    def reset(self) -> np.ndarray:
        return self.venv.reset()

    def step_wait(self):
        obs, rew, done, infos = self.venv.step_wait()
        self.num_timesteps += self.num_envs
        if done.any():
            self.record_episodes(bool(infos[i].get("is_success")) for i in np.flatnonzero(done))
        self.apply()
        return obs, rew, done, infos
