"""Sphinx configuration of the lunar-descent-guidance site (furo theme, MyST Markdown pages).

Build (from the repository's top directory)::

    python -m sphinx -W --keep-going -b html docs docs/_build/html

Every build first regenerates what is read from the code (``docs/_scripts``): the env pages
and their pictures, the tables of the uncertainty model, the law catalogue, the campaign schema
and the shipped hyperparameters, and the API pages. ``LUNAR_DOCS_NO_IMAGES=1`` skips flying the
episodes for the env pictures (the pages then have none).
"""

from __future__ import annotations

import inspect
import json
import os
import re
import subprocess
import sys
from pathlib import Path

from sphinx.util import logging as _sphinx_logging

_log = _sphinx_logging.getLogger(__name__)

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))

project = "lunar-descent-guidance"
author = "the lunar-descent-guidance authors"
copyright = "the lunar-descent-guidance authors"


def _version() -> str:
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    m = re.search(r'^version\s*=\s*"([^"]+)"', text, flags=re.M)
    return m.group(1) if m else "unknown"


release = version = _version()

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_scripts", "_generated", "Thumbs.db", ".DS_Store"]

# -- MyST -------------------------------------------------------------------------------------
myst_enable_extensions = ["colon_fence", "deflist"]
# anchors for headings down to ###, so pages can link to a section: [text](page.md#a-heading)
myst_heading_anchors = 3

# -- autodoc ----------------------------------------------------------------------------------
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_class_signature = "separated"
# the reference shows the project's own docstrings: a method it inherits without writing one
# (Gymnasium's ``Env.step``, SB3's) keeps its base's documentation there
autodoc_inherit_docstrings = False
# numpydoc is the project's style; Google style is what the methods inherited from Gymnasium
# (``Env.step``, ``Env.reset``) carry
napoleon_google_docstring = True
napoleon_numpy_docstring = True
napoleon_use_rtype = False
# a class's "Attributes" section as fields of the class, not as attribute entries of their own:
# a dataclass field named there is also a member autodoc documents, and one name would get two
# entries (and an instance's docs would repeat its class's)
napoleon_use_ivar = True

# Type names in numpydoc fields ("n : int", "shape (n, 3)") are resolved as cross-references;
# a short name such as ``n`` matches attributes of several classes, and Sphinx links the first
# and warns. Those links are not wrong enough to fail the build for.
suppress_warnings = ["ref.python"]

# -- HTML -------------------------------------------------------------------------------------
html_theme = "furo"
html_title = "lunar-descent-guidance"
html_static_path = ["_static"]
html_css_files = ["custom.css"]
html_show_sourcelink = False

# -- What is read from the code ---------------------------------------------------------------
_GENERATORS = ("gen_env_pages.py", "gen_tables.py", "gen_api_pages.py")


