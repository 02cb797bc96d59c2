"""Stable-Baselines3 ``VecEnv`` over the natively batched landing envs.

SB3's ``DummyVecEnv`` loops over Python envs; :class:`LanderSB3VecEnv` instead steps the whole
batch of a native vector env (:mod:`lunar_env.envs`) in one compiled integrator call, with SB3's
conventions: same-step reset (the observation returned for a finished sub-env is the first
observation of its next episode; the last one is in ``info["terminal_observation"]``) and
``info["TimeLimit.truncated"]``. Wrap it in ``VecMonitor`` for episode statistics and in
``VecNormalize`` as usual.

>>> from agents.common.vec_env import make_sb3_vec_env
>>> venv = make_sb3_vec_env("LunarSoftLanding-v0", n_envs=4, seed=0)
>>> venv.reset().shape
(4, 5)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import VecEnv

import lunar_env  # noqa: F401  (registers the ids)
from lunar_env.envs import LanderVectorEnv, validate_actions

__all__ = ["LanderSB3VecEnv", "make_sb3_vec_env"]


class LanderSB3VecEnv(VecEnv):
    """SB3 ``VecEnv`` stepping a :class:`~lunar_env.envs.LanderVectorEnv` batch.

    :param native: the native vector env whose batch is stepped (its own NEXT_STEP autoreset
        is bypassed: this class resets finished sub-envs in the same step, as SB3 expects).

    Sub-env i draws its episodes from the generator seeded with ``seed + i`` (``seed()`` then
    ``reset()``), like ``DummyVecEnv``; its episodes are the same as those of a single env
    ``reset(seed=seed + i)`` and then reset without seed.
    """

    def __init__(self, native: LanderVectorEnv) -> None:
        if not isinstance(native, LanderVectorEnv):
            raise TypeError(f"native must be a lunar_env native vector env, got {type(native)}")
        self.native = native
        super().__init__(native.num_envs, native.single_observation_space,
                         native.single_action_space)
        self._actions: np.ndarray | None = None
        self._act_shape = (native.num_envs, *native.single_action_space.shape)

    # -- core -----------------------------------------------------------------------------------
    def reset(self) -> np.ndarray:
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        opts = self._options[0] if self._options and self._options[0] else None
        obs, _ = self.native.reset(seed=seeds, options=opts)
        self.reset_infos = [{} for _ in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = validate_actions(actions, self._act_shape)

    def step_wait(self):
        nat = self.native
        if self._actions is None:
            raise RuntimeError("step_wait() called without step_async()")
        out = nat.step_landers(self._actions)
        self._actions = None
        done = out["terminated"] | out["truncated"]
        obs = nat.observations()
        extra_keys = [k for k in nat.task.extra_info_keys if k in out]
        infos: list[dict[str, Any]] = []
        for i in range(self.num_envs):
            info: dict[str, Any] = {"fuel_used_kg": float(out["fuel_used_kg"][i]),
                                    "is_success": bool(out["is_success"][i]),
                                    "altitude_m": float(out["altitude_m"][i]),
                                    "time_s": float(out["time_s"][i])}
            if out["terminated"][i]:
                info["touchdown_speed_m_s"] = float(out["touchdown_speed_m_s"][i])
                for key in extra_keys:  # the task's own touchdown quantities (v3: the speeds)
                    if np.isfinite(out[key][i]):
                        info[key] = float(out[key][i])
            if nat.has_target and done[i]:
                info["miss_distance_m"] = float(out["miss_distance_m"][i])
            if done[i]:
                info["terminal_observation"] = obs[i].copy()
                info["TimeLimit.truncated"] = bool(out["truncated"][i] and
                                                   not out["terminated"][i])
            infos.append(info)
        if done.any():
            nat.reset_landers(np.flatnonzero(done))
            obs = nat.observations()
        return obs, out["reward"].astype(np.float32), done, infos

    def close(self) -> None:
        self.native.close()

    # -- attribute access (one shared batch: every index sees the same object) ------------------
    def _indices(self, indices) -> Sequence[int]:
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, int):
            return [indices]
        return indices

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return [getattr(self.native, attr_name) for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        setattr(self.native, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs):
        fn = getattr(self.native, method_name)
        return [fn(*method_args, **method_kwargs) for _ in self._indices(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None for _ in range(self.num_envs)]


def make_sb3_vec_env(env_id: str, n_envs: int, seed: int | None = None,
                     **env_kwargs: Any) -> VecEnv:
    """SB3 ``VecEnv`` of ``n_envs`` landers of ``env_id`` stepped as one batch.

    :param env_id: ``"LunarSoftLanding-v0"`` or ``"LunarPinpointLanding-v0"`` (a ``lunar_env:``
        prefix is accepted).
    :param n_envs: number of landers.
    :param seed: sub-env i uses ``seed + i`` (None: fresh entropy).
    :param env_kwargs: constructor arguments of the env (``scenario``, ``dt_s``, ...).
    """
    if int(n_envs) < 1:
        raise ValueError(f"n_envs = {n_envs!r} must be >= 1")
    native = gym.make_vec(env_id, num_envs=int(n_envs), vectorization_mode="vector_entry_point",
                          **env_kwargs)
    if not isinstance(native, LanderVectorEnv):
        raise ValueError(f"{env_id!r} has no lunar_env native vector env; use SB3's make_vec_env")
    venv = LanderSB3VecEnv(native)
    venv.seed(seed)
    return venv
