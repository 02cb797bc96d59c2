"""Monte Carlo campaigns: every guidance law flown on the same dispersed cases of plant and
navigation errors, scored against each case's omniscient optimum.

A campaign (:func:`run_campaign`) flies each law of a list of law specs
(:mod:`guidance.registry`) on cases ``0..N-1`` of an env under an uncertainty model
(:mod:`lunar_env.uncertainty`). Case k is sub-env reset with ``seed + k``: its planned start,
its plant and its navigation errors come from streams of that seed, so every law, every chunk
size, every worker count and every executor sees the same case k (common random numbers).

Work is split into keyed tasks on the project's executor (:mod:`optimizers.common.executor`):
one per (law, error scale, chunk of cases) plus one per chunk for the reference. Each result
is written atomically to the campaign's store as it finishes, so a killed campaign resumes
where it stopped and ends with the same numbers. Adding a law to a finished campaign flies
only that law.

**Results never mix.** The store's identity (:meth:`CampaignConfig.identity`) holds what every
result depends on: env, uncertainty model and its version, cases, seed, env arguments, chunk
size; a store of other settings is refused. What one law or one curve point depends on is in
its tasks' keys (:func:`campaign_tasks`): the law's full spec and the fingerprint of its files
(a run's path in full and its model's bytes: two runs of one name in two folders, or a run
retrained in place, are two laws), the error scale, and the number of cases flown at it. Every
result read back is checked against its key (:func:`campaign_schema`: the cases the chunk names,
lists of one length); one that fails is moved aside and flown again. One process writes a
campaign directory at a time (:class:`~optimizers.common.lock.DirectoryLock`, held for the
whole run), and every law is built once before any work (:func:`check_laws`).

**Reference.** The omniscient optimum of a case is the certified minimum-fuel landing of its
*true* plant (thrust and Isp scales) from its *true* start (entry and wet-mass errors), as if
the flight computer knew everything (a misalignment it knew would be steered out at no fuel
cost): Pontryagin for the planar env; for pinpoint the compiled 3D Pontryagin extremal, and the
direct optimum (GPM + shooting) where the extremal's shooting fails
(:meth:`~optimizers.optimum.OptimumFamily.plant_optimum_fuel`). Every law's fuel is reported as
a gap to it; the JSON counts the cases each method solved.

**Robustness curve.** The first ``curve_cases`` cases flown again with every error scaled by
each factor of ``scales`` (0, 0.5, 1, 2, 3 × the set by default;
:meth:`~lunar_env.uncertainty.UncertaintyModel.scaled`): success rate against error scale.

The JSON contract is :func:`campaign_summary`; per-case rows are written beside it as CSV.
"""

from __future__ import annotations

import csv
import io
import json
import math
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from guidance.campaign.statistics import footprint_ellipse, wilson_interval
from lunar_env.uncertainty import MODEL_VERSION, UncertaintyModel, resolve_uncertainty
from optimizers.common.checkpoint import atomic_write_bytes
from optimizers.common.executor import (
    Executor,
    ResultSchema,
    ResultStore,
    Task,
    TaskKey,
    get_executor,
    run_tasks,
)
from optimizers.common.lock import DirectoryLock
from optimizers.common.store import identity_fingerprint

__all__ = ["CampaignConfig", "CampaignResult", "run_campaign", "fly_chunk", "reference_chunk",
           "summarise_law", "campaign_summary", "check_laws", "check_scales", "campaign_tasks",
           "campaign_schema", "curve_scales", "scale_text", "DEFAULT_SCALES", "SCHEMA_VERSION"]

#: error scales of the robustness curve (× the campaign's uncertainty set)
DEFAULT_SCALES = (0.0, 0.5, 1.0, 2.0, 3.0)
#: version of the JSON contract (:func:`campaign_summary`)
SCHEMA_VERSION = 1

_CASE_KEYS = ("success", "touchdown_speed_m_s", "miss_distance_m", "fuel_kg", "time_s",
              "propellant_left_kg", "downrange_offset_m", "crossrange_offset_m")
_REF_KEYS = ("thrust_scale", "isp_scale", "mass_error_kg", "omniscient_fuel_kg")
#: the reference tasks' key in the campaign's store, versioned: a store made by an older
#: reference recomputes it (v2: the pinpoint direct-method fallback; v3: the touchdown optimum
#: certifies extremals holding an arc shorter than the collocation resolves; v4: its
#: collocation resumes once from IPOPT's iteration limit)
_REF_TASK = "reference_v4"
#: fields of every stored flight chunk (per-case lists: ``case`` and :data:`_CASE_KEYS`)
_FLIGHT_FIELDS = ("case", *_CASE_KEYS, "n_decisions", "policy_wall_s")
#: fields of every stored reference chunk (per-case lists: all but ``wall_s``)
_REF_FIELDS = ("case", *_REF_KEYS, "omniscient_solver")


