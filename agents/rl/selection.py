"""Choose a run's final policy among its checkpoints by landings on held-out states.

Why: the policy of one PPO update (or DAgger iteration) to the next trades cases —
the pinpoint PPO's training success moved 93.0 → 89.9 % over its last two checkpoints, DAgger's
iterates 95 / 100 / 98 % — so the last iterate is a draw from that spread. Ross et al. (2011)
bound the *best* DAgger iterate, and SB3's ``EvalCallback(best_model_save_path=...)`` keeps the
best PPO checkpoint by evaluation return; here the criterion is the env's own verdict (landings)
on validation cases ``seed .. seed + n_states - 1`` (default 50000: disjoint from the training
draws, the imitation datasets' cases and the evaluation's 2026..). Ties go to the later
candidate. Deterministic actions, as in the evaluation.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.common.runs import write_text_atomic

__all__ = ["score_candidates", "select_checkpoint", "write_selection"]

#: validation case set (see module docstring)
VALIDATION_SEED = 50000


def score_candidates(candidates: list[tuple[int, Path]], env_id: str,
                     env_kwargs: dict[str, Any] | None, obs_features: list[str] | None,
                     n_states: int, seed: int = VALIDATION_SEED, device: str = "cpu",
                     label: str = "checkpoint", history: int | None = None
                     ) -> list[dict[str, Any]]:
    """Landings of each candidate ``(key, model .zip)`` on the validation cases; one dict per
    candidate (``key``, ``model``, ``vecnormalize``: the statistics file found for it by
    :func:`agents.common.runs.load_trained` or None, ``success_rate``, ``fuel_mean_kg`` of its
    landings), in the candidates' order. ``obs_features`` and ``history`` are the run's (the
    policies' inputs). Prints one line per candidate."""
    from agents.common.runs import load_trained
    from agents.laws import SB3Law
    from guidance.flight import rollout

    if int(n_states) < 1:
        raise ValueError(f"n_states={n_states!r} must be >= 1")
    scores = []
    for key, model_path in candidates:
        model, vn_path, _ = load_trained(model_path, device=device)
        res = rollout(env_id, SB3Law(model, vn_path, name=f"{label} {key}",
                                     obs_features=obs_features, history=history),
                      int(n_states), int(seed), env_kwargs, trace_cases=0)
        ok = res.is_success
        scores.append({"key": int(key), "model": Path(model_path), "vecnormalize": vn_path,
                       "success_rate": float(ok.mean()),
                       "fuel_mean_kg": float(np.mean(res.fuel_used_kg[ok])) if ok.any()
                       else float("nan")})
        print(f"selection: {label} {key} lands {100 * ok.mean():.1f} % of {n_states} "
              f"validation states", flush=True)
    return scores


def best_of(scores: list[dict[str, Any]]) -> dict[str, Any]:
    """The candidate with the most landings (the later one on a tie)."""
    return max(scores, key=lambda r: (r["success_rate"], r["key"]))


def write_selection(run_dir: Path, seed: int, n_states: int, key_name: str,
                    scores: list[dict[str, Any]], best: dict[str, Any],
                    **extra: Any) -> None:
    """``selection.yml`` (atomic): the validation set, ``chosen_<key_name>``, any ``extra``
    fields, and each candidate's ``<key_name>``, success rate and fuel (one writer for the
    PPO checkpoint and the DAgger iteration selections)."""
    write_text_atomic(Path(run_dir) / "selection.yml", yaml.safe_dump(
        {"validation_seed": int(seed), "n_states": int(n_states),
         f"chosen_{key_name}": best["key"], **extra,
         "scores": [{key_name: s["key"], "success_rate": s["success_rate"],
                     "fuel_mean_kg": s["fuel_mean_kg"]} for s in scores]}, sort_keys=False))


def select_checkpoint(run_dir: Path, env_id: str, env_kwargs: dict[str, Any] | None,
                      obs_features: list[str] | None, n_states: int, last: int,
                      seed: int = VALIDATION_SEED, device: str = "cpu",
                      warn_below: float | None = 0.5, history: int | None = None
                      ) -> tuple[int, Path, Path | None]:
    """Among the ``last`` newest checkpoints of an SB3 run, the one that lands most of the
    validation states; writes ``selection.yml`` atomically and returns ``(steps, model path,
    VecNormalize path or None)``.

    If even the chosen one lands less than ``warn_below`` of the validation states (None: never),
    a warning on stderr says so before any evaluation runs: the run did not learn to land, and
    no choice of checkpoint mends that (measured: two pinpoint PPO seeds of fourteen land 0 %
    on every checkpoint). ``selection.yml`` records the flag."""
    from agents.common.runs import checkpoints
    from lunar_env.validation import require_number

    if int(last) < 1:
        raise ValueError(f"select_checkpoint last={last!r} must be >= 1")
    if warn_below is not None:
        warn_below = require_number("select_checkpoint warn_below", warn_below)
        if not 0.0 <= warn_below <= 1.0:
            raise ValueError(f"select_checkpoint warn_below={warn_below!r} must be in [0, 1] "
                             "or None")
    found = checkpoints(run_dir)[:int(last)]
    if not found:
        raise FileNotFoundError(f"no checkpoint in {Path(run_dir) / 'checkpoints'}")
    scores = score_candidates(sorted(found), env_id, env_kwargs, obs_features, n_states, seed,
                              device, label="checkpoint at step", history=history)
    best = best_of(scores)
    low = warn_below is not None and best["success_rate"] < warn_below
    write_selection(run_dir, seed, n_states, "steps", scores, best,
                    below_warn_threshold=bool(low))
    print(f"selection: the checkpoint at step {best['key']:,} "
          f"({100 * best['success_rate']:.1f} %) is the final policy")
    if low:
        print(f"selection: WARNING: the best of the last {len(scores)} checkpoints lands only "
              f"{100 * best['success_rate']:.1f} % of the validation states (< "
              f"{100 * warn_below:.0f} %): this run has not learnt to land; train again "
              f"with another --seed", file=sys.stderr, flush=True)
    return best["key"], best["model"], best["vecnormalize"]
