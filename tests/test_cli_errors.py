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
    (["--n-states", "0"], "argument --n-states: 0 is out of range; allowed: 1 to"),
])
def test_agents_evaluate_usage_errors(argv, expected, capsys):
    from agents.evaluate import main

    line = _usage_error(main, argv, capsys)
    assert line.startswith("python -m agents.evaluate: error:") and expected in line


@pytest.mark.parametrize("argv, expected", [
    (["--env", "Nope-v0"], "'Nope-v0' is not a registered"),
    (["--env-kwargs", "dt_s=-1"], "dt_s = -1"),
    (["--n", "0"], "argument --n: 0 is out of range; allowed: 1 to"),
    (["--noise", "-0.5"], "argument --noise: -0.5 is out of range; allowed: finite and >= 0"),
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
    (["zhu2007", "--runs", "0"], "argument --runs: 0 is out of range; allowed: 1 to 100000"),
])
def test_optimizers_reproduce_usage_errors(argv, expected, capsys):
    from optimizers.reproduce.__main__ import main

    line = _usage_error(main, argv, capsys)
    assert ": error:" in line and expected in line


_UNWRITABLE = "/dev/null/out.json"  # under a file: no process can create it (root included)

# (command, argv, text the one line must contain): every bad argument names its option and what
# is allowed; checked before any work (negative and huge counts, seeds outside [0, 2**63 - 1],
# output files that are directories or cannot be created, malformed Ray addresses)
_BAD_ARGUMENTS = [
    ("study", ["--runs", "-3"], "argument --runs: -3 is out of range; allowed: 1 to 100000"),
    ("study", ["--runs", "10000000000000"], "argument --runs: 10000000000000 is out of range"),
    ("study", ["--runs", "many"], "argument --runs: 'many' is not an integer"),
    ("study", ["--seed", "-1"], "argument --seed: -1 is out of range; allowed: 0 to 2**63 - 1"),
    ("study", ["--seed", str(2**70)], f"argument --seed: {2**70} is out of range"),
    ("study", ["--workers", "-1"], "argument --workers: -1 is out of range; allowed: 0 to"),
    ("study", ["--json", "{tmp}"], "argument --json: {tmp} is a directory; give a file name"),
    ("study", ["--json", _UNWRITABLE], "argument --json: /dev/null/out.json cannot be "
                                       "created: /dev/null is a file"),
    ("study", ["--address", "garbage"], "argument --address: 'garbage' is not a Ray address; "
                                        "allowed: 'auto', 'local', HOST:PORT"),
    ("study", ["--address", "host:99999"], "argument --address: 'host:99999' is not a Ray"),
    ("study", ["--out", "{file}"], "--out {file}:"),
    ("zhu2007", ["--runs", "-1"], "argument --runs: -1 is out of range; allowed: 1 to 100000"),
    ("zhu2007", ["--runs", str(2**70)], "argument --runs"),
    ("zhu2007", ["--seed", "-1"], "argument --seed: -1 is out of range"),
    ("zhu2007", ["--seed", str(2**70)], "argument --seed"),
    ("zhu2007", ["--generations", "0"], "argument --generations: 0 is out of range"),
    ("zhu2007", ["--json", "{tmp}"], "argument --json: {tmp} is a directory"),
    ("zhu2007", ["--json", _UNWRITABLE], "argument --json: /dev/null/out.json cannot be"),
    ("peng2012", ["--guesses", "-2"], "argument --guesses: -2 is out of range; allowed: 0 to"),
    ("peng2012", ["--seed", str(2**70)], "argument --seed"),
    ("peng2012", ["--json", "{tmp}"], "argument --json: {tmp} is a directory"),
    ("peng_mars", ["--runs", "-1"], "argument --runs"),
    ("peng_mars", ["--starts", "-1"], "argument --starts"),
    ("peng_mars", ["--seed", "-1"], "argument --seed"),
    ("peng_mars", ["--json", _UNWRITABLE], "argument --json"),
    ("wang2001", ["--seeds", "0"], "argument --seeds: 0 is out of range"),
    ("wang2001", ["--n-scan", "2"], "argument --n-scan: 2 is out of range; allowed: 3 to"),
    ("wang2001", ["--json", "{tmp}"], "argument --json"),
    ("wang2003", ["--runs", "-1"], "argument --runs: -1 is out of range; allowed: 0 to"),
    ("wang2003", ["--seed", str(2**70)], "argument --seed"),
    ("wang2003", ["--json", _UNWRITABLE], "argument --json"),
    ("reproduce", ["nope"], "invalid choice: 'nope'"),
]