def scale_text(scale: float) -> str:
    """An error scale as task keys write it: 6 significant digits (``:g``) where they give the
    scale exactly, else every digit (``repr``), so two scales never share a key."""
    text = f"{float(scale):g}"
    return text if float(text) == float(scale) else repr(float(scale))


@dataclass(frozen=True)
class CampaignConfig:
    """What a campaign flies (its identity, :meth:`identity`: a store made with other settings
    is refused).

    Attributes
    ----------
    env_id : str
    uncertainty : UncertaintyModel
    cases : int
        Cases 0..cases-1 (case k: reset seed ``seed + k``).
    seed : int
    laws : tuple of str
        Law specs (:mod:`guidance.registry`).
    env_kwargs : dict
        Env arguments besides ``uncertainty``.
    chunk : int
        Cases per task.
    scales : tuple of float
        Error scales of the robustness curve (empty: no curve); repeats are dropped. Each
        scaled model must be valid (:meth:`~lunar_env.uncertainty.UncertaintyModel.scaled`),
        and two scales must differ in their first 6 significant digits (the tables' and the
        curve's precision; scale 1, the main run, is always flown).
    curve_cases : int
        Cases flown at each scale of the curve (the first ones).
    imports : tuple of str
        Modules (names or ``.py`` paths) that register laws, imported before any law is built
        (:func:`guidance.registry.import_law_modules`), in every worker too.
    """

    env_id: str
    uncertainty: UncertaintyModel
    cases: int
    seed: int
    laws: tuple[str, ...]
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    chunk: int = 100
    scales: tuple[float, ...] = DEFAULT_SCALES
    curve_cases: int = 200
    imports: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        from guidance.registry import import_law_modules, parse_law_spec
        from lunar_env.validation import require_integer

        object.__setattr__(self, "uncertainty", resolve_uncertainty(self.uncertainty))
        require_integer("cases", self.cases, minimum=1)
        require_integer("chunk", self.chunk, minimum=1)
        require_integer("curve_cases", self.curve_cases, minimum=1)
        require_integer("seed", self.seed, minimum=0)
        from optimizers.common.cli import MAX_SEED

        if self.seed + self.cases - 1 > MAX_SEED:
            raise ValueError(f"seed = {self.seed} with {self.cases} cases reaches "
                             f"{self.seed + self.cases - 1}; case k is reset with seed + k, "
                             f"at most 2**63 - 1: allowed seeds 0 to {MAX_SEED - self.cases + 1}")
        if not self.laws:
            raise ValueError("a campaign needs at least one law (--laws)")
        import_law_modules(self.imports)
        specs = [parse_law_spec(t) for t in self.laws]
        names = [s.label() for s in specs]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"law(s) {', '.join(dup)} given twice (--laws)")
        if "uncertainty" in self.env_kwargs:
            raise ValueError("give the uncertainty set as --uncertainty, not in --env-kwargs")
        object.__setattr__(self, "scales", curve_scales(self.uncertainty, self.scales))

    def identity(self) -> dict[str, Any]:
        """The settings every stored result belongs to: env, uncertainty model and its
        version (:data:`~lunar_env.uncertainty.MODEL_VERSION`), cases, seed, env arguments
        and chunk size.

        What belongs to one law or one curve point is in its tasks' keys instead
        (:func:`campaign_tasks`), so adding a law or a scale to a finished campaign reuses
        the other flights: the law's full spec and the fingerprint of its files
        (:func:`guidance.registry.law_identity`), the error scale and the number of cases
        flown at it."""
        return {"env": self.env_id, "uncertainty": self.uncertainty.as_dict(),
                "uncertainty_model_version": MODEL_VERSION,
                "cases": int(self.cases), "seed": int(self.seed),
                "env_kwargs": self.env_kwargs, "chunk": int(self.chunk)}

    @property
    def curve_n(self) -> int:
        """Cases flown at each scale of the robustness curve (the first ones)."""
        return min(self.curve_cases, self.cases)

    def chunks(self, n_cases: int) -> list[tuple[int, int]]:
        """(first case, number of cases) of each task covering cases 0..n_cases-1."""
        return [(a, min(self.chunk, n_cases - a)) for a in range(0, n_cases, self.chunk)]


