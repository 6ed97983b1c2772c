"""The package's layers, over every module: what may import what, and no cycles.

Rules (docs/architecture.md): Hydra, OmegaConf and MLflow only under ``maglev/study/``;
no matplotlib in estimation, the model or validation; ``import maglev`` stays light;
no import cycle between the package's modules.

Package-internal imports are read from the source (every module, module-level
imports for the layer rules, function-level ones too for cycles); what each
third-party package pulls in at import time is measured in a fresh interpreter
(``control`` imports matplotlib, for instance), so a rule broken through a library is
caught as well as one broken directly.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from functools import cache
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "maglev"
HEAVY = ("hydra", "omegaconf", "mlflow")
NO_PLOTTING = ("maglev.estimation", "maglev.model", "maglev.validation", "maglev.initial_state", "maglev.data",
               "maglev.polynomials", "maglev.structures", "maglev.uncertainty", "maglev.fit", "maglev.spectral")


def module_names() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


MODULES = module_names()


@cache
def imports_of(name: str, module_level: bool) -> tuple[frozenset[str], frozenset[str]]:
    """(package modules, third-party top-level names) that ``name`` imports."""
    path = MODULES[name]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    if module_level:
        nodes = [n for stmt in tree.body if not isinstance(stmt, (ast.FunctionDef, ast.AsyncFunctionDef))
                 for n in ast.walk(stmt) if not isinstance(stmt, ast.ClassDef) or n is stmt]
    else:
        nodes = list(ast.walk(tree))
    internal, external = set(), set()

    def add(target: str) -> None:
        if target.split(".")[0] != "maglev":
            external.add(target.split(".")[0])
            return
        while target and target not in MODULES:  # an attribute of a module: the module
            target = target.rpartition(".")[0]
        if target and target != name:
            internal.add(target)

    for node in nodes:
        if isinstance(node, ast.Import):
            for alias in node.names:
                add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(up + ([base] if base else []))
            for alias in node.names:
                add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES else base)
    parent = name.rpartition(".")[0]
    while parent:  # importing a submodule runs its packages' __init__ first
        internal.add(parent)
        parent = parent.rpartition(".")[0]
    internal.discard(name)
    return frozenset(internal), frozenset(external)


@cache
def pulled_by(library: str) -> frozenset[str]:
    """Which of HEAVY and matplotlib a third-party package imports, measured in a fresh interpreter."""
    code = (f"import sys\ntry:\n    import {library}\nexcept ImportError:\n    pass\n"
            f"print([m for m in {(*HEAVY, 'matplotlib')!r} if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    return frozenset(json.loads(out.replace("'", '"')))


def reaches(name: str) -> set[str]:
    """Every heavy top-level package that importing ``name`` pulls in (module-level imports, transitively)."""
    seen, stack, heavy = set(), [name], set()
    while stack:
        module = stack.pop()
        if module in seen:
            continue
        seen.add(module)
        internal, external = imports_of(module, module_level=True)
        stack.extend(internal)
        for library in external - set(sys.stdlib_module_names):
            heavy |= {library} & {*HEAVY, "matplotlib"} or pulled_by(library)
    return heavy


def test_import_maglev_pulls_in_no_hydra_omegaconf_mlflow_or_matplotlib():
    code = f"import sys, maglev\nprint([m for m in {(*HEAVY, 'matplotlib')!r} if m in sys.modules])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("name", [m for m in MODULES if not m.startswith("maglev.study")])
def test_only_the_study_layer_reaches_hydra_omegaconf_or_mlflow(name):
    assert reaches(name) & set(HEAVY) == set()


@pytest.mark.parametrize("name", [m for m in MODULES if m.startswith(NO_PLOTTING)])
def test_identification_core_does_not_reach_matplotlib(name):
    assert "matplotlib" not in reaches(name)


def test_the_rules_see_a_heavy_import_through_a_library():
    assert "matplotlib" in pulled_by("control")  # why plotting is kept out of the core by measurement
    assert "matplotlib" in reaches("maglev.plots") and "mlflow" in reaches("maglev.study.tracking")


def test_no_import_cycle_between_package_modules():
    graph = {name: imports_of(name, module_level=False)[0] for name in MODULES}
    graph = {name: {m for m in deps if not name.startswith(m + ".")} for name, deps in graph.items()}
    state: dict[str, int] = {}  # 1 on the current path, 2 done

    def visit(name: str, path: list[str]) -> list[str] | None:
        state[name] = 1
        for dep in sorted(graph[name]):
            if state.get(dep) == 1:
                return path[path.index(dep):] + [dep] if dep in path else [*path, dep]
            if dep not in state and (cycle := visit(dep, [*path, dep])):
                return cycle
        state[name] = 2
        return None

    for name in MODULES:
        if name not in state:
            cycle = visit(name, [name])
            assert cycle is None, " → ".join(cycle)
