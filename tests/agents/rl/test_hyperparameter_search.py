"""train.py --optimize: Optuna trials on the executor, resumable, best entry written as YAML."""

from __future__ import annotations

import numpy as np
import optuna
import pytest

from agents.hyperparams import load_hyperparams
from agents.rl.search import TrialEvalCallback, score
from agents.train import main


def test_score_orders_landings_fuel_and_crashes():
    land = np.array([True, True, False, False])
    assert score(land, np.array([280.0, 282.0, 0, 0]), np.array([1, 1, 50.0, 50.0])) == \
        pytest.approx(0.5 - 0.281 - 0.5 * 0.05)
    # more landings beat less fuel; softer crashes beat harder ones; no landing at all is < 0
    assert score(np.ones(4, bool), np.full(4, 290.0), np.ones(4)) > score(land, np.full(4, 270.0),
                                                                        np.ones(4))
    none = np.zeros(4, bool)
    assert score(none, np.zeros(4), np.full(4, 10.0)) > score(none, np.zeros(4),
                                                             np.full(4, 900.0))
    assert score(none, np.zeros(4), np.full(4, np.nan)) == pytest.approx(-1.0)


class _Trial:
    """An Optuna trial's reporting surface: records the reports, prunes when told to."""

    def __init__(self, prune: bool) -> None:
        self.prune = prune
        self.reports: list[tuple[float, int]] = []

    def report(self, value: float, step: int) -> None:
        self.reports.append((value, step))

    def should_prune(self) -> bool:
        return self.prune


def _steps(cb: TrialEvalCallback, model, timesteps) -> list[bool]:
    out = []
    for t in timesteps:
        model.num_timesteps = t
        out.append(cb.on_step())
    return out


@pytest.mark.parametrize("prune", [False, True])
def test_trial_callback_reports_each_evaluation_and_prunes_before_the_last(prune):
    """Scores at the first step at or after each multiple of ``eval_every``, reported as steps
    1, 2, ...; a pruning trial stops the training at its first evaluation that is not the last,
    and a trial is never pruned at the last one."""
    from types import SimpleNamespace

    model = SimpleNamespace(num_timesteps=0, logger=None)
    scores = iter([0.25, 0.5, 0.75])
    trial = _Trial(prune)
    cb = TrialEvalCallback(trial, lambda m: next(scores), eval_every=100, n_evaluations=3)
    cb.init_callback(model)
    if prune:
        assert _steps(cb, model, [50, 120]) == [True, False]
        assert cb.pruned and cb.n_evals == 1 and cb.last == 0.25
        assert trial.reports == [(0.25, 1)]
        last = TrialEvalCallback(_Trial(True), lambda m: 1.0, eval_every=100, n_evaluations=1)
        last.init_callback(model)
        assert _steps(last, model, [100]) == [True] and not last.pruned
    else:
        assert all(_steps(cb, model, [50, 120, 199, 200, 250, 310, 320]))
        assert trial.reports == [(0.25, 1), (0.5, 2), (0.75, 3)]
        assert cb.n_evals == 3 and cb.last == 0.75 and not cb.pruned


def test_optimize_quick_writes_best_entry_and_resumes(tmp_path, capsys):
    out = tmp_path / "search"
    argv = ["--optimize", "--quick", "-n", "1024", "--n-trials", "2", "--n-evaluations", "2",
            "--tune-states", "4", "--workers", "0", "--run-dir", str(out), "--no-progress",
            "--seed", "3", "--n-startup-trials", "1"]
    assert main(argv) == 0
    best = load_hyperparams(out / "best.yml", "LunarSoftLanding-v0")
    assert best["n_timesteps"] == 1024 and best["n_steps"] in (64, 128, 256, 512)
    assert best["policy_kwargs"]["activation_fn"] in ("tanh", "relu")
    assert "curriculum" in best  # the base entry's run keys are kept
    table = (out / "trials.md").read_text()
    assert table.count("COMPLETE") + table.count("PRUNED") == 2

    from agents.rl.search import make_storage

    study = optuna.load_study(study_name="LunarSoftLanding-v0-ppo",
                              storage=make_storage(str(out / "study.journal")))
    assert len(study.trials) == 2
    capsys.readouterr()
    assert main(argv) == 0  # rerun: both trials are stored, nothing is trained again
    assert len(optuna.load_study(study_name="LunarSoftLanding-v0-ppo",
                                 storage=make_storage(str(out / "study.journal"))).trials) == 2
    assert "Trained" not in capsys.readouterr().out
