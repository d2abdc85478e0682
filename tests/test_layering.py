"""The layers of nrobust, read from the source: every import runs one way.

``docs/architecture.md`` states the rule: the core knows nothing of PDEs, files or
figures, the plants sit on the core, and the application layer on both. This test parses
every module (``ast``: module-level and function-level imports alike) and fails on an
edge the layering forbids, on a cycle, on a function-level import of nrobust itself (the
way cycles are dodged) and on a lookup of a module by name.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "nrobust"

#: Rank of each layer: a module may import modules of its own rank or below.
BASE, CORE, HYPERBOLIC, APPLICATION = 0, 1, 2, 3
LAYER_NAMES = {BASE: "base", CORE: "core", HYPERBOLIC: "hyperbolic", APPLICATION: "application"}

#: Every module of the package and its layer; a new module must be placed here.
LAYERS = {
    "nrobust.errors": BASE,
    "nrobust._validate": BASE,
    "nrobust._progress": BASE,
    "nrobust._json": BASE,
    "nrobust._journal": BASE,
    "nrobust._atomic": BASE,
    "nrobust._version": BASE,
    "nrobust._newton": BASE,
    "nrobust.parallel": BASE,
    "nrobust.difference": CORE,
    "nrobust.quasipoly": CORE,
    "nrobust.qpmatrix": CORE,
    "nrobust.matrix_difference": CORE,
    "nrobust.matrix_crossings": CORE,
    "nrobust.statespace": CORE,
    "nrobust.bounds": CORE,
    "nrobust.balls": CORE,
    "nrobust.roots": CORE,
    "nrobust.roots.winding": CORE,
    "nrobust.roots.finder": CORE,
    "nrobust.roots.abscissa": CORE,
    "nrobust.crossings": CORE,
    "nrobust.margins": CORE,
    "nrobust.proven_crossings": CORE,
    "nrobust.transfer": CORE,
    "nrobust.hyperbolic": HYPERBOLIC,
    "nrobust.hyperbolic.system": HYPERBOLIC,
    "nrobust.hyperbolic.kernels": HYPERBOLIC,
    "nrobust.hyperbolic.laplace": HYPERBOLIC,
    "nrobust.hyperbolic.delay_form": HYPERBOLIC,
    "nrobust.hyperbolic.controllers": HYPERBOLIC,
    "nrobust.hyperbolic.loops": HYPERBOLIC,
    "nrobust.hyperbolic.robustness": HYPERBOLIC,
    "nrobust.hyperbolic.studies": HYPERBOLIC,
    "nrobust.hyperbolic.simulate": HYPERBOLIC,
    "nrobust.hyperbolic.nplusm": HYPERBOLIC,
    "nrobust.hyperbolic.nplusm_kernels": HYPERBOLIC,
    "nrobust.hyperbolic.general": HYPERBOLIC,
    "nrobust.hyperbolic.feedback": HYPERBOLIC,
    "nrobust.hyperbolic.frontends": HYPERBOLIC,
    "nrobust.hyperbolic.varying": HYPERBOLIC,
    "nrobust.hyperbolic.varying_kernels": HYPERBOLIC,
    "nrobust.hyperbolic.simulate_general": HYPERBOLIC,
    "nrobust.montecarlo": APPLICATION,
    "nrobust.config": APPLICATION,
    "nrobust.sweepfile": APPLICATION,
    "nrobust.outputs": APPLICATION,
    "nrobust.sweep": APPLICATION,
    "nrobust.certificate": APPLICATION,
    "nrobust.report": APPLICATION,
    "nrobust.plots": APPLICATION,
    "nrobust.analyze": APPLICATION,
    "nrobust.nplusm_report": APPLICATION,
    "nrobust.paper": APPLICATION,
    "nrobust.cli": APPLICATION,
    "nrobust.__main__": APPLICATION,
    "nrobust": APPLICATION,
}

#: Function-level imports of nrobust modules that are deliberate, with the reason.
#: (module, function, imported module)
ALLOWED_LAZY = {
    # PEP 562 deprecated aliases of names that moved up to the plant layer: resolved on
    # attribute access only, so importing the core never loads the plants.
    ("nrobust.transfer", "__getattr__", "nrobust.hyperbolic.loops"),
    ("nrobust.transfer", "__getattr__", "nrobust.hyperbolic"),
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def resolve(module: str, is_package: bool, node: ast.ImportFrom) -> list[str]:
    """Absolute names of the modules an ``import from`` statement reaches."""
    if node.level:
        base = module.split(".") if is_package else module.split(".")[:-1]
        base = base[: len(base) - (node.level - 1)]
        target = ".".join(base + ([node.module] if node.module else []))
    else:
        target = node.module or ""
    names = [target]
    # ``from . import plots`` imports the submodule nrobust.plots
    names += [f"{target}.{alias.name}" for alias in node.names if f"{target}.{alias.name}" in LAYERS]
    return names


def imports_of(path: Path) -> list[tuple[str, str | None, int]]:
    """(imported module, enclosing function or None, line) for every nrobust import of a file."""
    module = module_name(path)
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found: list[tuple[str, str | None, int]] = []

    def visit(node: ast.AST, function: str | None) -> None:
        for child in ast.iter_child_nodes(node):
            inner = child.name if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) else function
            if isinstance(child, ast.Import):
                found.extend((a.name, function, child.lineno) for a in child.names if a.name.startswith("nrobust"))
            elif isinstance(child, ast.ImportFrom):
                targets = resolve(module, path.name == "__init__.py", child)
                found.extend((t, function, child.lineno) for t in targets if t.startswith("nrobust"))
            visit(child, inner)

    visit(tree, None)
    return found


def all_modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def owning_module(name: str) -> str:
    """The listed module an imported name belongs to (``nrobust.roots.finder.RootSet`` -> its module)."""
    while name not in LAYERS and "." in name:
        name = name.rsplit(".", 1)[0]
    return name


def forbidden_edges(layers: dict[str, int]) -> list[str]:
    errors = []
    for module, path in all_modules().items():
        for target, function, line in imports_of(path):
            target = owning_module(target)
            if target not in layers:
                errors.append(f"{module}:{line} imports {target}, which has no layer")
                continue
            if (module, function, target) in ALLOWED_LAZY:
                continue
            if layers[target] > layers[module]:
                errors.append(
                    f"{module}:{line} ({LAYER_NAMES[layers[module]]}) imports {target} "
                    f"({LAYER_NAMES[layers[target]]}): imports must run down the layers"
                )
            if function is not None:
                errors.append(f"{module}:{line} imports {target} inside {function}(): import at module level")
    return errors


def test_every_module_has_a_layer():
    missing = sorted(set(all_modules()) - set(LAYERS))
    assert not missing, f"place these modules in a layer (tests/test_layering.py, docs/architecture.md): {missing}"
    stale = sorted(set(LAYERS) - set(all_modules()))
    assert not stale, f"listed modules that no longer exist: {stale}"


def test_imports_run_down_the_layers():
    errors = forbidden_edges(LAYERS)
    assert not errors, "\n".join(errors)


def test_no_import_cycle_at_module_level():
    graph: dict[str, set[str]] = {}
    for module, path in all_modules().items():
        graph[module] = {
            owning_module(t) for t, function, _ in imports_of(path) if function is None and owning_module(t) != module
        }
        # a package's __init__ runs before its submodules: importing the package is implied
    state: dict[str, int] = {}
    stack: list[str] = []

    def dfs(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            # importing a submodule first runs its package's __init__; that edge is not a cycle
            if node.startswith(nxt + "."):
                continue
            if state.get(nxt) == 1:
                cycle = [*stack[stack.index(nxt) :], nxt]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if state.get(nxt) is None:
                dfs(nxt)
        stack.pop()
        state[node] = 2

    for module in sorted(graph):
        if state.get(module) is None:
            dfs(module)


def test_no_lookup_of_code_by_name():
    offenders = [
        f"{module}: {needle}"
        for module, path in all_modules().items()
        for needle in ("importlib.import_module", "__import__(")
        if needle in path.read_text(encoding="utf-8")
    ]
    assert not offenders, offenders


def test_the_rule_bites_on_a_forbidden_edge(tmp_path, monkeypatch):
    """A core module importing the plants is reported (the check is not vacuous)."""
    fake = tmp_path / "nrobust"
    (fake / "hyperbolic").mkdir(parents=True)
    (fake / "__init__.py").write_text("")
    (fake / "hyperbolic" / "__init__.py").write_text("")
    (fake / "margins.py").write_text("from .hyperbolic import controllers\n\n\ndef f():\n    from . import plots\n")
    monkeypatch.setattr(__import__(__name__), "PACKAGE", fake)
    errors = forbidden_edges(LAYERS)
    assert any("nrobust.margins:1 (core) imports nrobust.hyperbolic" in e for e in errors), errors
    assert any("inside f()" in e for e in errors), errors