def curve_scales(model: UncertaintyModel, scales) -> tuple[float, ...]:
    """The robustness curve's error scales: ``scales`` without repeats, each checked (finite,
    >= 0, ``model`` scaled by it valid, and distinct from the others, scale 1 included, in
    its first 6 significant digits).

    Raises
    ------
    ValueError
        Naming the scale and what is wrong with it.
    """
    out: list[float] = []
    shown = {"1": 1.0}
    for raw in scales:
        try:
            s = float(raw)
        except (TypeError, ValueError):
            raise ValueError(f"robustness-curve scale {raw!r} is not a number") from None
        if not (math.isfinite(s) and s >= 0.0):
            raise ValueError(f"robustness-curve scale {raw!r} must be finite and >= 0")
        if s in out:
            continue
        text = f"{s:g}"
        if text in shown and shown[text] != s:
            other = "the main run's scale 1" if shown[text] == 1.0 else repr(shown[text])
            raise ValueError(f"robustness-curve scale {s!r} is {other} to 6 significant "
                             "digits, the precision of the tables and of the curve; give "
                             "scales that differ within 6 digits")
        try:
            model.scaled(s)
        except ValueError as exc:
            raise ValueError(f"robustness-curve scale {s:g} takes the uncertainty model "
                             f"beyond its limits: {exc}") from None
        shown[text] = s
        out.append(s)
    return tuple(out)


def _env_kwargs(env_kwargs: dict, model_dict: dict, scale: float) -> dict:
    model = UncertaintyModel(**model_dict)
    if scale != 1.0:
        model = model.scaled(scale)
    return {**env_kwargs, "uncertainty": model}


def _starts(env_id: str, kwargs: dict, n: int, seed: int):
    """True starts, navigated starts, episode errors and the env's core of cases
    seed..seed+n-1 (a vector env reset only: nothing is flown)."""
    from guidance.flight import make_vec

    venv = make_vec(env_id, n, kwargs)
    venv.reset(seed=seed)
    core = venv.unwrapped
    out = (core.state_nd, core.navigation_state_nd, core.episode_errors, core)
    venv.close()
    return out


def reference_chunk(env_id: str, env_kwargs: dict, model_dict: dict, first: int, n: int,
                    seed: int) -> dict[str, list]:
    """Executor task: the true plant and the omniscient optimum of cases first..first+n-1."""
    from optimizers.optimum import optimum_family

    kwargs = _env_kwargs(env_kwargs, model_dict, 1.0)
    truth, _, errors, core = _starts(env_id, kwargs, n, seed + first)
    fam = optimum_family(core)
    t0 = time.perf_counter()
    ref = fam.plant_optimum_fuel(core.scenario, truth, errors.thrust_scale, errors.isp_scale)
    return {"case": list(range(first, first + n)),
            "thrust_scale": errors.thrust_scale.tolist(), "isp_scale": errors.isp_scale.tolist(),
            "mass_error_kg": errors.mass_error_kg.tolist(),
            "omniscient_fuel_kg": ref.fuel_kg.tolist(), "omniscient_solver": list(ref.solver),
            "wall_s": time.perf_counter() - t0}


def fly_chunk(spec_text: str, env_id: str, env_kwargs: dict, model_dict: dict, scale: float,
              first: int, n: int, seed: int, imports: tuple[str, ...] = (),
              law_files: dict | None = None) -> dict[str, Any]:
    """Executor task: law ``spec_text`` flown on cases first..first+n-1 with every error
    scaled by ``scale``; per-case outcomes (lists) and the law's decision cost. ``imports``:
    the campaign's law modules (imported first). ``law_files``: what the law's factory
    declared of its files when the campaign started (:func:`_law_files`); a law whose files
    changed since (a run retrained in place) is refused with RuntimeError, so its flights
    never mix with those of the model the campaign's keys name."""
    import sys

    from guidance.flight import fly
    from guidance.registry import LawContext, build_law, import_law_modules, parse_law_spec
    from optimizers.optimum import optimum_family

    import_law_modules(imports)
    if law_files is not None:
        now = _law_files(parse_law_spec(spec_text))
        if now != law_files:
            raise RuntimeError(f"law {spec_text!r}: its files changed after the campaign "
                               f"started ({law_files} then, {now} now); run the campaign "
                               "again: the new files are another law, with their own tasks")
    kwargs = _env_kwargs(env_kwargs, model_dict, scale)
    _, nav0, _, core = _starts(env_id, kwargs, n, seed + first)
    scenario = core.scenario
    task = core.task

    def nominal_optimum():
        # the plan the flight computer would make: nominal plant, navigated start
        return optimum_family(scenario).per_case_optimum(scenario, nav0, progress=False)

    ctx = LawContext(env_id=env_id, env_kwargs=dict(env_kwargs), scenario=scenario,
                     nominal_optimum=nominal_optimum)
    law = build_law(spec_text, ctx)
    if "torch" in sys.modules:  # a learned law: one core per task, as tasks run side by side
        sys.modules["torch"].set_num_threads(1)
    t0 = time.perf_counter()
    ro = fly(env_id, law, n, seed=seed + first, env_kwargs=kwargs)
    wall = time.perf_counter() - t0
    final = ro.final_state_nd
    left = (final[:, -1] - task.dry_mass_nd) * task.mass_ref_kg
    if task.has_target:
        off = task.target_offsets_m(final)
    else:
        off = np.full((n, 2), np.nan)
    return {"case": list(range(first, first + n)), "success": ro.is_success.tolist(),
            "touchdown_speed_m_s": ro.touchdown_speed_m_s.tolist(),
            "miss_distance_m": ro.miss_distance_m.tolist(), "fuel_kg": ro.fuel_used_kg.tolist(),
            "time_s": ro.episode_time_s.tolist(), "propellant_left_kg": left.tolist(),
            "downrange_offset_m": off[:, 0].tolist(), "crossrange_offset_m": off[:, 1].tolist(),
            "n_decisions": int(ro.n_decisions), "policy_wall_s": float(ro.policy_wall_s),
            "flight_wall_s": wall, "name": law.name}


