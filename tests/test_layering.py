"""Imports point one way: agents -> optimizers -> lunar_env (function-local imports included)."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
LAYER = {"lunar_env": 0, "optimizers": 1, "agents": 2}


def _imports(path: Path, module: str) -> set[str]:
    tree = ast.parse(path.read_text())
    is_pkg = path.name == "__init__.py"
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                out.add(node.module or "")
            else:
                base = module.split(".") if is_pkg else module.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                out.add(".".join(base + ([node.module] if node.module else [])))
    return out


def _modules():
    for pkg in LAYER:
        for path in (ROOT / pkg).rglob("*.py"):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            yield pkg, ".".join(parts), path


@pytest.mark.parametrize("pkg", list(LAYER))
def test_no_import_points_up(pkg):
    bad = []
    for owner, module, path in _modules():
        if owner != pkg:
            continue
        for target in _imports(path, module):
            top = target.split(".")[0]
            if top in LAYER and LAYER[top] > LAYER[owner]:
                bad.append(f"{module} imports {target}")
    assert not bad, "layering violations (agents -> optimizers -> lunar_env):\n" + "\n".join(bad)


def test_optimizers_common_imports_nothing_above_it():
    """optimizers.common is the floor of optimizers: it imports lunar_env and itself only, never a
    problem, a family, the certification or the reproductions above it."""
    bad = []
    for _, module, path in _modules():
        if not (module == "optimizers.common" or module.startswith("optimizers.common.")):
            continue
        for target in _imports(path, module):
            if target.split(".")[0] == "optimizers" and not (
                    target == "optimizers.common" or target.startswith("optimizers.common.")):
                bad.append(f"{module} imports {target}")
    assert not bad, "optimizers.common points up:\n" + "\n".join(bad)