@pytest.mark.parametrize("command, argv, expected", _BAD_ARGUMENTS,
                         ids=[f"{c}-{' '.join(a)[:40]}" for c, a, _ in _BAD_ARGUMENTS])
def test_optimizer_commands_refuse_bad_arguments_in_one_line(command, argv, expected, tmp_path,
                                                             capsys):
    """``python -m optimizers.study`` and ``python -m optimizers.reproduce``: one
    argparse-style line naming the option and what is allowed, exit 2, no traceback, nothing
    written."""
    from optimizers.reproduce.__main__ import main as reproduce
    from optimizers.study.__main__ import main as study

    a_file = tmp_path / "a_file"
    a_file.write_text("")
    fill = {"{tmp}": str(tmp_path), "{file}": str(a_file)}
    argv = [fill.get(a, a) for a in argv]
    for k, v in fill.items():
        expected = expected.replace(k, v)
    if command == "study":
        line = _usage_error(study, ["ea", "zhu2007", "--out", str(tmp_path / "out"), *argv],
                            capsys)
        assert line.startswith("python -m optimizers.study: error:")
        assert not (tmp_path / "out" / "results").exists()
    elif command == "reproduce":
        line = _usage_error(reproduce, argv, capsys)
    else:
        line = _usage_error(reproduce, [command, *argv], capsys)
        assert line.startswith(f"python -m optimizers.reproduce {command}: error:")
    assert expected in line, line


_NOWHERE = "/nonexistent/run"

# (command, argv, text the one line must contain) of the agents' commands: every bad number or
# path names its option and what is allowed, before any work
_AGENT_BAD_ARGUMENTS = [
    ("evaluate", ["--n-states", "-1"], "argument --n-states: -1 is out of range; allowed: 1 to"),
    ("evaluate", ["--seed", "-1"], "argument --seed: -1 is out of range; allowed: 0 to 2**63 - 1"),
    ("evaluate", ["--seed", str(2**70)], f"argument --seed: {2**70} is out of range"),
    ("evaluate", ["--expert-states", "-2"], "argument --expert-states: -2 is out of range"),
    ("evaluate", ["--trace-cases", "many"], "argument --trace-cases: 'many' is not an integer"),
    ("evaluate", ["--torch-threads", "0"], "argument --torch-threads: 0 is out of range"),
    ("evaluate", ["--optimum-workers", "0"], "argument --optimum-workers: 0 is out of range"),
    ("evaluate", ["--json", "{tmp}"], "argument --json: {tmp} is a directory; give a file name"),
    ("evaluate", ["--out", "{file}"], "argument --out: {file} is a file, not a directory"),
    ("evaluate", ["--address", "garbage"], "argument --address: 'garbage' is not a Ray address"),
    ("train", ["-n", "0"], "argument -n/--n-timesteps: 0 is out of range; allowed: 1 to"),
    ("train", ["--n-envs", "-1"], "argument --n-envs: -1 is out of range; allowed: 1 to"),
    ("train", ["--seed", "-1"], "argument --seed: -1 is out of range; allowed: 0 to 2147483647"),
    ("train", ["--seed", str(2**32)], f"argument --seed: {2**32} is out of range"),
    ("train", ["--save-freq", "0"], "argument --save-freq: 0 is out of range"),
    ("train", ["--torch-threads", "0"], "argument --torch-threads: 0 is out of range"),
    ("train", ["--eval-states", "-1"], "argument --eval-states: -1 is out of range"),
    ("train", ["--eval-seed", str(2**70)], "argument --eval-seed"),
    ("train", ["--verbose", "3"], "argument --verbose/-v: 3 is out of range; allowed: 0 to 2"),
    ("train", ["--summary-every", "-1"], "argument --summary-every: -1 is out of range"),
    ("train", ["--n-trials", "0"], "argument --n-trials: 0 is out of range"),
    ("train", ["--tune-states", "x"], "argument --tune-states: 'x' is not an integer"),
    ("train", ["--workers", "-1"], "argument --workers: -1 is out of range"),
    ("train", ["--address", "host:0"], "argument --address: 'host:0' is not a Ray address"),
    ("train", ["--run-dir", "{file}"], "argument --run-dir: {file} is a file, not a directory"),
    ("train", ["--log-folder", "/dev/null/runs"], "argument --log-folder/-f: /dev/null/runs "
                                                  "cannot be created: /dev/null is a file"),
    ("train", ["--resume", _NOWHERE], f"argument --resume: {_NOWHERE} does not exist"),
    ("train", ["--init-from", _NOWHERE], f"argument --init-from: {_NOWHERE} does not exist"),
    ("train", ["--hyperparams-file", _NOWHERE], "argument --hyperparams-file/--conf-file: "
                                                f"{_NOWHERE} does not exist"),
    ("dataset", ["--n", "-5"], "argument --n: -5 is out of range; allowed: 1 to"),
    ("dataset", ["--seed", str(2**70)], "argument --seed"),
    ("dataset", ["--workers", "0"], "argument --workers: 0 is out of range"),
    ("dataset", ["--shard-size", "0"], "argument --shard-size: 0 is out of range"),
    ("dataset", ["--n-steps", "1"], "argument --n-steps: 1 is out of range; allowed: 2 to"),
    ("dataset", ["--noise", "nan"], "argument --noise: nan is out of range; allowed: finite"),
    ("dataset", ["--tol-radius-m", "0"], "argument --tol-radius-m: 0 is out of range; "
                                         "allowed: finite and > 0"),
    ("dataset", ["--tol-speed-m-s", "fast"], "argument --tol-speed-m-s: 'fast' is not a number"),
    ("dataset", ["--out", "{tmp}"], "argument --out: {tmp} is a directory; give a file name"),
    ("dataset", ["--address", "garbage"], "argument --address"),
    ("imitation", ["bc", "--seed", "-1"], "argument --seed: -1 is out of range"),
    ("imitation", ["bc", "--torch-threads", "0"], "argument --torch-threads: 0 is out of range"),
    ("imitation", ["bc", "--eval-states", "-1"], "argument --eval-states: -1 is out of range"),
    ("imitation", ["bc", "--eval-seed", "-1"], "argument --eval-seed: -1 is out of range"),
    ("imitation", ["bc", "--run-dir", "{file}"], "argument --run-dir: {file} is a file"),
    ("imitation", ["bc", "--log-folder", "/dev/null/runs"], "argument --log-folder/-f"),
    ("imitation", ["bc", "--resume", _NOWHERE], f"argument --resume: {_NOWHERE} does not exist"),
    ("imitation", ["dagger", "--init", _NOWHERE], f"argument --init: {_NOWHERE} does not exist"),
    ("imitation", ["evaluate", "--n-states", "0"], "argument --n-states: 0 is out of range"),
    ("imitation", ["evaluate", "--seed", str(2**70)], "argument --seed"),
    ("imitation", ["evaluate", "--expert-states", "-1"], "argument --expert-states"),
    ("imitation", ["evaluate", "--json", "{tmp}"], "argument --json: {tmp} is a directory"),
    ("imitation", ["evaluate", "--out", "{file}"], "argument --out: {file} is a file"),
]


