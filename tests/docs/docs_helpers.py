"""Helpers of the documentation tests: the fenced blocks of a Markdown page, the built site,
and headless Chromium."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
#: the built site the tests read (CI builds it first: ``.ci/run``)
SITE = Path(os.environ.get("LUNAR_DOCS_HTML", DOCS / "_build" / "html"))
BUILD_COMMAND = "python -m sphinx -W --keep-going -b html docs docs/_build/html"
#: a fenced block preceded by this comment is not run by the tests (the comment says why)
SKIP_MARK = "<!-- not run by tests/docs"

_FENCE = re.compile(r"^(?P<fence>```+)(?P<info>[^\n`]*)\n(?P<body>.*?)^(?P=fence)[ \t]*$",
                    re.M | re.S)


def fenced_blocks(path: Path) -> list[tuple[str, str, bool]]:
    """(language, code, skipped) of every fenced block of a Markdown page, in order; a block is
    skipped when the last non-blank line before it is a :data:`SKIP_MARK` comment."""
    text = path.read_text(encoding="utf-8")
    out = []
    for m in _FENCE.finditer(text):
        before = [ln for ln in text[:m.start()].splitlines() if ln.strip()]
        skipped = bool(before) and before[-1].lstrip().startswith(SKIP_MARK)
        out.append((m.group("info").strip(), m.group("body"), skipped))
    return out


def shell_commands(body: str) -> list[str]:
    """The commands of a shell block, one per logical line (continuation lines joined; blank
    lines and comment lines left out)."""
    return [c for c in body.replace("\\\n", " ").splitlines()
            if c.strip() and not c.lstrip().startswith("#")]


class _Links(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.refs: list[tuple[str, str]] = []
        self.ids: set[str] = set()
        self.title = ""
        self._in_title = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        for key in ("id", "name"):
            if a.get(key):
                self.ids.add(a[key])
        if tag == "a" and a.get("href") is not None:
            self.refs.append(("href", a["href"]))
        if tag in ("img", "script") and a.get("src"):
            self.refs.append(("src", a["src"]))
        if tag == "link" and a.get("href"):
            self.refs.append(("href", a["href"]))
        self._in_title = tag == "title"

    def handle_endtag(self, tag):
        if tag == "title":
            self._in_title = False

    def handle_data(self, data):
        if self._in_title:
            self.title += data


def parse_html(text: str) -> _Links:
    p = _Links()
    p.feed(text)
    return p


def is_external(ref: str) -> bool:
    return bool(re.match(r"^[a-z][a-z0-9+.-]*:", ref, re.I)) or ref.startswith("//")


def chromium() -> str | None:
    """The headless browser, if installed (Debian's ``chromium``)."""
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    return None


def run_chromium(url: str, user_data_dir: Path, *args: str, timeout: float = 120.0
                 ) -> subprocess.CompletedProcess:
    """Headless Chromium on ``url`` with no network activity of its own."""
    cmd = [chromium(), "--headless", "--no-sandbox", "--disable-gpu",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           "--no-first-run", f"--user-data-dir={user_data_dir}", *args, url]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=False)
