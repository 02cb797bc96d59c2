"""The built site holds together: every internal link and image resolves, and headless
Chromium renders the index and an env page with their pictures.

These tests read the site ``.ci/run`` builds before the test run
(``python -m sphinx -W --keep-going -b html docs docs/_build/html``; ``LUNAR_DOCS_HTML`` names
another build) and skip, saying so, when there is none."""

from __future__ import annotations

import re
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest
from docs_helpers import BUILD_COMMAND, SITE, chromium, is_external, parse_html, run_chromium

pytestmark = pytest.mark.skipif(not (SITE / "index.html").is_file(),
                                reason=f"no built site in {SITE}; build it with: {BUILD_COMMAND}")

ENV_PAGE = "envs/LunarSoftLanding-v0.html"


def _target(page: Path, ref: str) -> tuple[Path, str]:
    parts = urlsplit(ref)
    path = page if not parts.path else (page.parent / unquote(parts.path)).resolve()
    if path.is_dir():
        path = path / "index.html"
    return path, unquote(parts.fragment)


def test_internal_links_and_images_resolve():
    pages = sorted(SITE.rglob("*.html"))
    assert len(pages) > 20
    parsed = {p.resolve(): parse_html(p.read_text(encoding="utf-8")) for p in pages}
    broken = []
    for page, doc in parsed.items():
        for kind, ref in doc.refs:
            if not ref or is_external(ref) or ref.startswith("javascript:"):
                continue
            path, fragment = _target(page, ref)
            if not path.exists():
                broken.append(f"{page.relative_to(SITE.resolve())}: {kind}={ref} (no file)")
            elif fragment and path.suffix == ".html" and path in parsed and \
                    fragment not in parsed[path].ids:
                broken.append(f"{page.relative_to(SITE.resolve())}: {ref} (no anchor)")
    assert not broken, "broken internal links:\n" + "\n".join(broken[:50])


def test_every_env_page_has_its_picture():
    pages = sorted((SITE / "envs").glob("Lunar*.html"))
    assert pages, "no env pages were generated"
    for page in pages:
        doc = parse_html(page.read_text(encoding="utf-8"))
        images = [ref for kind, ref in doc.refs if kind == "src" and ref.endswith(".png")]
        assert images, f"{page.name} has no picture"
        for ref in images:
            assert (page.parent / ref).resolve().stat().st_size > 10_000, ref


@pytest.mark.skipif(chromium() is None,
                    reason="chromium is not installed (apt-get install -y chromium; .ci/run "
                           "installs it)")
@pytest.mark.parametrize(("page", "title"), [("index.html", "lunar-descent-guidance"),
                                             (ENV_PAGE, "LunarSoftLanding-v0")])
def test_chromium_renders_page_with_its_images(tmp_path, page, title):
    url = (SITE / page).resolve().as_uri()
    r = run_chromium(url, tmp_path / "profile", "--dump-dom")
    assert r.returncode == 0, r.stderr[-2000:]
    dom = r.stdout
    doc = parse_html(dom)
    assert title in doc.title, f"title {doc.title!r} of {page}"
    images = [ref for kind, ref in doc.refs if kind == "src" and
              re.search(r"\.(png|svg|jpg)$", ref)]
    assert images, f"{page} rendered without images"
    for ref in images:
        assert (SITE / page).parent.joinpath(unquote(ref)).resolve().is_file(), ref
    shot = tmp_path / "page.png"
    r = run_chromium(url, tmp_path / "profile", f"--screenshot={shot}", "--window-size=1280,1600",
                     "--hide-scrollbars")
    assert r.returncode == 0, r.stderr[-2000:]
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert shot.stat().st_size > 20_000, "the screenshot is blank"