def _law_files(spec) -> dict:
    """The part of a law's identity its factory declares (:func:`guidance.registry.
    law_identity` without the spec: e.g. a learned law's model bytes); checked again in each
    worker, where the spec's path may resolve otherwise (another machine's mount)."""
    from guidance.registry import law_identity

    return {k: v for k, v in law_identity(spec).items() if k != "spec"}


# -------------------------------------------------------------------------------------------
# Checks, tasks and the store's schema
# -------------------------------------------------------------------------------------------


def check_scales(config: CampaignConfig) -> None:
    """Build the env once under the campaign's uncertainty model at every error scale flown
    (1 and the curve's), so a model a task refuses (e.g. a wet-mass error reaching the dry
    mass) is refused before any work.

    Raises
    ------
    ValueError
        Naming the scale and the refused field.
    """
    from optimizers.common.cli import check_env

    for scale in sorted({1.0, *config.scales}):
        model = config.uncertainty if scale == 1.0 else config.uncertainty.scaled(scale)
        try:
            check_env(config.env_id, {**config.env_kwargs, "uncertainty": model})
        except ValueError as exc:
            where = "" if scale == 1.0 else f"robustness-curve scale {scale:g}: "
            raise ValueError(f"{where}{exc}") from None


def check_laws(config: CampaignConfig) -> dict[str, tuple[str, dict]]:
    """Check every law of ``config`` in this process, before any work: its spec parsed, its
    argument and options checked by its factory (:func:`guidance.registry.validate_law`:
    built once, or its ``validate`` hook), and its identity taken.

    Returns
    -------
    dict
        Law spec -> ``(law key, identity)``: the key, ``LABEL#FINGERPRINT`` (the label of
        the tables and the first 16 hex digits of the SHA-256 of
        :func:`guidance.registry.law_identity`), names the law's tasks; the identity is
        that of :func:`~guidance.registry.law_identity`.

    Raises
    ------
    ValueError
        A law that cannot be built (the message names it and the bad argument or option).
    """
    from guidance.flight import make_vec
    from guidance.registry import (
        LawContext,
        import_law_modules,
        law_identity,
        parse_law_spec,
        validate_law,
    )

    import_law_modules(config.imports)
    venv = make_vec(config.env_id, 1, {**config.env_kwargs, "uncertainty": config.uncertainty})
    scenario = venv.unwrapped.scenario
    venv.close()
    out = {}
    for text in config.laws:
        spec = parse_law_spec(text)
        ctx = LawContext(env_id=config.env_id, env_kwargs=dict(config.env_kwargs),
                         scenario=scenario, nominal_optimum=_no_optimum_here)
        try:
            validate_law(spec, ctx)
        except _NeedsTheOptimum:  # built from the per-case optimum: checked in the workers
            pass
        ident = law_identity(spec)
        out[text] = (f"{spec.label()}#{identity_fingerprint(ident)}", ident)
    return out


class _NeedsTheOptimum(Exception):
    """A law asked for the per-case optimum while it was being checked (not computed there)."""


def _no_optimum_here():
    raise _NeedsTheOptimum


