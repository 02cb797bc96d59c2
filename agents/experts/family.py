"""The env-family contract: one object answers every question that depends on the env family.

An env family is a kind of landing problem with its own state, optimum and expert: the planar
soft landing (:mod:`agents.experts.planar`) and the 3D pinpoint landing
(:mod:`agents.experts.pinpoint`). Code outside the family modules asks
:func:`agents.common.families.family_of` for the family of a scenario and calls its methods; it
never branches on the family itself. A new family (a throttled vehicle, another body) is one
new module with an :class:`EnvFamily` subclass, registered in :mod:`agents.common.families`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agents.common.law import GuidanceLaw

__all__ = ["EnvFamily", "PerCaseOptimum", "PlantOptimumFuel", "DatasetRecipe", "DaggerRequest",
           "plant_scenario"]


def plant_scenario(scenario, thrust_scale: float, isp_scale: float):
    """``scenario`` with its engine's thrust and Isp multiplied by the given scales (a true
    plant of the uncertainty model); the same scenario for scales of 1. The normalisation
    (length, μ, mass units) does not depend on either, so normalised states carry over."""
    import dataclasses

    if thrust_scale == 1.0 and isp_scale == 1.0:
        return scenario
    v = scenario.vehicle
    return dataclasses.replace(
        scenario, name=f"{scenario.name}[T×{thrust_scale:.6g},Isp×{isp_scale:.6g}]",
        vehicle=dataclasses.replace(v, thrust_n=v.thrust_n * float(thrust_scale),
                                    isp_s=v.isp_s * float(isp_scale)))


@dataclass
class PerCaseOptimum:
    """The minimum-fuel optimum of each case of an evaluation, from the env's own initial states.

    Attributes
    ----------
    fuel_kg, tf_s : ndarray, shape (n,)
        Optimal propellant and final time per case (NaN where the solve failed).
    solutions : list
        The family's solution objects, one per case (each with ``success``).
    info : dict
        ``solver`` (what computed it), ``converged``, ``fuel_mean_kg``, ``wall_s``.
    """

    fuel_kg: np.ndarray
    tf_s: np.ndarray
    solutions: list
    info: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_solutions(cls, solutions: list, solver: str, wall_s: float) -> PerCaseOptimum:
        """From solution objects with ``success``, ``fuel_kg`` and ``tf_s``."""
        fuel = np.array([s.fuel_kg if s.success else np.nan for s in solutions], dtype=float)
        tf = np.array([s.tf_s if s.success else np.nan for s in solutions], dtype=float)
        ok = np.isfinite(fuel)
        return cls(fuel, tf, list(solutions), {
            "solver": solver, "converged": int(ok.sum()),
            "fuel_mean_kg": float(np.mean(fuel[ok])) if ok.any() else float("nan"),
            "wall_s": float(wall_s)})


@dataclass(frozen=True)
class PlantOptimumFuel:
    """The omniscient reference of a campaign's cases (:meth:`EnvFamily.plant_optimum_fuel`).

    Attributes
    ----------
    fuel_kg : ndarray, shape (n,)
        Minimum propellant (kg) of each case's true plant from its true start; NaN where no
        method found an optimum.
    solver : tuple of str, length n
        The method that found each case's optimum (``""`` where none did).
    """

    fuel_kg: np.ndarray
    solver: tuple[str, ...]

    def __post_init__(self) -> None:
        if len(self.solver) != len(self.fuel_kg):
            raise ValueError(f"{len(self.solver)} solver names for {len(self.fuel_kg)} cases")


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
    """One DAgger iteration's inputs (:meth:`EnvFamily.dagger_iteration`).

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


