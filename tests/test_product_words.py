"""The product speaks of itself: code, comments, YAML, tests and pyproject describe the product,
not how it was made. No issue numbers, no development rounds, no pointers to the research log
(the measured figures that justify a choice are stated inline instead).

The words are those of ``tools/check_product_words.py``; this test applies them to the tracked
``.py``, ``.yml``, ``.yaml`` and ``.toml`` files of the packages, tests, benchmarks, examples,
``train.py`` and ``pyproject.toml``, and to every tracked file under ``.ci/``; it also refuses
citations of the research log's present home and sessions named by their place ("the last
one").
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tools"))
import check_product_words as cpw  # noqa: E402

#: folders and files scanned (relative to the repository root)
SCOPE = ("lunar_env", "optimizers", "guidance", "agents", "tests", "benchmarks", "examples",
         "lunar", "train.py", "pyproject.toml", ".ci")
SUFFIXES = {".py", ".yml", ".yaml", ".toml"}
#: files left out of the scan (none)
EXCLUDED: frozenset[str] = frozenset()
#: the checker's labels not applied here: the benchmarks print the system's loadavg beside
#: their timings, as the context of what they measured (the label built from parts, so that
#: this file holds none of the checker's words)
LABELS_NOT_CHECKED = frozenset({"machine" + " load"})
#: words checked here besides the checker's (each written so that it does not match itself):
#: the research log in its present home (the checker flags its old one), and the sessions
#: named by their place rather than an ordinal
EXTRA: tuple[tuple[str, re.Pattern[str]], ...] = (
    ("research log", re.compile(r"\bresearch[/]notes\b", re.IGNORECASE)),
    ("development round", re.compile(r"\b(?:last|next|previous)[ ]sessions?\b", re.IGNORECASE)),
)


def _scanned_files() -> list[str]:
    try:
        out = subprocess.run(["git", "ls-files", "-z", "--", *SCOPE], cwd=REPO, check=True,
                             capture_output=True, timeout=60).stdout.decode()
        files = [f for f in out.split("\0") if f]
    except (OSError, subprocess.SubprocessError):  # not a git checkout: walk the folders
        files = []
        for entry in SCOPE:
            path = REPO / entry
            found = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
            files += [p.relative_to(REPO).as_posix() for p in found]
    return sorted(f for f in files
                  if f not in EXCLUDED and (f.startswith(".ci/") or Path(f).suffix in SUFFIXES)
                  and (REPO / f).is_file())


def _hits(files: list[str], root: Path = REPO) -> list[str]:
    """``file:line: label: match`` of every hit in ``files`` (relative to ``root``)."""
    found = [(name, n, label, text)
             for name, n, label, text in cpw.hits([root / f for f in files], root=root)
             if label not in LABELS_NOT_CHECKED]
    for f in files:
        text = (root / f).read_text(encoding="utf-8", errors="replace")
        for n, line in enumerate(text.splitlines(), start=1):
            found += [(f, n, label, m.group(0))
                      for label, pattern in EXTRA for m in pattern.finditer(line)]
    return [f"{name}:{n}: {label}: {text!r}" for name, n, label, text in sorted(found)]


def test_the_scan_covers_the_scope():
    files = _scanned_files()
    assert {"pyproject.toml", "train.py", "tests/conftest.py", ".ci/run"} <= set(files)
    assert any(f.startswith("lunar_env/envs/") for f in files)
    assert any(f.startswith("agents/hyperparams/") and f.endswith(".yml") for f in files)
    assert LABELS_NOT_CHECKED <= {label for label, _ in cpw.WORDS}


def test_the_words_are_found(tmp_path):
    # built from parts, so that this file holds none of the words it tests
    page = tmp_path / "page.py"
    page.write_text("\n".join([
        "# Iss" + "ue 31: measured",
        "# (iss" + "ue-16, fif" + "th session)",
        "# see doc" + "s/notes/x.md",
        "# see research" + "/notes/x.md",
        "# Seventh and eigh" + "th sessions: resumed",
        "# as in the previ" + "ous session",
        "# a POSIX session; pytest_sessionstart(session); the study issues a command",
        "# train_wall_s_this_session: one record per process",
    ]), encoding="utf-8")
    hits = _hits([page.name], root=tmp_path)
    assert [h.split(": ")[:2] for h in hits] == [
        ["page.py:1", "issue number"], ["page.py:2", "development round"],
        ["page.py:2", "issue number"], ["page.py:3", "research log"],
        ["page.py:4", "research log"], ["page.py:5", "development round"],
        ["page.py:6", "development round"]]


def test_the_product_speaks_of_itself():
    hits = _hits(_scanned_files())
    assert not hits, ("process words in the product (state the reason and the measured figure "
                      "instead):\n" + "\n".join(hits))