def campaign_tasks(config: CampaignConfig, law_keys: dict[str, tuple[str, dict]]
                   ) -> tuple[list[Task], dict[str, int]]:
    """The campaign's tasks and the number of cases each task set covers.

    Keys: ``(reference_v4, seed, k)`` for chunk k of the reference, and
    ``(LAW_KEY@xSCALE/nCASES, seed, k)`` for chunk k of a law flown at an error scale on its
    first CASES cases (:attr:`CampaignConfig.cases` at scale 1, :attr:`CampaignConfig.curve_n`
    at the curve's other scales); ``LAW_KEY`` from :func:`check_laws`, ``SCALE`` by
    :func:`scale_text`.

    Returns
    -------
    tasks : list of Task
    n_cases : dict
        Key problem -> the cases 0..n-1 its chunks cover (:meth:`CampaignConfig.chunks`).
    """
    model_dict = config.uncertainty.as_dict()
    n_cases = {_REF_TASK: config.cases}
    tasks = []
    for k, (a, n) in enumerate(config.chunks(config.cases)):
        tasks.append(Task(TaskKey(_REF_TASK, config.seed, k), reference_chunk,
                          (config.env_id, config.env_kwargs, model_dict, a, n, config.seed)))
    # every law at scale 1 on all cases (the table); the curve's other scales on curve_n cases
    for text in config.laws:
        key, ident = law_keys[text]
        files = {k: v for k, v in ident.items() if k != "spec"}
        for scale in sorted({1.0, *config.scales}):
            problem = _flight_problem(config, key, scale)
            n_cases[problem] = config.cases if scale == 1.0 else config.curve_n
            for k, (a, n) in enumerate(config.chunks(n_cases[problem])):
                tasks.append(Task(TaskKey(problem, config.seed, k), fly_chunk,
                                  (text, config.env_id, config.env_kwargs, model_dict, scale,
                                   a, n, config.seed, tuple(config.imports), files)))
    return tasks, n_cases


def _flight_problem(config: CampaignConfig, law_key: str, scale: float) -> str:
    n = config.cases if scale == 1.0 else config.curve_n
    return f"{law_key}@x{scale_text(scale)}/n{n}"


def campaign_schema(config: CampaignConfig, n_cases: dict[str, int]):
    """What every stored result of the campaign must hold (``schema`` of its
    :class:`~optimizers.common.store.ResultStore`): the fields of a flight or a reference
    chunk, per-case lists of one length, and exactly the cases its key names (chunk
    ``k`` of cases 0..n-1: ``range(a, a + m)`` for ``(a, m) = config.chunks(n)[k]``), so a
    chunk stored under another chunk's key, or cut short, is damaged and flown again.

    ``n_cases``: key problem -> cases its chunks cover (:func:`campaign_tasks`).
    """
    def expected(key: TaskKey) -> dict[str, Any]:
        a, m = config.chunks(n_cases[key.problem])[key.index]
        return {"case": list(range(a, a + m))}

    flight = ResultSchema(required=_FLIGHT_FIELDS, same_length=("case", *_CASE_KEYS),
                          expected=expected)
    reference = ResultSchema(required=_REF_FIELDS, same_length=_REF_FIELDS, expected=expected)

    def schema(key: TaskKey, value: Any) -> None:
        (reference if key.problem == _REF_TASK else flight)(key, value)

    return schema


# -------------------------------------------------------------------------------------------
# Statistics
# -------------------------------------------------------------------------------------------


def _pct(x: np.ndarray, q: float) -> float | None:
    """Percentile ``q`` of ``x``, where NaN counts as +inf (a case with no value is the worst:
    e.g. no touchdown at all); None (JSON null) if that is not finite."""
    x = np.where(np.isnan(x), np.inf, np.asarray(x, dtype=np.float64))
    if len(x) == 0:
        return None
    v = float(np.percentile(x, q, method="higher"))
    return v if math.isfinite(v) else None


def _finite_pct(x: np.ndarray, q: float) -> float | None:
    x = np.asarray(x, dtype=np.float64)
    x = x[np.isfinite(x)]
    return float(np.percentile(x, q)) if len(x) else None


