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


PRIVATE_OWNER = "lunar_env.uncertainty"


def _resolve(node: ast.ImportFrom, module: str, is_pkg: bool) -> str:
    if node.level == 0:
        return node.module or ""
    base = module.split(".") if is_pkg else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _inside(name: str) -> bool:
    return name == PRIVATE_OWNER or name.startswith(PRIVATE_OWNER + ".")


def _private_uses(source: str, module: str, is_pkg: bool = False) -> list[str]:
    """Where the code ``source`` of ``module`` imports an underscore name of
    lunar_env.uncertainty (a private module or a private attribute), or reads one through a
    name bound to the package or a module of it (``unc._x``)."""
    tree = ast.parse(source)
    bound: set[str] = set()
    bad = []

    def private(dotted: str) -> bool:
        return any(p.startswith("_") for p in dotted[len(PRIVATE_OWNER):].split(".") if p)

    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if _inside(a.name):
                    if private(a.name):
                        bad.append(f"{module}:{node.lineno} imports {a.name}")
                    if a.asname:
                        bound.add(a.asname)
        elif isinstance(node, ast.ImportFrom):
            source = _resolve(node, module, is_pkg)
            for a in node.names:
                target = f"{source}.{a.name}"
                if _inside(source) and (private(source) or a.name.startswith("_")):
                    bad.append(f"{module}:{node.lineno} imports {a.name} from {source}")
                elif _inside(target):
                    bound.add(a.asname or a.name)
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in bound and node.attr.startswith("_")
                and not node.attr.startswith("__")):
            bad.append(f"{module}:{node.lineno} reads {node.value.id}.{node.attr}")
    return bad


def test_nothing_outside_lunar_env_uncertainty_uses_its_private_names():
    """lunar_env.uncertainty's private names (its _random module, its underscored helpers)
    are its own: the tasks, the agents, the benchmarks and the tests use its public API."""
    bad = []
    for top in (*LAYER, "benchmarks", "tests"):
        for path in (ROOT / top).rglob("*.py"):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            module = ".".join(parts)
            if _inside(module):
                continue
            bad += _private_uses(path.read_text(), module, path.name == "__init__.py")
    assert not bad, "private names of lunar_env.uncertainty used outside it:\n" + "\n".join(bad)


def test_the_private_name_check_sees_each_form():
    src = ("from lunar_env.uncertainty._random import splitmix64\n"
           "from lunar_env.uncertainty.navigation import _shrink\n"
           "from lunar_env import uncertainty as unc\n"
           "import lunar_env.uncertainty.navigation as nav\n"
           "unc._x\nnav._y\nunc.navigation_noise\n")
    found = _private_uses(src, "tests.probe")
    assert len(found) == 4, found
    # relative imports inside lunar_env resolve to the package too
    found = _private_uses("from ..uncertainty import _random\nfrom .. import uncertainty as u\n"
                          "u._shrink\n", "lunar_env.envs.task")
    assert len(found) == 2, found
