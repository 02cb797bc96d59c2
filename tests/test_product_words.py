"""The product speaks of itself: code, comments, YAML, tests, the README, the changelog and the
docs describe the product, not how it was made. No issue numbers, no development rounds, no
pointers to the research log (the measured figures that justify a choice are stated inline
instead).

The words, the product's parts and the paths where a word is allowed are those of
``tools/check_product_words.py`` (one list); this test applies them to the tracked files of
its ``PRODUCT``, and checks that ``.ci/run`` runs the checker over the same parts.
"""

from __future__ import annotations

import shlex
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tools"))
import check_product_words as cpw  # noqa: E402


def _scanned_files() -> list[str]:
    """The tracked files of the checker's product (every file named by ``PRODUCT`` itself, and
    the files of the checker's kinds in its directories)."""
    try:
        out = subprocess.run(["git", "ls-files", "-z", "--", *cpw.PRODUCT], cwd=REPO,
                             check=True, capture_output=True, timeout=60).stdout.decode()
        files = [f for f in out.split("\0") if f]
    except (OSError, subprocess.SubprocessError):  # not a git checkout: walk the folders
        files = [p.resolve().relative_to(REPO).as_posix()
                 for p in cpw.product_files(cpw.default_paths(REPO))]
    this = Path(cpw.__file__).resolve()
    return sorted(f for f in files
                  if (f in cpw.PRODUCT or Path(f).suffix in cpw.SUFFIXES)
                  and not cpw.SKIP_PARTS & set(Path(f).parts)
                  and (REPO / f).is_file() and (REPO / f).resolve() != this)


def _hits(files: list[str], root: Path = REPO) -> list[str]:
    """``file:line: label: match`` of every hit in ``files`` (relative to ``root``)."""
    found = cpw.hits([root / f for f in files], root=root)
    return [f"{name}:{n}: {label}: {text!r}" for name, n, label, text in sorted(found)]


def test_the_scan_covers_the_product():
    files = set(_scanned_files())
    assert {"README.md", "CHANGELOG.md", "pyproject.toml", "train.py", "tests/conftest.py",
            ".ci/run", "docs/index.md"} <= files
    for part in ("lunar_env/envs/", "agents/hyperparams/", "docs/results/", "benchmarks/",
                 "guidance/", "optimizers/", "tests/docs/"):
        assert any(f.startswith(part) for f in files), part
    assert set(cpw.ALLOWED) <= {label for label, _ in cpw.WORDS}


def test_ci_checks_the_same_product():
    """``.ci/run``'s check line names every part of the checker's ``PRODUCT``."""
    lines = (REPO / ".ci" / "run").read_text(encoding="utf-8").replace("\\\n", " ").splitlines()
    runs = [shlex.split(ln) for ln in lines if "tools/check_product_words.py" in ln
            and not ln.lstrip().startswith("#")]
    assert len(runs) == 1, runs
    args = runs[0][runs[0].index("tools/check_product_words.py") + 1:]
    assert set(args) == set(cpw.PRODUCT)


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


def test_a_word_is_allowed_only_where_the_checker_allows_it(tmp_path):
    text = "print('lo" + "ad average', os.getloadavg())\n"
    for rel in ("benchmarks/bench_x.py", "lunar_env/x.py"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text, encoding="utf-8")
    hits = _hits(["benchmarks/bench_x.py", "lunar_env/x.py"], root=tmp_path)
    assert [h.split(": ")[:2] for h in hits] == [["lunar_env/x.py:1", "machine" + " load"]]


def test_the_product_speaks_of_itself():
    hits = _hits(_scanned_files())
    assert not hits, ("process words in the product (state the reason and the measured figure "
                      "instead):\n" + "\n".join(hits))
