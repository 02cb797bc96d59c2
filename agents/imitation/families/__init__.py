"""Each env family's imitation recipes: datasets of certified optimal flights and DAgger
labels.

An :class:`ImitationFamily` per env family, registered in :data:`IMITATION_FAMILIES` by
``scenario.family``: ``planar`` (:mod:`.planar`: Pontryagin optima, the re-planning expert as
teacher), ``pinpoint`` (:mod:`.pinpoint`: the compiled Pontryagin feedback expert, or any law
spec, as teacher) and ``pinpoint_touchdown`` (:mod:`.touchdown`: the certified optima flown in
the env; law specs only as teacher). The generic drivers are
:func:`agents.imitation.dataset.generate` and :func:`agents.imitation.dagger.train_dagger`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from lunar_env.families import FamilyRegistry

__all__ = ["ImitationFamily", "IMITATION_FAMILIES", "DatasetRecipe", "DaggerRequest",
           "FollowsFlight"]


@runtime_checkable
class FollowsFlight(Protocol):
    """A teacher law whose memory follows the controls flown (a thrust estimate from the
    velocity changes they gave): in a DAgger roll-out the student flies and the teacher labels,
    so the roll-out tells it, after it was asked, the actions (N, n_act) actually flown."""

    def flown(self, nav, actions: np.ndarray) -> None:
        """Record that ``actions`` were flown at the decision of ``nav``."""


@dataclass(frozen=True)
class DatasetRecipe:
    """What an imitation dataset of a family is made of (:func:`agents.imitation.dataset.
    generate` is the generic driver: shards, resume, merge).

    Attributes
    ----------
    rows : ndarray, shape (n, n_row)
        Initial rows of the trajectories, in the form the shard function reads (planar: SI
        (r m, vr m/s, θ rad, v_t m/s, m kg); pinpoint: normalised Moon-fixed state (7,)).
    observation_names : list of str
        Names of the observation's components (the dataset meta).
    label_rule : str
        How each label is made (the dataset meta).
    initial_states : str
        How ``rows`` were drawn (the dataset meta).
    solver, certification : dict
        JSON metadata; both are part of the shard directory's identity.
    shard_fn : callable
        A *module-level* function (an executor task) ``shard_fn(job) -> dict of arrays``: one
        shard's per-trajectory arrays and samples (the keys of :mod:`agents.imitation.data`)
        and ``wall_s``. ``job`` holds ``k`` (shard index), ``rows`` (its rows),
        ``first_index``, ``env_id``, ``env_kwargs``, ``dt_s`` (s), ``seed``,
        ``tol_radius_m``, ``tol_speed_m_s`` and the items of ``job_args``.
    job_args : dict
        Family-specific items of every job (picklable).
    """

    rows: np.ndarray
    observation_names: list[str]
    label_rule: str
    initial_states: str
    solver: dict[str, Any]
    certification: dict[str, Any]
    shard_fn: Callable[[dict[str, Any]], dict[str, np.ndarray]]
    job_args: dict[str, Any] = field(default_factory=dict)

    @property
    def tolerances(self) -> tuple[float, float]:
        """(tol_radius_m, tol_speed_m_s) of the certification (m, m/s)."""
        return (float(self.certification["tol_radius_m"]),
                float(self.certification["tol_speed_m_s"]))


@dataclass(frozen=True)
class DaggerRequest:
    """One DAgger iteration's inputs (:meth:`ImitationFamily.dagger_iteration`).

    Attributes
    ----------
    env_id : str
    env_kwargs : dict
    policy_file : str
        The current policy, saved (a worker process loads it).
    load_learner : callable
        A *module-level* function ``load_learner(policy_file, env_id, env_kwargs,
        obs_features) -> fn``, ``fn(obs (N, n_obs)) -> actions (N, n_act)``: the policy's
        deterministic actions (given by the learner's room: the families never import it).
    obs_features : list of str or None
    n_episodes : int
        Roll-outs; sub-env i is reset with seed ``seed + i``.
    seed : int
    settings : dict
        The ``dagger`` section of the run's config (``beta``, ``label_every``,
        ``dense_tail_s``, ``min_label_speed_m_s``, ``tail_label_every``, ...; each family reads
        its own items, with defaults).
    n_workers : int
        Processes of the labelling (1: this process).
    store_dir : path or None
        A :class:`optimizers.common.executor.ResultStore` for the iteration's parts: parts
        finished before a kill are read back, not recomputed.
    progress : bool
    history : int or None
        The student's history (k decisions, :mod:`agents.features.history`): ``load_learner``
        is then called with ``history=k`` and the labels' inputs are the student's stacked
        inputs. Law teachers only (:mod:`agents.imitation.teachers`).
    teacher_throughout : bool
        The teacher flies every roll-out to its end (DAgger's first iteration, β₁ = 1).
    """

    env_id: str
    env_kwargs: dict[str, Any]
    policy_file: str
    load_learner: Callable
    obs_features: list[str] | None
    n_episodes: int
    seed: int
    settings: dict[str, Any]
    n_workers: int = 1
    store_dir: Path | None = None
    progress: bool = True
    history: int | None = None
    teacher_throughout: bool = False

    def memory_kwargs(self) -> dict[str, Any]:
        """``history`` and ``teacher_throughout`` as keyword arguments of
        :func:`agents.imitation.teachers.law_dagger_rollouts`."""
        return {"history": self.history, "teacher_throughout": bool(self.teacher_throughout)}


class ImitationFamily(ABC):
    """The imitation recipes of an env family (see the module docstring)."""

    @abstractmethod
    def dataset_recipe(self, scenario, n: int, seed: int, *, n_steps: int, check: str,
                       tol_radius_m: float | None, tol_speed_m_s: float | None,
                       action_noise: float | None) -> DatasetRecipe:
        """The recipe of an imitation dataset of ``n`` trajectories drawn with ``seed``.

        ``n_steps`` / ``check``: the optimiser's grid and certification check (families with
        an open-loop solver); ``tol_*``: certification tolerances (m, m/s; None: the family's
        default); ``action_noise``: noise on flown actions (action units; None: the family's
        default). Raises ValueError naming an option the family does not accept.
        """

    def check_teacher(self, teacher) -> None:
        """Refuse a DAgger teacher (:class:`agents.imitation.teachers.Teacher`) the family
        cannot label with, before anything is trained or flown (ValueError); every teacher is
        accepted by default."""
        return None

    @abstractmethod
    def dagger_iteration(self, scenario, request: DaggerRequest
                         ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
        """One DAgger iteration's labelled data from the current policy.

        Returns ``(labels, rollout)``: ``labels`` has ``obs`` (L, n_obs) float32, ``actions``
        (L, n_act) float32, ``phi_rad`` (L,) or (L, n_angle) (rad) and ``status`` (L,) str
        (the teacher's per-label status); ``rollout`` has ``rollout_success_rate``,
        ``rollout_fuel_mean_kg`` (kg), ``rollout_wall_s`` and ``label_wall_s`` (s), and any
        family-specific scalars.
        """


#: the imitation recipes of each env family, by ``scenario.family``
IMITATION_FAMILIES: FamilyRegistry[ImitationFamily] = FamilyRegistry(
    "imitation", entry_point_group="lunar_env.imitation_families")
IMITATION_FAMILIES.register("planar", "agents.imitation.families.planar:PlanarImitation")
IMITATION_FAMILIES.register("pinpoint", "agents.imitation.families.pinpoint:PinpointImitation")
IMITATION_FAMILIES.register("pinpoint_touchdown",
                            "agents.imitation.families.touchdown:TouchdownImitation")
