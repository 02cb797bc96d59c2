"""Gymnasium environments; importing :mod:`lunar_env` registers them.

- ``LunarSoftLanding-v0``: :class:`~lunar_env.envs.soft_landing.LunarSoftLandingEnv`
- ``LunarPinpointLanding-v0``: :class:`~lunar_env.envs.pinpoint_landing.LunarPinpointLandingEnv`

Both have a native vector env (``gym.make_vec(id, num_envs=N,
vectorization_mode="vector_entry_point")``).
"""

from gymnasium.envs.registration import register, registry

__all__ = ["register_envs"]

_ENVS = {
    "LunarSoftLanding-v0": ("soft_landing", "LunarSoftLandingEnv", "LunarSoftLandingVectorEnv"),
    "LunarPinpointLanding-v0": ("pinpoint_landing", "LunarPinpointLandingEnv",
                                "LunarPinpointLandingVectorEnv"),
}


def register_envs() -> None:
    """Register both ids (idempotent). The episode length is handled by the envs themselves
    (``time_limit_s``), so no ``TimeLimit`` wrapper is added."""
    for env_id, (mod, cls, vec_cls) in _ENVS.items():
        if env_id in registry:
            continue
        register(id=env_id, entry_point=f"lunar_env.envs.{mod}:{cls}",
                 vector_entry_point=f"lunar_env.envs.{mod}:{vec_cls}")


register_envs()
