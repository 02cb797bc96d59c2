"""optimizers.study: seeded runs on the executor, certified, resumable; the registry."""

from __future__ import annotations

import json

import numpy as np
import pytest

from optimizers.evolutionary import ASAGA
from optimizers.problems import PlanarLandingProblem
from optimizers.study import markdown_table, run_study
from optimizers.study.__main__ import main
from optimizers.study.registry import ALGORITHMS, PROBLEMS, make_algorithm, make_problem


def test_registry_builds_and_names_unknowns():
    assert "asaga" in ALGORITHMS and "zhu2007" in PROBLEMS
    assert isinstance(make_algorithm("asaga", n_generations=3), ASAGA)
    assert make_problem("zhu2007-si").penalty_units == "si"
    with pytest.raises(ValueError, match="available"):
        make_algorithm("no-such-algorithm")
    with pytest.raises(ValueError, match="available"):
        make_problem("no-such-problem")


def test_study_resumes_and_equals_direct_runs(tmp_path):
    """An interrupted study resumes with only the missing runs; run i is the run a user gets
    from SeedSequence(seed).spawn(n)[i], whatever the executor."""
    kw = dict(seed=3, settings={"n_generations": 4}, out=tmp_path, certify_runs=False,
              progress=False)
    part = run_study("asaga", "zhu2007", 3, max_tasks=2, **kw)
    assert not part["complete"] and len(part["rows"]) == 2
    full = run_study("asaga", "zhu2007", 3, **kw)
    assert full["complete"] and full["summary"]["runs_resumed"] == 2
    assert full["summary"]["runs_this_session"] == 1
    problem = PlanarLandingProblem("zhu2007")
    for i, ss in enumerate(np.random.SeedSequence(3).spawn(3)):
        r = ASAGA(n_generations=4).solve(problem, seed=np.random.default_rng(ss))
        row = full["rows"][i]
        assert row["index"] == i and row["fuel_kg"] == r.fuel_kg and row["x"] == r.x.tolist()
        assert row["success"] == r.success
    with pytest.raises(ValueError, match="settings"):  # another study in the same directory
        run_study("asaga", "zhu2007", 3, **{**kw, "settings": {"n_generations": 5}})


def test_cli_quick_study_with_certificate(tmp_path, capsys):
    out = tmp_path / "study"
    assert main(["asaga", "zhu2007", "--runs", "2", "--set", "n_generations=3", "--workers",
                 "0", "--out", str(out), "--json", str(tmp_path / "s.json"),
                 "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "success (problem's verdict)" in text and "fuel gap to optimum" in text
    data = json.loads((tmp_path / "s.json").read_text())
    assert data["complete"] and len(data["rows"]) == 2
    assert data["optimum"]["success"] and 270 < data["optimum"]["fuel_kg"] < 285
    for row in data["rows"]:
        cert = row["certificate"]
        assert cert is not None
        assert cert["fuel_gap_kg"] == pytest.approx(row["fuel_kg"] - data["optimum"]["fuel_kg"])
    assert (out / "study.png").exists() and (out / "table.md").exists()
    assert "Optimum:" in markdown_table({**data, "summary": data["summary"]})
