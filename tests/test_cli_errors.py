"""Every command of the project answers a wrong input like argparse: one line
``<prog>: error: <message naming the value and what is allowed>`` and exit status 2; a bug
raised after validation keeps its traceback (optimizers.common.cli)."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import pytest

from optimizers.common.cli import check_env, error_message, user_input_errors

REPO = Path(__file__).resolve().parents[1]


def _usage_error(main, argv, capsys) -> str:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err.strip().splitlines()[-1]


def test_helper_turns_value_and_key_errors_into_parser_errors(capsys):
    p = argparse.ArgumentParser(prog="prog")
    for exc in (ValueError("x=3 must be >= 4"), KeyError("unknown law 'y'")):
        with pytest.raises(SystemExit) as info, user_input_errors(p):
            raise exc
        assert info.value.code == 2
    err = capsys.readouterr().err.splitlines()
    assert err[-1] == "prog: error: unknown law 'y'"
    assert "prog: error: x=3 must be >= 4" in err
    # anything else is a bug: it propagates untouched
    with pytest.raises(RuntimeError), user_input_errors(p):
        raise RuntimeError("bug")
    assert error_message(ValueError("a\n  b")) == "a b"


def test_check_env_names_the_project_envs_and_bad_arguments():
    with pytest.raises(ValueError, match=r"'Nope-v0'.*LunarSoftLanding-v0"):
        check_env("Nope-v0")
    with pytest.raises(ValueError, match="bogus"):
        check_env("LunarSoftLanding-v0", {"bogus": 1})
    check_env("LunarSoftLanding-v0", {"dt_s": 2.0})


def test_train_script_reports_an_unknown_env_without_traceback():
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.run([sys.executable, "train.py", "--env", "Nope-v0"], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("train.py: error: env 'Nope-v0' is not a registered")
    assert "LunarSoftLanding-v0" in last


@pytest.mark.parametrize("argv, expected", [
    (["--env", "Nope-v0"], "'Nope-v0' is not a registered"),
    (["--quick", "--hyperparams", "policy_kwargs.activation_fn=swish"], "allowed:"),
    (["--quick", "--hyperparams", "obs_features=[nope]"], "unknown obs_features"),
    (["--quick", "--hyperparams", "learning_rate=fast"], "learning_rate='fast'"),
    (["--quick", "--hyperparams", "n_envs=0"], "n_envs=0 must be >= 1"),
    (["--config", "nope"], "no profile 'nope'"),
])
def test_agents_train_usage_errors(argv, expected, capsys, tmp_path):
    from agents.train import main

    line = _usage_error(main, [*argv, "--log-folder", str(tmp_path)], capsys)
    assert line.startswith("train.py: error:") and expected in line
    assert not any(tmp_path.iterdir())  # refused before any run directory


def test_a_bug_during_training_keeps_its_traceback(monkeypatch, tmp_path):
    import agents.train as tr

    def broken(*args, **kwargs):
        raise ValueError("a bug inside the run")

    monkeypatch.setattr(tr, "train", broken)
    with pytest.raises(ValueError, match="a bug inside the run"):
        tr.main(["--quick", "--run-dir", str(tmp_path / "run"), "--no-progress"])


@pytest.mark.parametrize("argv, expected", [
    (["--env", "Nope-v0"], "'Nope-v0' is not a registered"),
    (["--env-kwargs", '{"bogus": 1}'], "bogus"),
    (["--env-kwargs", "{nope"], "is not JSON"),
    (["--model", "/nonexistent/run"], "--model /nonexistent/run"),
    (["--n-states", "0"], "--n-states 0"),
])
def test_agents_evaluate_usage_errors(argv, expected, capsys):
    from agents.evaluate import main

    line = _usage_error(main, argv, capsys)
    assert line.startswith("python -m agents.evaluate: error:") and expected in line


@pytest.mark.parametrize("argv, expected", [
    (["--env", "Nope-v0"], "'Nope-v0' is not a registered"),
    (["--env-kwargs", "dt_s=-1"], "dt_s = -1"),
    (["--n", "0"], "--n 0: must be >= 1"),
    (["--noise", "-0.5"], "--noise -0.5"),
    (["--minari", "optimal"], "NAME-v<version>"),
])
def test_agents_dataset_usage_errors(argv, expected, capsys):
    from agents.imitation.make_dataset import main

    line = _usage_error(main, argv, capsys)
    assert line.startswith("lunar dataset: error:") and expected in line


@pytest.mark.parametrize("argv, expected", [
    (["bc", "--env", "Nope-v0", "--dataset", "x.npz"], "'Nope-v0' is not a registered"),
    (["bc", "--dataset", "/nonexistent.npz"], "/nonexistent.npz does not exist"),
    (["bc", "--quick", "--dataset", "x.npz", "--hyperparams", "bc"], "key=value"),
    (["evaluate", "--model", "foo"], "expected NAME=PATH"),
    (["evaluate", "--model", "a=/nonexistent"], "/nonexistent"),
])
def test_agents_imitation_usage_errors(argv, expected, capsys):
    from agents.imitation.cli import main

    line = _usage_error(main, argv, capsys)
    assert line.startswith("python -m agents.imitation: error:") and expected in line


@pytest.mark.parametrize("argv, expected", [
    (["ea", "zhu2007", "--set", "bogus=1"], "bogus"),
    (["ea", "zhu2007", "--problem-set", "n_steps=abc"], "--problem-set {'n_steps': 'abc'}"),
    (["nope", "zhu2007"], "unknown algorithm 'nope'"),
])
def test_optimizers_study_usage_errors(argv, expected, capsys):
    from optimizers.study.__main__ import main

    line = _usage_error(main, argv, capsys)
    assert line.startswith("python -m optimizers.study: error:") and expected in line


@pytest.mark.parametrize("argv, expected", [
    ([], "the following arguments are required: scenario"),
    (["nope"], "invalid choice: 'nope'"),
    (["zhu2007", "--runs", "0"], "--runs and --generations must be >= 1"),
])
def test_optimizers_reproduce_usage_errors(argv, expected, capsys):
    from optimizers.reproduce.__main__ import main

    line = _usage_error(main, argv, capsys)
    assert ": error:" in line and expected in line
