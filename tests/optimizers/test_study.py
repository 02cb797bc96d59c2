"""optimizers.study: seeded runs on the executor, certified, resumable; the registry."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from proc_helpers import REPO, alive, children, wait_for

from optimizers.common.executor import TaskKey
from optimizers.common.store import ResultStore
from optimizers.evolutionary import ASAGA
from optimizers.problems import PlanarLandingProblem
from optimizers.study import markdown_table, run_study, study_identity
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
    assert full["summary"]["runs_this_call"] == 1
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



# ------------------------------------------------------------ interrupts and one writer (CLI)

_STUDY_ARGS = ["asaga", "zhu2007", "--quick", "--no-certify", "--no-plot", "--no-progress",
               "--workers", "2", "--runs", "60", "--set", "n_generations=300"]
_STUDY_CLI = """
    import sys
    from optimizers.study.__main__ import main
    sys.exit(main(sys.argv[1:]))
"""


def _study_process(out) -> subprocess.Popen:
    """The study command in a child process, with -W error::UserWarning (a leaked semaphore,
    reported by the resource tracker as a UserWarning, then fails loudly)."""
    env = dict(os.environ, PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1")
    return subprocess.Popen([sys.executable, "-W", "error::UserWarning", "-c",
                             textwrap.dedent(_STUDY_CLI), *_STUDY_ARGS, "--out", str(out)],
                            cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def _key_of(stem: str) -> TaskKey:
    problem, seed, index = stem.split("__")
    return TaskKey(problem, int(seed.removeprefix("seed")), int(index))


@pytest.mark.parametrize("sig, status", [("SIGTERM", 143), ("SIGINT", 130)])
def test_an_interrupted_study_stops_cleanly_and_resumes(tmp_path, capsys, sig, status):
    """SIGTERM or SIGINT to a running study: its workers stop, the finished runs stay stored,
    one line is printed, exit 143 / 130; no traceback, no leaked semaphore; the same study then
    resumes from the stored runs. While it runs, a second study in its directory is refused at
    once, naming the first one's PID."""
    out = tmp_path / "study"
    proc = _study_process(out)
    workers: set[int] = set()

    def started():
        workers.update(children(proc.pid))
        return (out / "results").is_dir() and any((out / "results").glob("*.json"))

    try:
        wait_for(started, 300, proc)
        workers.update(children(proc.pid))
        with pytest.raises(SystemExit) as second:  # one writer per study directory
            main([*_STUDY_ARGS, "--out", str(out)])
        assert second.value.code == 2
        line = capsys.readouterr().err.strip().splitlines()[-1]
        assert line.startswith("python -m optimizers.study: error:")
        assert f"is in use by process {proc.pid}" in line
        proc.send_signal(getattr(signal, sig))
        _, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
        proc.wait()
    err = stderr.decode()
    assert proc.returncode == status, err
    assert err.strip().splitlines() == ["interrupted; run the same command to resume"], err
    wait_for(lambda: not any(alive(p) for p in workers), 30)  # the workers stopped too
    results = out / "results"
    assert not list(results.glob(".*tmp")) and not list(results.glob("*.damaged"))
    settings = {"n_generations": 300}
    store = ResultStore(out, study_identity("asaga", "zhu2007", settings=settings,
                                            certify_runs=False))
    stored = store.keys()
    assert stored and all(store.readable(_key_of(k)) for k in stored)
    again = run_study("asaga", "zhu2007", 60, settings=settings, out=out, certify_runs=False,
                      progress=False, max_tasks=1)
    assert again["summary"]["runs_resumed"] == len(stored)
    assert again["summary"]["runs_this_call"] == 1


def test_cli_refuses_another_studys_directory_and_a_lost_identity(tmp_path, capsys):
    """Another study's directory, or one whose identity.json was deleted (a resume with other
    settings then adopted them), is a one-line usage error before any run."""
    out = tmp_path / "study"
    base = ["asaga", "zhu2007", "--runs", "1", "--workers", "0", "--no-certify", "--no-plot",
            "--no-progress", "--out", str(out)]
    assert main([*base, "--set", "n_generations=2"]) == 0
    capsys.readouterr()
    for damage in ("other settings", "identity deleted"):
        if damage == "identity deleted":
            (out / "identity.json").unlink()
        with pytest.raises(SystemExit) as info:
            main([*base, "--set", "n_generations=3"])
        assert info.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) >= 1 and "Traceback" not in "".join(err)
        line = err[-1]
        assert line.startswith(f"python -m optimizers.study: error: --out {out}:")
        assert ("holds results of another study" in line if damage == "other settings"
                else "identity.json is missing" in line)
    assert len(list((out / "results").glob("*.json"))) == 1