def summarise_law(rows: dict[str, np.ndarray], reference: dict[str, np.ndarray],
                  has_target: bool) -> dict[str, Any]:
    """The figures of merit of one law (the JSON contract's ``laws[NAME]``).

    Percentiles of touchdown speed and miss count a case without a value (no touchdown; no
    gate) as the worst; fuel percentiles are over every case; the fuel gap to the omniscient
    optimum, 100 (fuel − optimum) / optimum, is over the successful cases with a converged
    optimum (a failed landing's fuel says nothing of its efficiency); the propellant margin is
    what is left at touchdown (kg, its 1st percentile: the worst 1 %)."""
    ok = np.asarray(rows["success"], dtype=bool)
    n = len(ok)
    k = int(ok.sum())
    speed = np.asarray(rows["touchdown_speed_m_s"], dtype=np.float64)
    fuel = np.asarray(rows["fuel_kg"], dtype=np.float64)
    ref = np.asarray(reference["omniscient_fuel_kg"], dtype=np.float64)
    gap = 100.0 * (fuel - ref) / ref
    gap_ok = gap[ok & np.isfinite(gap)]
    out: dict[str, Any] = {
        "cases": n, "successes": k, "success_rate": k / n if n else float("nan"),
        "success_ci95": list(wilson_interval(k, n)),
        "touchdown_speed_p50_m_s": _pct(speed, 50), "touchdown_speed_p99_m_s": _pct(speed, 99),
        "touchdown_speed_max_m_s": _pct(speed, 100),
        "fuel_p50_kg": _finite_pct(fuel, 50), "fuel_p99_kg": _finite_pct(fuel, 99),
        "fuel_gap_p50_pct": float(np.percentile(gap_ok, 50)) if len(gap_ok) else None,
        "fuel_gap_p99_pct": float(np.percentile(gap_ok, 99)) if len(gap_ok) else None,
        "fuel_gap_cases": int(len(gap_ok)),
        "propellant_margin_p1_kg": _finite_pct(np.asarray(rows["propellant_left_kg"])[ok], 1),
        "us_per_decision": float(rows["us_per_decision"]),
    }
    if has_target:
        miss = np.asarray(rows["miss_distance_m"], dtype=np.float64)
        out.update({"miss_p50_m": _pct(miss, 50), "miss_p95_m": _pct(miss, 95),
                    "miss_p99_m": _pct(miss, 99)})
        off = np.stack([np.asarray(rows["downrange_offset_m"], dtype=np.float64),
                        np.asarray(rows["crossrange_offset_m"], dtype=np.float64)], 1)
        out["footprint_3sigma"] = footprint_ellipse(off)
    return out


# -------------------------------------------------------------------------------------------
# The campaign
# -------------------------------------------------------------------------------------------


@dataclass
class CampaignResult:
    """A finished campaign: per-case arrays of every law (main run), the reference, the
    robustness curve, and the JSON summary.

    Attributes
    ----------
    config : CampaignConfig
    cases : dict law label -> dict of per-case arrays (:data:`_CASE_KEYS`, ``us_per_decision``)
    reference : dict of per-case arrays (``thrust_scale``, ``isp_scale``, ``mass_error_kg``,
        ``omniscient_fuel_kg``, ``omniscient_solver``: the method that found it, "" where none)
    curve : dict law label -> list of (scale, successes, cases)
    summary : dict
        :func:`campaign_summary`.
    wall_s : float
    """

    config: CampaignConfig
    cases: dict[str, dict[str, np.ndarray]]
    reference: dict[str, np.ndarray]
    curve: dict[str, list[tuple[float, int, int]]]
    summary: dict[str, Any]
    wall_s: float

    def rows_csv(self) -> str:
        """Per-case rows of every law (CSV text)."""
        buf = io.StringIO()
        w = csv.writer(buf)
        ref_cols = list(_REF_KEYS)
        w.writerow(["law", "case", *_CASE_KEYS, "fuel_gap_pct", *ref_cols,
                    "omniscient_solver"])
        ref = self.reference
        for name, rows in self.cases.items():
            gap = 100.0 * (rows["fuel_kg"] - ref["omniscient_fuel_kg"]) \
                / ref["omniscient_fuel_kg"]
            for i in range(len(rows["success"])):
                w.writerow([name, i, *(_fmt(rows[k][i]) for k in _CASE_KEYS), _fmt(gap[i]),
                            *(_fmt(ref[k][i]) for k in ref_cols),
                            ref["omniscient_solver"][i]])
        return buf.getvalue()


def _fmt(v) -> str:
    if isinstance(v, (bool, np.bool_)):
        return str(bool(v))
    v = float(v)
    return "" if not math.isfinite(v) else repr(v)


