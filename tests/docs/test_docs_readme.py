"""The README holds together: it stays a map (at most 200 lines), its Python blocks run (in one
interpreter, in order, as a reader types them), and every command of its shell blocks starts
with something that exists: a script of the repository, an importable module run with
``python -m``, the project's console script or a tool of the environment. Running the shell
blocks is the slow suite's job (``tests/docs/test_docs_quickstart.py``, at smoke-test sizes).
"""

from __future__ import annotations

import importlib.util
import os
import re
import shlex
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

from docs_helpers import ROOT, SKIP_MARK, fenced_blocks, shell_commands

README = ROOT / "README.md"
#: how many lines the README may have: it is a map, the rest lives in the docs
MAX_LINES = 200
#: the prefix of the commands that name the virtual environment's tools
VENV_BIN = ".venv/bin/"
#: what separates the commands of one shell line
_SEPARATORS = {"&&", "||", ";", "|"}


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get("PYTHONPATH", "")
                                                       .split(os.pathsep) if p])
    env.setdefault("MPLBACKEND", "Agg")
    return env


def _console_scripts() -> set[str]:
    data = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    return set(data["project"].get("scripts", {}))


def _installed_by(commands: list[list[str]]) -> set[str]:
    """The distributions that ``pip install -e ".[EXTRA,...]"`` among ``commands`` installs
    from the project's extras (lower-case names, without version bounds)."""
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))[
        "project"].get("optional-dependencies", {})
    names: set[str] = set()
    for words in commands:
        if words[0].removeprefix(VENV_BIN) != "pip" or "install" not in words:
            continue
        for w in words:
            if w.startswith(".[") and w.endswith("]"):
                for extra in w[2:-1].split(","):
                    for req in extras.get(extra.strip(), []):
                        names.add(re.split(r"[\s<>=!~;\[]", req, maxsplit=1)[0].lower())
    return names


def _commands(line: str) -> list[list[str]]:
    """The simple commands of one shell line, as words (comments dropped)."""
    lexer = shlex.shlex(line, posix=True, punctuation_chars=True)
    lexer.whitespace_split = True
    lexer.commenters = "#"
    out: list[list[str]] = [[]]
    for token in lexer:
        if token in _SEPARATORS:
            out.append([])
        else:
            out[-1].append(token)
    return [c for c in out if c]


def _missing(words: list[str], scripts: set[str], installed: set[str] = frozenset()
             ) -> str | None:
    """Why the command ``words`` does not start with something that exists, or None; a module
    of a distribution the same line installs (``installed``) counts as existing."""
    name = words[0].removeprefix(VENV_BIN)
    if name in ("python", "python3"):
        if words[1:2] == ["-m"]:
            module = words[2] if len(words) > 2 else ""
            top = module.split(".")[0].lower()
            return None if module and (importlib.util.find_spec(module) or top in installed) \
                else f"no module {module!r}"
        script = words[1] if len(words) > 1 else ""
        return None if script.endswith(".py") and (ROOT / script).is_file() else \
            f"no script {script!r}"
    if name in scripts:
        return None
    here = Path(sys.executable).parent / name
    if here.exists() or shutil.which(name):
        return None
    return f"{name!r} is neither a script, a module, the project's command nor a tool"


def test_the_readme_is_a_map():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= MAX_LINES, f"README.md has {len(lines)} lines (at most {MAX_LINES})"


def test_every_block_is_python_or_shell_and_a_skipped_one_says_why():
    blocks = fenced_blocks(README)
    assert any(lang == "python" for lang, _, _ in blocks)
    assert any(lang == "bash" and not skipped for lang, _, skipped in blocks)
    assert {lang for lang, _, skipped in blocks if not skipped} <= {"python", "bash", "text"}
    for line in README.read_text(encoding="utf-8").splitlines():
        if line.startswith(SKIP_MARK):
            assert ":" in line and len(line.split(":", 1)[1].strip(" ->")) > 10, line


def test_readme_python_blocks_run(tmp_path):
    code = "\n\n".join(body for lang, body, skipped in fenced_blocks(README)
                       if lang == "python" and not skipped)
    script = tmp_path / "readme.py"
    script.write_text(code, encoding="utf-8")
    r = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=_env(),
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, f"README Python blocks failed:\n{r.stdout}\n{r.stderr}"


def test_every_shell_command_starts_with_something_that_exists():
    scripts = _console_scripts()
    blocks = [body for lang, body, _ in fenced_blocks(README) if lang == "bash"]
    assert blocks
    problems = []
    n = 0
    for body in blocks:
        for line in shell_commands(body):
            commands = _commands(line)
            installed = _installed_by(commands)
            for words in commands:
                n += 1
                why = _missing(words, scripts, installed)
                if why:
                    problems.append(f"{line}: {why}")
    assert n > 10, n
    assert not problems, "README commands that cannot run:\n" + "\n".join(problems)


def test_the_checker_of_commands_refuses_what_does_not_exist():
    scripts = _console_scripts()
    assert _missing(["python", "no_such_script.py"], scripts)
    assert _missing(["python", "-m", "no_such_module_here"], scripts)
    assert _missing(["no-such-tool-here"], scripts)
    assert _missing([".venv/bin/python", "train.py"], scripts) is None
    assert _missing(["lunar", "dataset"], scripts) is None
    assert _commands("a x && b -y | c # d && e") == [["a", "x"], ["b", "-y"], ["c"]]


def test_a_missing_module_counts_only_where_the_same_line_installs_its_extra():
    line = '.venv/bin/pip install -e ".[docs]" && .venv/bin/python -m sphinx_not_a_module'
    commands = _commands(line)
    assert _missing(commands[1], set(), _installed_by(commands)) == \
        "no module 'sphinx_not_a_module'"
    assert "sphinx" in _installed_by(commands)
    assert _missing(["python", "-m", "sphinx"], set(), {"sphinx"}) is None
    assert _installed_by(_commands(".venv/bin/python -m sphinx")) == set()
