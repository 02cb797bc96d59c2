"""Where imitation data comes from: a dataset file of :mod:`agents.imitation.data`, or a Minari
dataset (``minari:<dataset id>``, :mod:`agents.imitation.minari_data`). The one place that
knows both, so that neither format module imports the other."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from agents.imitation.data import ImitationDataset, load_dataset

__all__ = ["DATASET_BOUND_ENV_KWARGS", "open_dataset", "load_run_dataset", "run_env_kwargs"]

#: env arguments the dataset's samples depend on: the scenario and engine (initial states and
#: plant), the decision interval (actions are labelled at mid-step of dt_s), the time limit (the
#: observation encodes t / time limit) and the action channels. A run may not change them.
DATASET_BOUND_ENV_KWARGS = ("scenario", "dt_s", "time_limit_s", "thrust_n", "throttle_channel")


def open_dataset(source: str | Path) -> ImitationDataset:
    """The dataset ``source`` names: ``minari:<dataset id>`` (read from the local Minari
    store) or a dataset file path."""
    if str(source).startswith("minari:"):
        from agents.imitation.minari_data import load_minari

        return load_minari(str(source))
    return load_dataset(source)


def run_env_kwargs(env_id: str, dataset_kwargs: dict[str, Any] | None,
                   override: dict[str, Any] | None) -> dict[str, Any]:
    """The env arguments of an imitation run: the dataset's, with the run's ``env_kwargs``
    (the hyperparameter entry's, e.g. ``--hyperparams env_kwargs.uncertainty=standard``)
    merged over them. The roll-outs, the validation selection and the saved ``config.yml``
    (which loads the run later) all use the result.

    Raises
    ------
    ValueError
        ``override`` is not a mapping, or through one of :data:`DATASET_BOUND_ENV_KWARGS` it
        changes the env's scenario, decision interval, time limit or action space from the
        dataset's (compared as the env resolves them: an explicit default is no change).
    """
    base = dict(dataset_kwargs or {})
    if override is None:
        return base
    if not isinstance(override, dict):
        raise ValueError(f"env_kwargs = {override!r} must be a mapping of env arguments "
                         "(e.g. {uncertainty: standard})")
    if any(k in override for k in DATASET_BOUND_ENV_KWARGS):
        # compared as the env resolves them (an explicit default equals an absent key)
        was, now = _dataset_bound(env_id, base), _dataset_bound(env_id, base | override)
        for k, v in was.items():
            if now[k] != v:
                raise ValueError(
                    f"env_kwargs {override!r} is not allowed: it changes the env's {k} from the "
                    f"dataset's {_short(v)} to {_short(now[k])}, and the dataset's samples "
                    f"depend on it; keep the dataset's value or make a dataset with the new "
                    f"one (lunar dataset --env-kwargs ...). A run may change the "
                    f"other env arguments (e.g. uncertainty), not "
                    f"{', '.join(DATASET_BOUND_ENV_KWARGS)}")
    return base | override


def _dataset_bound(env_id: str, env_kwargs: dict[str, Any]) -> dict[str, Any]:
    """What the env built with ``env_kwargs`` makes of the dataset-bound arguments."""
    import gymnasium as gym

    import lunar_env  # noqa: F401  (registers the env ids)

    env = gym.make(env_id, **env_kwargs)
    core = env.unwrapped
    out = {"scenario": core.scenario, "dt_s": float(core.dt_s),
           "time_limit_s": float(core.time_limit_s), "action_space": core.action_space}
    env.close()
    return out


def _short(value: Any) -> str:
    return repr(getattr(value, "name", value))


def load_run_dataset(run: dict[str, Any], env_kwargs: dict[str, Any] | None = None
                     ) -> tuple[ImitationDataset, dict[str, Any]]:
    """The dataset of an imitation run (``run["dataset"]``) and the run's env arguments: the
    dataset's, with ``env_kwargs`` (the run's config) merged over them (:func:`run_env_kwargs`);
    ValueError if it was made for another env than ``run["env"]``."""
    ds = open_dataset(run["dataset"])
    if ds.meta["env_id"] != run["env"]:
        raise ValueError(f"dataset {run['dataset']} is for {ds.meta['env_id']!r}, not "
                         f"{run['env']!r}")
    return ds, run_env_kwargs(run["env"], ds.meta.get("env_kwargs"), env_kwargs)
