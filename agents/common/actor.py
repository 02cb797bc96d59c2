"""The actor half of an SB3 actor-critic policy (behaviour cloning fits it; the critic warm-up
freezes it)."""

from __future__ import annotations

__all__ = ["actor_parameters"]


def actor_parameters(policy, include_log_std: bool = True) -> list:
    """The parameters of an SB3 actor-critic policy that only the actor uses (a features
    extractor shared with the critic is left out); ``include_log_std`` False leaves out the
    exploration noise too (behaviour cloning regresses the mean action only)."""
    parts = [policy.mlp_extractor.policy_net, policy.action_net]
    if not getattr(policy, "share_features_extractor", True):
        parts.append(policy.pi_features_extractor)
    params = [p for m in parts for p in m.parameters()]
    log_std = getattr(policy, "log_std", None) if include_log_std else None
    return params + ([log_std] if log_std is not None else [])