def _generate(app) -> None:
    """Run each generator in a process of its own (the env pictures fly compiled envs; the
    build's process keeps only what autodoc imports)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    for script in _GENERATORS:
        cmd = [sys.executable, str(DOCS / "_scripts" / script)]
        if script == "gen_env_pages.py" and os.environ.get("LUNAR_DOCS_NO_IMAGES") == "1":
            cmd.append("--no-images")
        subprocess.run(cmd, check=True, cwd=ROOT, env=env)


# -- Docstrings as autodoc reads them -----------------------------------------------------------
#: docstrings that are not valid reST: autodoc shows them verbatim (a literal block) instead of
#: failing the build. Each is listed for its owner to fix; remove a name once its docstring
#: parses. (Module, class or function names, exactly as autodoc names them.)
VERBATIM_DOCSTRINGS: set[str] = {
    "lunar_env.envs.core.LanderBatch",                   # a field list without a blank line
}

_LITERAL = re.compile(r"(``.+?``|`[^`]*`)")


def _escape_bars(line: str) -> str:
    """``|x|`` (an absolute value, as the docstrings write it) escaped outside literals, so
    reST does not read it as a substitution; a line of a grid table (``+``, ``| ``) or of a line
    block (``| ``) is left alone."""
    head = line.lstrip()
    if "|" not in line or head.startswith(("+", "| ")) or head == "|":
        return line
    parts = _LITERAL.split(line)
    for i in range(0, len(parts), 2):
        parts[i] = parts[i].replace("|", "\\|")
    return "".join(parts)


def _escape_bars_outside_literals(lines: list[str]) -> list[str]:
    """:func:`_escape_bars` on every line except those of a literal block (the indented lines
    after a line ending in ``::``), where a backslash would be shown as it is."""
    out: list[str] = []
    literal_indent: int | None = None  # indentation of the line that opened a literal block
    for line in lines:
        indent = len(line) - len(line.lstrip())
        if literal_indent is not None and line.strip() and indent <= literal_indent:
            literal_indent = None
        if literal_indent is not None:
            out.append(line)
            continue
        out.append(_escape_bars(line))
        if line.rstrip().endswith("::"):
            literal_indent = indent
    return out


def _env_manual(obj) -> bool:
    """True for an env class whose docstring is its Markdown manual (``## Description``...),
    which docs/_scripts/gen_env_pages.py lays out as the env's page."""
    return isinstance(obj, type) and "## Description" in (obj.__doc__ or "")


def _process_docstring(app, what, name, obj, options, lines):
    if _env_manual(obj):
        summary = (obj.__doc__ or "").strip().splitlines()[0]
        ids = _ENV_IDS.get(f"{obj.__module__}:{obj.__qualname__}", [])
        if not ids:  # a vector env: the page of its single env
            single = obj.__qualname__.replace("VectorEnv", "Env")
            ids = _ENV_IDS.get(f"{obj.__module__}:{single}", [])
        links = ", ".join(f":doc:`{i} </envs/{i}>`" for i in ids)
        lines[:] = [summary, "", f"The manual of this env is its page: {links}."]
        return
    if what == "data" and obj is not None and lines and \
            "\n".join(lines).strip() == (type(obj).__doc__ or "").strip():
        lines[:] = []  # a constant without a doc comment: not its type's docstring
        return
    if name in VERBATIM_DOCSTRINGS:
        raw = inspect.getdoc(obj) or ""
        lines[:] = ["::", ""] + ["    " + line for line in raw.splitlines()] + [""]
        return
    lines[:] = _escape_bars_outside_literals(lines)


def _env_ids() -> dict[str, list[str]]:
    """{entry point: [env ids]} of the registered lunar_env envs."""
    import gymnasium as gym

    import lunar_env  # noqa: F401

    out: dict[str, list[str]] = {}
    for env_id, spec in sorted(gym.registry.items()):
        if isinstance(spec.entry_point, str) and spec.entry_point.startswith("lunar_env."):
            out.setdefault(spec.entry_point, []).append(env_id)
    return out


_ENV_IDS: dict[str, list[str]] = {}


def _aliases() -> dict[str, str]:
    path = DOCS / "api" / "aliases.json"
    return json.loads(path.read_text(encoding="utf-8")) if path.is_file() else {}


def _missing_reference(app, env, node, contnode):
    """A Python reference Sphinx did not find: a re-exported name resolves to where it is
    documented (``docs/api/aliases.json``); a reference written in a hand-written page that
    still resolves nowhere is a warning (so the build fails), as a broken link would be. (A
    reference in a docstring is the code owner's; it renders as code, unlinked.)"""
    if node.get("refdomain") != "py":
        return None
    target = node.get("reftarget", "")
    aliases = app.config._lunar_aliases
    if target in aliases:
        domain = env.get_domain("py")
        return domain.resolve_xref(env, node.get("refdoc", ""), app.builder,
                                   node.get("reftype", "obj"), aliases[target], node, contnode)
    source = str(node.source or "")
    if source.endswith(".md") and not Path(source).name.startswith("Lunar"):
        _log.warning("unresolved Python reference %r in a hand-written page", target,
                     location=node)
    return None


def _load_aliases(app) -> None:
    app.config._lunar_aliases = _aliases()


def setup(app):
    _ENV_IDS.update(_env_ids())
    app.connect("builder-inited", _generate)
    app.connect("builder-inited", _load_aliases)  # after the generators wrote them
    app.connect("missing-reference", _missing_reference)
    app.connect("autodoc-process-docstring", _process_docstring)
    return {"parallel_read_safe": True}
