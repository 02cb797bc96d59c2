"""Structure counts of a checkout: scenario-type forks, function-local imports, upward imports,
command lines, private names used across modules.

    python research/tools/structure_counts.py ROOT
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

PACKAGES = ("lunar_env", "optimizers", "guidance", "agents", "lunar")
LAYER = {"lunar_env": 0, "optimizers": 1, "guidance": 2, "agents": 3, "lunar": 4}
SCENARIO_TYPES = ("PlanarScenario", "PinpointScenario")


def modules(root: Path):
    for pkg in PACKAGES:
        base = root / pkg
        if not base.exists():
            continue
        for path in base.rglob("*.py"):
            parts = list(path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            yield ".".join(parts), path


def main(root: Path) -> None:
    forks = local = clis = private = 0
    fork_sites = []
    for mod, path in modules(root):
        tree = ast.parse(path.read_text())
        family_module = ".families." in f".{mod}." or mod.endswith("families") \
            or mod.startswith("lunar_env.scenarios") or ".optimum." in f".{mod}."
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "isinstance":
                names = {n.id for n in ast.walk(node.args[1]) if isinstance(n, ast.Name)} \
                    if len(node.args) > 1 else set()
                if names & set(SCENARIO_TYPES) and not family_module:
                    forks += 1
                    fork_sites.append(f"{mod}:{node.lineno}")
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                for sub in ast.walk(node):
                    if isinstance(sub, ast.Import | ast.ImportFrom) and sub is not node:
                        level = getattr(sub, "level", 0)
                        target = sub.module if isinstance(sub, ast.ImportFrom) else \
                            sub.names[0].name
                        if level or (target or "").split(".")[0] in PACKAGES:
                            local += 1
            if isinstance(node, ast.Attribute) and node.attr.startswith("_") \
                    and not node.attr.startswith("__") and isinstance(node.value, ast.Name) \
                    and node.value.id not in ("self", "cls"):
                private += 1
        src = path.read_text()
        if "argparse.ArgumentParser" in src and "def main(" in src:
            clis += 1
    print(f"scenario-type forks outside family modules: {forks} {fork_sites}")
    print(f"function-local imports of project modules: {local}")
    print(f"command-line modules: {clis}")
    print(f"private attributes read through another module or object: {private}")


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "."))