class EnvFamily(ABC):
    """What an env family answers (see the module docstring)."""

    #: short name ("planar", "pinpoint")
    name: str = ""
    #: cases the family's closed-loop expert flies in an evaluation by default (None: all)
    default_expert_cases: int | None = None

    @abstractmethod
    def handles(self, scenario) -> bool:
        """True if ``scenario`` belongs to this family."""

    @abstractmethod
    def per_case_optimum(self, scenario, states_nd: np.ndarray, *, progress: bool = True,
                         workers: int = 1, executor=None) -> PerCaseOptimum:
        """The certified minimum-fuel optimum from each normalised initial state (n, n_state)."""

    def plant_optimum_fuel(self, scenario, states_nd: np.ndarray, thrust_scale: np.ndarray,
                           isp_scale: np.ndarray, *, progress: bool = False
                           ) -> PlantOptimumFuel:
        """Minimum propellant (kg) of each case (n,) from its true normalised start (n, n_state)
        with its true engine (thrust and Isp scales (n,)): the omniscient reference of a
        campaign, NaN where no optimum was found, with the method that found each. This default
        groups the cases by plant and calls :meth:`per_case_optimum`; families with a faster
        certified solver override it."""
        fuel = np.full(len(states_nd), np.nan)
        solver = [""] * len(states_nd)
        plants = np.stack([np.asarray(thrust_scale, float), np.asarray(isp_scale, float)], 1)
        for plant in np.unique(plants, axis=0):
            rows = np.flatnonzero(np.all(plants == plant, axis=1))
            opt = self.per_case_optimum(plant_scenario(scenario, *plant), states_nd[rows],
                                        progress=progress)
            fuel[rows] = opt.fuel_kg
            for r, f in zip(rows, opt.fuel_kg, strict=True):
                solver[r] = opt.info["solver"] if np.isfinite(f) else ""
        return PlantOptimumFuel(fuel, tuple(solver))

    @abstractmethod
    def open_loop_law(self, optimum: PerCaseOptimum) -> GuidanceLaw:
        """The replay of each case's optimal control history (case id = row of ``optimum``)."""

    @abstractmethod
    def expert_law(self, scenario) -> GuidanceLaw:
        """The closed-loop expert: the optimum re-solved from the navigation solution."""

    @abstractmethod
    def start_pool(self, scenario, n_trajectories: int, seed: int, n_points: int,
                   progress: bool) -> tuple[np.ndarray, np.ndarray]:
        """Curriculum starts: states (M, n_state) (normalised) along optimal flights from
        dispersed initial states, and the episode time (M,) (s) of each."""

    def start_noise_nd(self, scenario, noise: dict[str, float]) -> tuple[float, float]:
        """Validated curriculum start perturbation in normalised units (families that have
        one override this)."""
        raise ValueError(f"start_noise is not available for the {self.name} env family")

    def perturb_starts(self, states_nd: np.ndarray, sigma_nd: tuple[float, float],
                       rng: np.random.Generator) -> np.ndarray:
        """Curriculum starts with the errors of :meth:`start_noise_nd` added (a copy)."""
        raise ValueError(f"start_noise is not available for the {self.name} env family")

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

    @abstractmethod
    def dagger_iteration(self, scenario, request: DaggerRequest
                         ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
        """One DAgger iteration's labelled data from the current policy.

        Returns ``(labels, rollout)``: ``labels`` has ``obs`` (L, n_obs) float32, ``actions``
        (L, n_act) float32, ``phi_rad`` (L,) or (L, n_angle) (rad) and ``status`` (L,) str
        (the expert's per-label status); ``rollout`` has ``rollout_success_rate``,
        ``rollout_fuel_mean_kg`` (kg), ``rollout_wall_s`` and ``label_wall_s`` (s), and any
        family-specific scalars.
        """

    @abstractmethod
    def plot_optimum(self, ax_trajectory, ax_control, solution, scenario) -> None:
        """Draw one case's optimum (dashed) on the trajectory and control axes."""

    @abstractmethod
    def plot_flight(self, ax_trajectory, ax_control, trace: dict[str, np.ndarray], scenario,
                    label: str) -> None:
        """Draw one flown case (``trace``: ``t_s``, ``state_nd``, ``action``)."""

    @abstractmethod
    def feature_widths(self) -> dict[str, int]:
        """The observation features the family defines (YAML ``obs_features``): name -> number
        of columns it appends, in the order of the names."""

    def feature_constants(self, env) -> dict[str, Any]:
        """What the family's features need from ``env`` (an env, native vector env or flight
        computer) besides its ``physical_constants()`` and decoding (none by default)."""
        return {}

    @abstractmethod
    def augment_observation(self, obs: np.ndarray, consts: dict[str, Any],
                            names: Sequence[str]) -> np.ndarray:
        """The observations (B, n_obs) with the features ``names`` (at least one) appended,
        float32 (``consts``: :func:`agents.common.features.feature_constants` of the env)."""

    @abstractmethod
    def feature_bounds(self, names: Sequence[str]) -> tuple[list[float], list[float]]:
        """Lower and upper bounds of the columns the features ``names`` append."""

    @abstractmethod
    def shaping_potentials(self) -> tuple[str, ...]:
        """The reward-shaping potentials (:mod:`agents.rl.shaping`) that fit the family's envs."""

    #: axis labels of the evaluation plots: (trajectory x, trajectory y, control y)
    plot_labels: tuple[str, str, str] = ("", "altitude (km)", "")

    def baseline_laws(self, scenario, optimum: PerCaseOptimum, n_states: int, *,
                      open_loop: bool = True, n_expert_cases: int | None = None
                      ) -> list[tuple[GuidanceLaw, int]]:
        """The optimiser baselines of an evaluation: the open-loop optimum on every case and
        the closed-loop expert on the first ``n_expert_cases`` (None: the family's default;
        0: none)."""
        rows: list[tuple[GuidanceLaw, int]] = []
        if open_loop:
            rows.append((self.open_loop_law(optimum), n_states))
        n_exp = self.default_expert_cases if n_expert_cases is None else n_expert_cases
        n_exp = n_states if n_exp is None else min(int(n_exp), n_states)
        if n_exp > 0:
            rows.append((self.expert_law(scenario), n_exp))
        return rows
