"""A trained Stable-Baselines3 model as a guidance law (:mod:`guidance.law`)."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np

from agents.features import augment_observation, feature_constants, validate_features
from guidance.law import FlightComputer, GuidanceLaw, Navigation

__all__ = ["SB3Law", "law_from_spec", "run_env_kwargs", "run_identity"]


class SB3Law(GuidanceLaw):
    """A trained SB3 model with its ``VecNormalize`` observation statistics: deterministic
    actions, all landers in one batched forward pass of the observations.

    Parameters
    ----------
    model : BaseAlgorithm
    vecnormalize : VecNormalize or str or Path or None
        Statistics (or the ``.pkl`` written by ``VecNormalize.save``); ``None`` if the model was
        trained without normalisation.
    name : str
    obs_features : list of str, optional
        Derived observation features the model was trained with (:mod:`agents.features`,
        the run's ``obs_features``); computed from the observation and the flight computer's
        nominal constants and appended before normalisation, as in training.
    """

    def __init__(self, model, vecnormalize=None, name: str = "PPO",
                 obs_features: list[str] | None = None) -> None:
        self.model = model
        self.name = name
        if isinstance(vecnormalize, str | Path):
            with open(vecnormalize, "rb") as fh:
                vecnormalize = pickle.load(fh)
        self.vecnormalize = vecnormalize
        self.obs_features = validate_features(obs_features)
        self._feature_consts = None

    @classmethod
    def from_path(cls, path: str | Path, name: str | None = None) -> SB3Law:
        """Load from a run directory or model ``.zip`` (:func:`agents.common.runs.load_trained`)."""
        from agents.common.runs import load_trained, read_run

        model, vn_path, algo = load_trained(path)
        hp = read_run(path)[1]
        return cls(model, vn_path, name=name or algo.upper(), obs_features=hp.get("obs_features"))

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self._feature_consts = feature_constants(computer) if self.obs_features else None

    def act(self, nav: Navigation) -> np.ndarray:
        obs = nav.obs
        if self.obs_features:
            obs = augment_observation(obs, self._feature_consts, self.obs_features)
        if self.vecnormalize is not None:
            obs = self.vecnormalize.normalize_obs(obs)
        action, _ = self.model.predict(obs, deterministic=True)
        return action


def law_from_spec(spec, context) -> SB3Law:
    """Factory of the law specs ``ppo``/``sac``/``td3``/``bc``/``dagger``:``RUN``
    (:mod:`guidance.registry`): the run directory or model ``.zip`` ``RUN``, labelled
    ``NAME:run-name``. No options."""
    spec.require_known_options(())
    if not spec.argument:
        raise ValueError(f"law {spec.text!r} needs a run: {spec.name}:RUN (a run directory or "
                         "a model .zip)")
    path = Path(spec.argument)
    if not path.exists():
        raise ValueError(f"law {spec.text!r}: run {spec.argument!r} does not exist")
    return SB3Law.from_path(path, name=spec.label())


def run_env_kwargs(spec) -> dict | None:
    """The env arguments the run of a spec was trained with (its ``config.yml``; the
    uncertainty set left out: a campaign flies its own), or None for a spec without an
    existing run."""
    from agents.common.runs import read_run, run_dir_of

    if spec.argument is None or not Path(spec.argument).exists():
        return None
    hp = read_run(run_dir_of(spec.argument))[1]
    return {k: v for k, v in (hp.get("env_kwargs") or {}).items() if k != "uncertainty"}


def run_identity(spec) -> dict:
    """What the flights of a learned law depend on besides its spec: the SHA-256 of the model
    file and of its observation statistics (the files :func:`agents.common.runs.load_trained`
    reads; a run retrained in place, or its newest checkpoint replaced, is another law) and
    the observation features it was trained with. Empty for a spec without an existing run."""
    import hashlib

    from agents.common.runs import read_run, trained_files

    if spec.argument is None or not Path(spec.argument).exists():
        return {}

    def sha256(path):
        if path is None:
            return None
        h = hashlib.sha256()
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
        return h.hexdigest()

    model, stats = trained_files(spec.argument, log=lambda msg: None)
    return {"model_sha256": sha256(model), "vecnormalize_sha256": sha256(stats),
            "obs_features": list(read_run(spec.argument)[1].get("obs_features") or [])}


law_from_spec.env_kwargs = run_env_kwargs
law_from_spec.identity = run_identity
