"""Imports point one way (function-local imports included):

    lunar (the command line) -> agents -> guidance -> optimizers -> lunar_env

and, inside ``guidance/`` and ``agents/``, from a room to the rooms below it only (the orders of
:data:`ROOMS`). ``guidance`` needs neither torch nor SB3, and the env tests import only the envs
(and the optimisers they replay)."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
LAYER = {"lunar_env": 0, "optimizers": 1, "guidance": 2, "agents": 3, "lunar": 4}

#: the rooms of a package, lowest first: a room imports only itself and the rooms before it
ROOMS = {
    "guidance": ["explicit", "frames", "families", "law", "registry", "flight", "laws",
                 "evaluation", "campaign"],
    "agents": ["common", "hyperparams", "features", "laws", "evaluate", "rl", "imitation",
               "train"],
}


def _imports(path: Path, module: str) -> set[str]:
    """Every module ``module`` (at ``path``) imports, with ``from X import y`` as both ``X`` and
    ``X.y`` (``y`` may be a submodule)."""
    tree = ast.parse(path.read_text())
    is_pkg = path.name == "__init__.py"
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                base = node.module or ""
            else:
                b = module.split(".") if is_pkg else module.split(".")[:-1]
                b = b[: len(b) - (node.level - 1)]
                base = ".".join(b + ([node.module] if node.module else []))
            out.add(base)
            out.update(f"{base}.{a.name}" for a in node.names)
    return out


def _modules(packages=LAYER):
    for pkg in packages:
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
    assert not bad, "layering violations (lunar -> agents -> guidance -> optimizers -> " \
                    "lunar_env):\n" + "\n".join(sorted(bad))


@pytest.mark.parametrize("pkg", list(ROOMS))
def test_rooms_import_only_rooms_below_them(pkg):
    rooms = ROOMS[pkg]
    bad = []
    for _, module, path in _modules((pkg,)):
        parts = module.split(".")
        if len(parts) < 2:
            continue
        assert parts[1] in rooms, f"{module}: room {parts[1]!r} has no place in ROOMS[{pkg!r}]"
        for target in _imports(path, module):
            tp = target.split(".")
            if tp[0] == pkg and len(tp) > 1 and tp[1] in rooms \
                    and rooms.index(tp[1]) > rooms.index(parts[1]):
                bad.append(f"{module} imports {target}")
    assert not bad, f"{pkg}: a room imports a room above it:\n" + "\n".join(sorted(set(bad)))


def test_guidance_needs_neither_torch_nor_sb3():
    heavy = ("torch", "stable_baselines3", "sb3_contrib")
    bad = [f"{module} imports {t}" for _, module, path in _modules(("guidance",))
           for t in _imports(path, module) if t.split(".")[0] in heavy]
    assert not bad, "\n".join(bad)


def test_env_tests_import_only_the_envs_and_the_optimisers():
    bad = []
    for path in (ROOT / "tests" / "lunar_env").rglob("*.py"):
        for t in _imports(path, "tests.lunar_env." + path.stem):
            if t.split(".")[0] in ("guidance", "agents", "lunar"):
                bad.append(f"{path.name} imports {t}")
    assert not bad, "\n".join(bad)


def test_optimizers_common_imports_nothing_above_it():
    """optimizers.common is the floor of optimizers: it imports lunar_env and itself only, never a
    problem, a family, the certification or the reproductions above it."""
    bad = []
    for _, module, path in _modules(("optimizers",)):
        if not (module == "optimizers.common" or module.startswith("optimizers.common.")):
            continue
        for target in _imports(path, module):
            if target.split(".")[0] == "optimizers" and not (
                    target == "optimizers.common" or target.startswith("optimizers.common.")):
                bad.append(f"{module} imports {target}")
    assert not bad, "optimizers.common points up:\n" + "\n".join(bad)
