"""Where imitation data comes from: a dataset file of :mod:`agents.imitation.data`, or a Minari
dataset (``minari:<dataset id>``, :mod:`agents.imitation.minari_data`). The one place that
knows both, so that neither format module imports the other."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from agents.imitation.data import ImitationDataset, load_dataset

__all__ = ["open_dataset", "load_run_dataset"]


def open_dataset(source: str | Path) -> ImitationDataset:
    """The dataset ``source`` names: ``minari:<dataset id>`` (read from the local Minari
    store) or a dataset file path."""
    if str(source).startswith("minari:"):
        from agents.imitation.minari_data import load_minari

        return load_minari(str(source))
    return load_dataset(source)


def load_run_dataset(run: dict[str, Any]) -> tuple[ImitationDataset, dict[str, Any]]:
    """The dataset of an imitation run (``run["dataset"]``) and the env arguments it was made
    with; ValueError if it was made for another env than ``run["env"]``."""
    ds = open_dataset(run["dataset"])
    if ds.meta["env_id"] != run["env"]:
        raise ValueError(f"dataset {run['dataset']} is for {ds.meta['env_id']!r}, not "
                         f"{run['env']!r}")
    return ds, ds.meta.get("env_kwargs") or {}