@pytest.mark.parametrize("command, argv, expected", _AGENT_BAD_ARGUMENTS,
                         ids=[f"{c}-{' '.join(a)[:40]}" for c, a, _ in _AGENT_BAD_ARGUMENTS])
def test_agent_commands_refuse_bad_arguments_in_one_line(command, argv, expected, tmp_path,
                                                         capsys):
    """``python -m agents.evaluate``, ``python train.py``, ``lunar dataset`` and ``python -m
    agents.imitation``: one argparse-style line naming the option and what is allowed, exit 2,
    no traceback, nothing written."""
    from agents.evaluate import main as evaluate
    from agents.imitation.cli import main as imitation
    from agents.imitation.make_dataset import main as dataset
    from agents.train import main as train

    a_file = tmp_path / "a_file"
    a_file.write_text("")
    fill = {"{tmp}": str(tmp_path), "{file}": str(a_file)}
    argv = [fill.get(a, a) for a in argv]
    for k, v in fill.items():
        expected = expected.replace(k, v)
    runs = ["--log-folder", str(tmp_path / "runs")]
    main, prog, extra = {
        "evaluate": (evaluate, "python -m agents.evaluate", []),
        "train": (train, "train.py", [] if "--log-folder" in argv else runs),
        "dataset": (dataset, "lunar dataset", []),
        "imitation": (imitation, "python -m agents.imitation",
                      runs if argv[0] != "evaluate" and "--log-folder" not in argv else []),
    }[command]
    if command == "imitation":  # a subcommand's parser names it
        prog = f"{prog} {argv[0]}"
        argv = [argv[0], *extra, *argv[1:]]
    else:
        argv = [*extra, *argv]
    line = _usage_error(main, argv, capsys)
    assert line.startswith(f"{prog}: error:"), line
    assert expected in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]
