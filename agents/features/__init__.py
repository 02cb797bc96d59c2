"""Derived observation features for the landing policies (agents side; the env is unchanged).

Each env family defines its own features (a :class:`FeatureFamily` registered in
:data:`FEATURE_FAMILIES`): the planar soft landing's in :mod:`agents.features.planar`, the
pinpoint landing's in :mod:`agents.features.pinpoint`, the landing to touchdown's in
:mod:`agents.features.touchdown`. This module is the generic part: it
validates the names, asks the env's family for the features and their bounds, and wraps vec
envs and policy inputs.

The features are computed **from the env's observation alone** (which is an invertible scaling
of the physical state, up to the observation clipping), so the same function serves training,
the terminal observations SB3 bootstraps from, and evaluation, and a policy trained with
features can be replayed exactly: the run's ``config.yml`` records ``obs_features`` and
:class:`agents.laws.SB3Law` re-applies them.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from stable_baselines3.common.vec_env.base_vec_env import VecEnvWrapper

from lunar_env.families import FamilyRegistry, family_name

__all__ = ["FeatureFamily", "FEATURE_FAMILIES", "augment_observation", "feature_constants",
           "validate_features", "ObsFeatureWrapper", "StandardizedInputs",
           "standardized_inputs_kwargs"]


class FeatureFamily(ABC):
    """The observation features of an env family (YAML ``obs_features``)."""

    #: feature name -> number of columns it appends, in the order of the names
    widths: dict[str, int] = {}

    def constants(self, env) -> dict[str, Any]:
        """What the features need from ``env`` (an env, native vector env or flight computer)
        besides its ``physical_constants()`` and decoding (none by default)."""
        return {}

    @abstractmethod
    def augment(self, obs: np.ndarray, consts: dict[str, Any], names: Sequence[str]
                ) -> np.ndarray:
        """The observations (B, n_obs) with the features ``names`` (at least one) appended,
        float32 (``consts``: :func:`feature_constants` of the env)."""

    @abstractmethod
    def bounds(self, names: Sequence[str]) -> tuple[list[float], list[float]]:
        """Lower and upper bounds of the columns the features ``names`` append."""


#: the observation features of each env family, by ``scenario.family``
FEATURE_FAMILIES: FamilyRegistry[FeatureFamily] = FamilyRegistry(
    "observation-feature", entry_point_group="lunar_env.feature_families")
FEATURE_FAMILIES.register("planar", "agents.features.planar:PlanarFeatures")
FEATURE_FAMILIES.register("pinpoint", "agents.features.pinpoint:PinpointFeatures")
FEATURE_FAMILIES.register("pinpoint_touchdown", "agents.features.touchdown:TouchdownFeatures")


def validate_features(names: Sequence[str] | None) -> list[str]:
    """The feature names as a list; raises ``ValueError`` on unknown or repeated names."""
    if names is None:
        return []
    if isinstance(names, str):
        raise TypeError(f"obs_features={names!r} must be a list of names, not a string")
    out = [str(n) for n in names]
    allowed = {n for fam in FEATURE_FAMILIES.names()
               for n in FEATURE_FAMILIES.get(fam).widths}
    bad = [n for n in out if n not in allowed]
    if bad:
        raise ValueError(f"unknown obs_features {bad}; allowed: {sorted(allowed)}")
    if len(set(out)) != len(out):
        raise ValueError(f"obs_features {out} repeats a name")
    return out


def feature_constants(env) -> dict:
    """What the features need from a landing env, through its public API.

    ``env``: a lander env (single or native vector, or its flight computer): its
    ``physical_constants()`` (thrust, exhaust velocity, dry mass, surface gravity, nominal
    propellant), under ``"decode"`` its ``observation_quantities`` — the env's own inverse of its
    observation, so a change to the observation cannot silently break trained features —, under
    ``"family"`` the name of its env family, and what that family's features need besides
    (:meth:`FeatureFamily.constants`).

    Raises ``TypeError`` for an env that is not a lunar_env landing env.
    """
    if not hasattr(env, "observation_quantities") or not hasattr(env, "physical_constants"):
        raise TypeError("observation features are defined for the lunar_env landing envs only")
    try:
        consts: dict = dict(env.physical_constants())
    except TypeError:
        raise TypeError("observation features are defined for the lunar_env landing envs "
                        "only") from None
    consts["decode"] = env.observation_quantities
    name = family_name(env)
    consts["family"] = name
    consts.update(FEATURE_FAMILIES.get(name).constants(env))
    return consts


def augment_observation(obs: np.ndarray, consts: dict, names: Sequence[str]) -> np.ndarray:
    """Append the features ``names`` to env observations.

    Parameters
    ----------
    obs : ndarray, shape (B, n_obs)
        The env's observations.
    consts : dict
        :func:`feature_constants` of the env.
    names : sequence of str
        Feature names of the env's family (:attr:`FeatureFamily.widths`).

    Returns
    -------
    ndarray, shape (B, n_obs + Σ widths), float32
    """
    obs = np.asarray(obs)
    if not names:
        return obs.astype(np.float32, copy=False)
    return FEATURE_FAMILIES.get(consts["family"]).augment(obs, consts, names)


class ObsFeatureWrapper(VecEnvWrapper):
    """Append :func:`augment_observation` features to every observation of a lander VecEnv.

    :param venv: a VecEnv whose innermost env is a :class:`agents.common.vec_env.LanderSB3VecEnv`
        (curriculum wrappers in between are fine: the features are a function of the
        observation alone).
    :param names: feature names of the env's family.

    ``info["terminal_observation"]`` is augmented too, so value bootstrapping on truncation sees
    the same inputs as the policy.
    """

    def __init__(self, venv, names: Sequence[str]) -> None:
        self.names = validate_features(names)
        if not self.names:
            raise ValueError("ObsFeatureWrapper needs at least one feature name")
        node = venv
        while not hasattr(node, "native") and hasattr(node, "venv"):
            node = node.venv
        native = getattr(node, "native", None)
        if native is None:
            raise TypeError("ObsFeatureWrapper needs a LanderSB3VecEnv of a landing env "
                            "inside the wrapper chain")
        self.consts = feature_constants(native)
        base = venv.observation_space
        lo, hi = FEATURE_FAMILIES.get(self.consts["family"]).bounds(self.names)
        space = spaces.Box(np.concatenate([base.low, lo]).astype(np.float32),
                           np.concatenate([base.high, hi]).astype(np.float32), dtype=np.float32)
        super().__init__(venv, observation_space=space)

    def _aug(self, obs: np.ndarray) -> np.ndarray:
        return augment_observation(obs, self.consts, self.names)

    def reset(self) -> np.ndarray:
        return self._aug(self.venv.reset())

    def step_wait(self):
        obs, rew, done, infos = self.venv.step_wait()
        for info in infos:
            t = info.get("terminal_observation")
            if t is not None:
                info["terminal_observation"] = self._aug(np.asarray(t)[None])[0]
        return self._aug(obs), rew, done, infos


class StandardizedInputs(BaseFeaturesExtractor):
    """Flatten and standardise the policy input with fixed statistics: (x − mean)/std.

    A features extractor for SB3 policies trained by regression (behaviour cloning, DAgger):
    the statistics are those of the training inputs, stored as buffers in the policy's state
    dict and as ``features_extractor_kwargs`` in the saved model, so ``PPO.load`` and
    ``train.py --init-from`` rebuild the same input map (PPO's own ``VecNormalize`` plays this
    role in RL runs). Why: the pinpoint inputs span very different scales (stop offsets of
    metres in a log column, times of hundreds of seconds), and the clone's angle error reaches
    the ~0.1° it needs only on standardised inputs.
    """

    def __init__(self, observation_space, mean=None, std=None) -> None:
        import torch as th

        n = int(np.prod(observation_space.shape))
        super().__init__(observation_space, features_dim=n)
        m = np.zeros(n) if mean is None else np.asarray(mean, dtype=np.float64)
        s = np.ones(n) if std is None else np.asarray(std, dtype=np.float64)
        if m.shape != (n,) or s.shape != (n,) or not (np.isfinite(m).all() and np.all(s > 0)):
            raise ValueError(f"mean/std must be {n} finite numbers (std > 0)")
        self.register_buffer("mean", th.as_tensor(m, dtype=th.float32))
        self.register_buffer("std", th.as_tensor(s, dtype=th.float32))

    def forward(self, observations):
        import torch as th

        return (th.flatten(observations, start_dim=1) - self.mean) / self.std


def standardized_inputs_kwargs(inputs: np.ndarray) -> dict:
    """``policy_kwargs`` entries that standardise a policy's inputs with the statistics of
    ``inputs`` (N, n_in) (std floored at 1e-6 of the largest, for constant columns)."""
    x = np.asarray(inputs, dtype=np.float64)
    std = x.std(axis=0)
    std = np.maximum(std, 1e-6 * max(float(std.max()), 1e-12))
    return {"features_extractor_class": StandardizedInputs,
            "features_extractor_kwargs": {"mean": x.mean(axis=0).tolist(),
                                          "std": std.tolist()}}