def campaign_summary(config: CampaignConfig, cases: dict[str, dict[str, np.ndarray]],
                     reference: dict[str, np.ndarray], curve: dict, wall_s: float,
                     has_target: bool, reference_info: dict,
                     law_identity: dict[str, dict] | None = None) -> dict[str, Any]:
    """The campaign's JSON contract (``schema`` :data:`SCHEMA_VERSION`)::

        {"schema": 1, "env": ID, "uncertainty": NAME, "uncertainty_model": {...σ...},
         "uncertainty_model_version": V, "cases": N, "seed": S, "env_kwargs": {...},
         "law_identity": {NAME: {"spec", "fingerprint", ...}},
         "laws": {NAME: {"success_rate", "success_ci95": [lo, hi],
                         "touchdown_speed_p50_m_s", "touchdown_speed_p99_m_s",
                         "touchdown_speed_max_m_s", "miss_p50_m", "miss_p95_m", "miss_p99_m",
                         "footprint_3sigma" (pinpoint), "fuel_p50_kg", "fuel_p99_kg",
                         "fuel_gap_p50_pct", "fuel_gap_p99_pct", "propellant_margin_p1_kg",
                         "us_per_decision", "cases", "successes", "fuel_gap_cases"}},
         "reference": {"solver", "converged", "converged_by": {METHOD: n}, "fuel_p50_kg"},
         "robustness_curve": {NAME: [{"scale", "success_rate", "success_ci95", "cases"}]},
         "wall_s": seconds}

    ``uncertainty_model_version`` is :data:`lunar_env.uncertainty.MODEL_VERSION` of the
    model the cases were flown under. ``law_identity[NAME]`` says which law NAME is: its full
    spec (``spec``: a run's path in full, options sorted), the fingerprint that names its
    tasks in the store (``fingerprint``, 16 hex digits), and what its factory declares of its
    files (a learned law: ``model_sha256``, ``vecnormalize_sha256``, ``obs_features``).

    Undefined values (no case, or an infinite percentile) are null.
    """
    laws = {name: summarise_law(rows, reference, has_target) for name, rows in cases.items()}
    ref_fuel = np.asarray(reference["omniscient_fuel_kg"], dtype=np.float64)
    return {
        "schema": SCHEMA_VERSION, "env": config.env_id, "uncertainty": config.uncertainty.name,
        "uncertainty_model": config.uncertainty.as_dict(),
        "uncertainty_model_version": MODEL_VERSION, "cases": int(config.cases),
        "seed": int(config.seed), "env_kwargs": config.env_kwargs,
        "law_identity": dict(law_identity or {}), "laws": laws,
        "reference": {**reference_info, "converged": int(np.isfinite(ref_fuel).sum()),
                      "converged_by": dict(sorted(Counter(
                          m for m in reference["omniscient_solver"] if m).items())),
                      "fuel_p50_kg": _finite_pct(ref_fuel, 50)},
        "robustness_curve": {
            name: [{"scale": s, "success_rate": k / m, "success_ci95": list(wilson_interval(k, m)),
                    "cases": m} for s, k, m in pts] for name, pts in curve.items()},
        "wall_s": float(wall_s),
    }


def _json_safe(o):
    """Plain JSON values: non-finite floats as null, NumPy scalars and arrays as Python ones."""
    if isinstance(o, dict):
        return {k: _json_safe(v) for k, v in o.items()}
    if isinstance(o, (list, tuple, np.ndarray)):
        return [_json_safe(v) for v in o]
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, (float, np.floating)):
        return float(o) if math.isfinite(float(o)) else None
    if isinstance(o, np.integer):
        return int(o)
    return o


