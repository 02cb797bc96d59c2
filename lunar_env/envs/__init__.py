"""Gymnasium environments; importing :mod:`lunar_env` registers them.

- ``LunarSoftLanding-v0``: :class:`~lunar_env.envs.soft_landing.LunarSoftLandingEnv`
- ``LunarPinpointLanding-v1``: :class:`~lunar_env.envs.pinpoint_landing.LunarPinpointLandingEnv`
  (``-v0``: the same env without the propellant charge of a failed landing,
  ``charge_propellant_on_failure=False``;
  ``-v2``: the 2 km gate counts only within 10 km of the target, ``gate_range_m=10000``)
- ``LunarPinpointLanding-v3``: :class:`~lunar_env.envs.pinpoint_touchdown.LunarPinpointTouchdownEnv`
  (to touchdown on the target with a throttleable engine, ``peng2012_touchdown``)

Each has a native vector env (``gym.make_vec(id, num_envs=N,
vectorization_mode="vector_entry_point")``).

Public API for code built on the envs (agents, adapters, benchmarks): the env bases
:class:`LanderEnv` and :class:`LanderVectorEnv`, :func:`validate_actions`, and the task
contract :class:`~lunar_env.envs.task.LandingTask` with its shared settings
:class:`~lunar_env.envs.task.StepSettings` (what a task supplies; ``env.task`` is one).
"""

from gymnasium.envs.registration import register, registry

from .base import LanderEnv, LanderVectorEnv, validate_actions
from .task import LandingTask, StepSettings

__all__ = ["register_envs", "LanderEnv", "LanderVectorEnv", "validate_actions", "LandingTask",
           "StepSettings"]

_ENVS = {
    "LunarSoftLanding-v0": ("soft_landing", "LunarSoftLandingEnv", "LunarSoftLandingVectorEnv",
                            {}),
    "LunarPinpointLanding-v1": ("pinpoint_landing", "LunarPinpointLandingEnv",
                                "LunarPinpointLandingVectorEnv", {}),
    # v2: v1 with the 2 km gate counting only within 10 km of the target
    "LunarPinpointLanding-v2": ("pinpoint_landing", "LunarPinpointLandingEnv",
                                "LunarPinpointLandingVectorEnv", {"gate_range_m": 10_000.0}),
    # v0: v1's reward without the propellant charge of a failed landing
    "LunarPinpointLanding-v0": ("pinpoint_landing", "LunarPinpointLandingEnv",
                                "LunarPinpointLandingVectorEnv",
                                {"charge_propellant_on_failure": False}),
    # v3: to touchdown on the target with a throttleable engine (its own task)
    "LunarPinpointLanding-v3": ("pinpoint_touchdown", "LunarPinpointTouchdownEnv",
                                "LunarPinpointTouchdownVectorEnv", {}),
}


def register_envs() -> None:
    """Register every id (idempotent). The episode length is handled by the envs themselves
    (``time_limit_s``), so no ``TimeLimit`` wrapper is added."""
    for env_id, (mod, cls, vec_cls, kwargs) in _ENVS.items():
        if env_id in registry:
            continue
        register(id=env_id, entry_point=f"lunar_env.envs.{mod}:{cls}",
                 vector_entry_point=f"lunar_env.envs.{mod}:{vec_cls}", kwargs=dict(kwargs))


register_envs()
