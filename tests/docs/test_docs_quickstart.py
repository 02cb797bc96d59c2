"""The quickstart page runs: its Python blocks (in one interpreter, in order, as a reader types
them) and its shell blocks (the slow twin: each job at a smoke-test size), from a scratch
directory; the slow twin runs the README's shell blocks too (its quick tour, at the same
sizes). A block marked ``<!-- not run by tests/docs: why -->`` is set-up that needs the
network and a fresh virtual environment; ``.ci/run`` runs those commands itself."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from docs_helpers import DOCS, ROOT, SKIP_MARK, fenced_blocks, shell_commands

PAGE = DOCS / "quickstart.md"


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get("PYTHONPATH", "")
                                                       .split(os.pathsep) if p])
    # ``python`` and ``lunar`` are this interpreter's
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env.setdefault("MPLBACKEND", "Agg")
    return env


def test_every_block_is_run_or_says_why_not():
    blocks = fenced_blocks(PAGE)
    assert blocks, f"{PAGE} has no code blocks"
    langs = {lang for lang, _, skipped in blocks if not skipped}
    assert langs <= {"python", "bash"}, f"blocks the tests cannot run: {langs}"
    assert any(lang == "python" and not skipped for lang, _, skipped in blocks)
    text = PAGE.read_text(encoding="utf-8")
    for line in text.splitlines():
        if line.startswith(SKIP_MARK):
            assert ":" in line and len(line.split(":", 1)[1].strip(" ->")) > 10, \
                f"a skipped block must say why: {line}"


def test_quickstart_python_blocks_run(tmp_path):
    code = "\n\n".join(body for lang, body, skipped in fenced_blocks(PAGE)
                       if lang == "python" and not skipped)
    script = tmp_path / "quickstart.py"
    script.write_text(code, encoding="utf-8")
    r = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=_env(),
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, f"quickstart Python blocks failed:\n{r.stdout}\n{r.stderr}"


@pytest.mark.slow
@pytest.mark.parametrize("page", [PAGE, ROOT / "README.md"], ids=["quickstart", "README"])
def test_shell_blocks_run(tmp_path, page):
    (tmp_path / "train.py").symlink_to(ROOT / "train.py")
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    blocks = [body for lang, body, skipped in fenced_blocks(page)
              if lang == "bash" and not skipped]
    assert blocks
    for body in blocks:
        for command in shell_commands(body):
            r = subprocess.run(["bash", "-euo", "pipefail", "-c", command], cwd=tmp_path,
                               env=_env(), capture_output=True, text=True, timeout=3600)
            assert r.returncode == 0, (f"{page.name} command failed: {command}\n"
                                       f"{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