def run_campaign(config: CampaignConfig, out_dir: str | Path, *, workers: int = 1,
                 address: str | None = None, executor: Executor | None = None,
                 progress: bool = True, plots: bool = True,
                 json_file: str | Path | None = None, max_tasks: int | None = None,
                 wait: bool = False) -> CampaignResult:
    """Run (or resume) a campaign; writes ``campaign.json``, ``cases.csv`` and the plots into
    ``out_dir`` (and the JSON also to ``json_file``).

    Before any work, every law is built once in this process (:func:`check_laws`) and the env
    under every error scale (:func:`check_scales`). The directory is written by one process
    at a time: its :class:`~optimizers.common.lock.DirectoryLock` is held for the whole run.
    Every stored result is read back verified (:func:`campaign_schema`); one that fails is
    moved aside and flown again.

    Parameters
    ----------
    config : CampaignConfig
    out_dir : path
        Holds the store of finished tasks (``store/``): a rerun resumes from it.
    workers : int
        Local processes (0: this process); ignored when ``address`` selects Ray.
    address : str, optional
        Ray cluster (``"local"``, ``"auto"``, ``host:port``).
    executor : Executor, optional
        Run the tasks here instead (neither closed nor stopped here; ``workers`` and
        ``address`` are then ignored).
    max_tasks : int, optional
        Submit at most this many missing tasks, then stop (tests of the resume).
    wait : bool
        Wait for another process writing ``out_dir`` to finish (default: refuse at once).

    Raises
    ------
    ValueError
        A law or an error scale refused by the checks; a store of other settings in
        ``out_dir`` (:class:`~optimizers.common.store.StoreIdentityError`).
    ~optimizers.common.lock.DirectoryBusy
        Another process writes ``out_dir`` (and ``wait`` is False).
    RuntimeError
        ``max_tasks`` stopped the campaign before every task finished (the finished ones are
        stored).
    """
    t0 = time.perf_counter()
    out = Path(out_dir)
    with DirectoryLock(out, wait=wait, what="campaign"):
        law_keys = check_laws(config)
        check_scales(config)
        tasks, n_cases = campaign_tasks(config, law_keys)
        store = ResultStore(out / "store", identity=config.identity(), fmt="json",
                            schema=campaign_schema(config, n_cases))
        own = executor is None
        ex = get_executor(address, workers) if own else executor
        try:
            results, _ = run_tasks(tasks, ex, store, progress="campaign" if progress else False,
                                   max_tasks=max_tasks)
        except BaseException:
            if own:  # an interrupt or a failed task: stop the workers now, keep what is stored
                ex.terminate()
            raise
        finally:
            if own:
                ex.close()
        if len(results) < len(tasks):
            raise RuntimeError(f"campaign stopped after {len(results)} of {len(tasks)} tasks "
                               f"(max_tasks={max_tasks}); run it again to resume")
        result, has_target = _gather(config, law_keys, tasks, results, t0)
        text = json.dumps(result.summary, indent=1).encode()
        atomic_write_bytes(out / "campaign.json", text)
        if json_file:
            atomic_write_bytes(json_file, text)
        atomic_write_bytes(out / "cases.csv", result.rows_csv().encode())
        if plots:
            from guidance.campaign.plots import plot_campaign

            plot_campaign(result, out, has_target)
    return result


def _gather(config: CampaignConfig, law_keys: dict[str, tuple[str, dict]], tasks: list[Task],
            results: dict, t0: float) -> tuple[CampaignResult, bool]:
    """The finished campaign from its tasks' results, and whether its env has a target."""
    from guidance.registry import parse_law_spec

    by_key = {t.key: results[t.key] for t in tasks}

    def gather(problem: str, keys: tuple[str, ...], n_cases: int) -> dict[str, np.ndarray]:
        parts = [by_key[TaskKey(problem, config.seed, k)]
                 for k in range(len(config.chunks(n_cases)))]
        return {key: np.concatenate([np.asarray(p[key], dtype=bool if key == "success"
                                                else np.float64) for p in parts])
                for key in keys}, parts

    reference, ref_parts = gather(_REF_TASK, _REF_KEYS, config.cases)
    reference["omniscient_solver"] = [m for p in ref_parts for m in p["omniscient_solver"]]
    cases: dict[str, dict[str, np.ndarray]] = {}
    curve: dict[str, list[tuple[float, int, int]]] = {}
    identities: dict[str, dict] = {}
    for text in config.laws:
        label = parse_law_spec(text).label()
        key, ident = law_keys[text]
        identities[label] = {**ident, "fingerprint": key.rsplit("#", 1)[1]}
        rows, parts = gather(_flight_problem(config, key, 1.0), _CASE_KEYS, config.cases)
        n_dec = sum(p["n_decisions"] for p in parts)
        rows["us_per_decision"] = 1e6 * sum(p["policy_wall_s"] for p in parts) / max(n_dec, 1)
        cases[label] = rows
        pts = []
        for scale in sorted(config.scales):
            r, _ = gather(_flight_problem(config, key, scale), ("success",),
                          config.cases if scale == 1.0 else config.curve_n)
            ok = r["success"][:config.curve_n]
            pts.append((scale, int(ok.sum()), int(len(ok))))
        curve[label] = pts
    from guidance.flight import make_vec
    from optimizers.optimum import optimum_family

    venv = make_vec(config.env_id, 1, config.env_kwargs)
    fam = optimum_family(venv.unwrapped)
    has_target = bool(venv.unwrapped.has_target)
    venv.close()
    ref_info = {"solver": f"{type(fam).__name__}.plant_optimum_fuel "
                          "(true plant, true start)",
                "wall_s": float(sum(p.get("wall_s", 0.0) for p in ref_parts))}
    wall = time.perf_counter() - t0
    summary = _json_safe(campaign_summary(config, cases, reference, curve, wall, has_target,
                                          ref_info, identities))
    return CampaignResult(config, cases, reference, curve, summary, wall), has_target
