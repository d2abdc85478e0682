"""The layers of nrobust, read from the source: every import runs one way.

``docs/architecture.md`` states the rules, and this test reads them off the imports of every
module (``ast``: module-level and function-level alike, and the ``.pyi`` stubs from which the
lazy packages load their names):

- a module sits in the layer its path gives (:func:`layer_of`): the base, the core (no PDE, no
  files, no processes, no figures), the runtime (the executors that start processes), the PDE
  layer ``nrobust/hyperbolic/`` and the application (sweeps, reports, plots, config, cli);
  imports run down the layers, and no module imports itself back through a cycle;
- the core imports nothing, directly or not, that writes files, starts processes or draws;
- no module imports a private name of another module (a package shares helpers through
  public names, in one ``_common`` module at most);
- no function imports nrobust (the way cycles are dodged) and no module looks code up by name;
- ``import nrobust`` and ``import nrobust.quasipoly`` load the core they need and nothing else:
  neither the PDE layer, the application nor matplotlib.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "nrobust"

#: Rank of each layer: a module may import modules of its own rank or below.
BASE, CORE, RUNTIME, HYPERBOLIC, APPLICATION = 0, 1, 2, 3, 4
LAYER_NAMES = {BASE: "base", CORE: "core", RUNTIME: "runtime", HYPERBOLIC: "hyperbolic", APPLICATION: "application"}

#: The base: errors, argument checks, JSON, Newton, progress bars, atomic writes, moved paths,
#: python-flint access (loading, precision, Krawczyk's test).
BASE_MODULES = {
    "nrobust._digits",
    "nrobust.errors",
    "nrobust._validate",
    "nrobust._progress",
    "nrobust._json",
    "nrobust._atomic",
    "nrobust._version",
    "nrobust._newton",
    "nrobust._bracket",
    "nrobust._moved",
    "nrobust._flint",
    "nrobust._threads",
}
#: The core, by package or module: representations, proofs, roots, margins, delay systems, design.
CORE_PREFIXES = (
    "nrobust.quasipoly",
    "nrobust.distributed_delay",
    "nrobust.volterra",
    "nrobust.difference",
    "nrobust.qpmatrix",
    "nrobust.matrix_difference",
    "nrobust.bounds",
    "nrobust.balls",
    "nrobust.roots",
    "nrobust.margins",
    "nrobust.lti",
    "nrobust.design",
)
#: The executors (process pools, Dask) that the analyses of the PDE layer run their grids on.
RUNTIME_MODULES = {"nrobust.sweeps.executors"}
APPLICATION_PREFIXES = ("nrobust.sweeps", "nrobust.reports", "nrobust.plots", "nrobust.config", "nrobust.cli")

#: What the core may not reach, directly or through other modules: files, processes, figures.
SIDE_EFFECTS = (
    "nrobust._atomic",
    "nrobust.sweeps",
    "nrobust.reports",
    "nrobust.plots",
    "multiprocessing",
    "subprocess",
    "concurrent.futures",
    "tempfile",
    "shutil",
    "dask",
    "distributed",
    "matplotlib",
    "tqdm",
)

#: Modules that may look code up by name, with the reason.
LOOKUP_BY_NAME = {
    # the deprecated aliases of moved module paths resolve their new home on attribute access
    "nrobust._moved",
}

#: Function-level imports of nrobust modules that are deliberate, with the reason.
#: (module, function, imported module)
ALLOWED_LAZY: set[tuple[str, str, str]] = set()


def _matches(module: str, prefixes: tuple[str, ...] | set[str]) -> bool:
    return any(module == p or module.startswith(p + ".") for p in prefixes)


def layer_of(module: str) -> int | None:
    """The layer of a module of nrobust, from its path (None: not placed)."""
    if module in BASE_MODULES:
        return BASE
    if module in RUNTIME_MODULES:
        return RUNTIME
    if _matches(module, CORE_PREFIXES):
        return CORE
    if _matches(module, ("nrobust.hyperbolic",)):
        return HYPERBOLIC
    if _matches(module, APPLICATION_PREFIXES) or module in ("nrobust", "nrobust.__main__"):
        return APPLICATION
    return None


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def all_modules() -> dict[str, list[Path]]:
    """Every module of the package with its source files (``__init__.py`` and its ``.pyi`` stub)."""
    found: dict[str, list[Path]] = {}
    for p in sorted([*PACKAGE.rglob("*.py"), *PACKAGE.rglob("*.pyi")]):
        found.setdefault(module_name(p), []).append(p)
    return found


def resolve(module: str, is_package: bool, node: ast.ImportFrom, known: set[str]) -> list[str]:
    """Absolute names of the modules an ``import from`` statement reaches."""
    if node.level:
        base = module.split(".") if is_package else module.split(".")[:-1]
        base = base[: len(base) - (node.level - 1)]
        target = ".".join(base + ([node.module] if node.module else []))
    else:
        target = node.module or ""
    names = [target]
    # ``from . import plots`` imports the submodule nrobust.plots; ``from concurrent import
    # futures`` the module concurrent.futures (outside nrobust every name may be a module)
    names += [
        f"{target}.{alias.name}"
        for alias in node.names
        if f"{target}.{alias.name}" in known or not target.startswith("nrobust")
    ]
    return names


class Import:
    """One import statement's edge: the module reached, the names taken, where it stands."""

    def __init__(self, target: str, names: list[str], function: str | None, line: int, path: Path) -> None:
        self.target, self.names, self.function, self.line, self.path = target, names, function, line, path


def imports_of(module: str, paths: list[Path], known: set[str]) -> list[Import]:
    """Every import of a module (nrobust and other packages alike)."""
    found: list[Import] = []
    for path in paths:
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        is_package = path.stem == "__init__"

        def visit(node: ast.AST, function: str | None, path: Path = path, is_package: bool = is_package) -> None:
            for child in ast.iter_child_nodes(node):
                inner = child.name if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) else function
                if isinstance(child, ast.Import):
                    found.extend(Import(a.name, [], function, child.lineno, path) for a in child.names)
                elif isinstance(child, ast.ImportFrom):
                    targets = resolve(module, is_package, child, known)
                    names = [a.name for a in child.names]
                    found.extend(
                        Import(t, names if i == 0 else [], function, child.lineno, path) for i, t in enumerate(targets)
                    )
                visit(child, inner)

        visit(tree, None)
    return found


def owning_module(name: str, known: set[str]) -> str:
    """The module of nrobust an imported name belongs to (``nrobust.roots.finder.RootSet`` -> its module)."""
    while name not in known and "." in name:
        name = name.rsplit(".", 1)[0]
    return name


def module_graph() -> tuple[dict[str, list[Path]], dict[str, list[Import]]]:
    modules = all_modules()
    known = set(modules)
    return modules, {m: imports_of(m, paths, known) for m, paths in modules.items()}


def forbidden_edges() -> list[str]:
    modules, graph = module_graph()
    known = set(modules)
    errors = []
    for module, edges in graph.items():
        rank = layer_of(module)
        if rank is None:
            errors.append(f"{module} has no layer: place it in tests/test_layering.py and docs/architecture.md")
            continue
        for edge in edges:
            if not edge.target.startswith("nrobust"):
                continue
            target = owning_module(edge.target, known)
            if (module, edge.function, target) in ALLOWED_LAZY:
                continue
            target_rank = layer_of(target)
            if target_rank is None:
                continue  # reported on its own line
            if target_rank > rank:
                errors.append(
                    f"{module}:{edge.line} ({LAYER_NAMES[rank]}) imports {target} "
                    f"({LAYER_NAMES[target_rank]}): imports must run down the layers"
                )
            if edge.function is not None:
                errors.append(f"{module}:{edge.line} imports {target} inside {edge.function}(): import at module level")
            errors += _package_inits_run(module, rank, target, edge.line, graph)
    return errors


def _package_inits_run(module: str, rank: int, target: str, line: int, graph: dict[str, list[Import]]) -> list[str]:
    """Importing ``a.b.c`` first runs ``a/b/__init__.py``: a package of a higher layer may be
    passed through only if its ``__init__.py`` imports nothing of nrobust when it runs (lazy)."""
    errors = []
    parts = target.split(".")
    for i in range(2, len(parts)):
        package = ".".join(parts[:i])
        package_rank = layer_of(package)
        if package_rank is None or package_rank <= rank or module.startswith(package + "."):
            continue
        runs = [
            e.target
            for e in graph.get(package, [])
            if e.path.suffix == ".py" and e.function is None and e.target.startswith("nrobust")
        ]
        if runs:
            errors.append(
                f"{module}:{line} imports {target}, which first runs {package}/__init__.py "
                f"({LAYER_NAMES[package_rank]}), and it imports {', '.join(sorted(set(runs)))}"
            )
    return errors


def test_every_module_has_a_layer() -> None:
    missing = sorted(m for m in all_modules() if layer_of(m) is None)
    assert not missing, f"place these modules in a layer (tests/test_layering.py, docs/architecture.md): {missing}"


def test_imports_run_down_the_layers() -> None:
    errors = forbidden_edges()
    assert not errors, "\n".join(errors)


def test_no_import_cycle_at_module_level() -> None:
    modules, graph = module_graph()
    known = set(modules)
    edges = {
        module: {
            owning_module(e.target, known)
            for e in imports
            if e.function is None and e.target.startswith("nrobust") and e.path.suffix == ".py"
        }
        - {module}
        for module, imports in graph.items()
    }
    state: dict[str, int] = {}
    stack: list[str] = []

    def dfs(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(edges.get(node, ())):
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

    for module in sorted(edges):
        if state.get(module) is None:
            dfs(module)


def reach(module: str, graph: dict[str, list[Import]], known: set[str]) -> dict[str, list[str]]:
    """Every module a module imports, directly or not, at module level or inside a function
    (a lazy import still runs), with one path to it."""
    paths: dict[str, list[str]] = {module: [module]}
    todo = [module]
    while todo:
        here = todo.pop()
        for edge in graph.get(here, []):
            target = owning_module(edge.target, known) if edge.target.startswith("nrobust") else edge.target
            if target not in paths:
                paths[target] = [*paths[here], target]
                if target in graph:
                    todo.append(target)
    return paths


def side_effects_of_the_core() -> list[str]:
    modules, graph = module_graph()
    known = set(modules)
    errors = []
    for module in sorted(modules):
        if layer_of(module) != CORE:
            continue
        for target, path in reach(module, graph, known).items():
            if _matches(target, SIDE_EFFECTS):
                errors.append(f"{module} reaches {target}: {' -> '.join(path)}")
    return errors


#: Calls that write files: ``open`` in a writing mode, pathlib's writers, ``os``'s file operations.
WRITERS = ("write_text", "write_bytes", "mkdir", "unlink", "touch")
OS_WRITERS = ("replace", "remove", "rename", "makedirs", "mkdir", "unlink", "rmdir")


def writes_of_the_core() -> list[str]:
    """Calls in core modules that write, create or remove files."""
    errors = []
    for module, paths in all_modules().items():
        if layer_of(module) != CORE:
            continue
        for path in paths:
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if not isinstance(node, ast.Call):
                    continue
                func = node.func
                if isinstance(func, ast.Name) and func.id == "open":
                    mode = (
                        node.args[1]
                        if len(node.args) > 1
                        else next((k.value for k in node.keywords if k.arg == "mode"), None)
                    )
                    text = mode.value if isinstance(mode, ast.Constant) and isinstance(mode.value, str) else "?"
                    if text == "?" or set(text) & set("wax+"):
                        errors.append(f"{module}:{node.lineno} open(..., {text!r})")
                elif (
                    isinstance(func, ast.Attribute)
                    and func.attr in WRITERS
                    and not (isinstance(func.value, ast.Name) and func.value.id in ("self", "str", "dataclasses"))
                ):
                    errors.append(f"{module}:{node.lineno} .{func.attr}(...)")
    return errors


def test_core_writes_no_file() -> None:
    errors = writes_of_the_core()
    assert not errors, "the core may not write files:\n" + "\n".join(errors)


def test_core_reaches_no_files_processes_or_figures() -> None:
    errors = side_effects_of_the_core()
    assert not errors, "the core may not write files, start processes or draw:\n" + "\n".join(errors)


def private_imports() -> list[str]:
    _, graph = module_graph()
    errors = []
    for module, edges in graph.items():
        for edge in edges:
            if not edge.target.startswith("nrobust") or edge.target == module:
                continue
            private = [n for n in edge.names if n.startswith("_") and not n.startswith("__")]
            if private:
                errors.append(f"{module}:{edge.line} takes {', '.join(private)} from {edge.target}")
            # a private module (``roots/_common.py``) serves its own package only
            parts = edge.target.split(".")
            for i, part in enumerate(parts[1:], start=1):
                package = ".".join(parts[:i])
                if part.startswith("_") and not part.startswith("__") and not module.startswith(package + "."):
                    if module != package:
                        errors.append(f"{module}:{edge.line} imports {edge.target}, private to {package}")
    return errors


def test_no_private_name_crosses_a_module() -> None:
    errors = private_imports()
    assert not errors, "make shared helpers public (one _common module per package at most):\n" + "\n".join(errors)


#: Private attributes of the standard library's own API (``NamedTuple._asdict``, ``os._exit``).
STDLIB_PRIVATE = {"_asdict", "_replace", "_fields", "_make", "_exit"}


def private_attributes() -> list[str]:
    """``obj._name`` on another object than ``self``/``cls``, where no class of this module defines ``_name``."""
    errors = []
    for module, paths in all_modules().items():
        for path in paths:
            tree = ast.parse(path.read_text(encoding="utf-8"))
            own = {n.name for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
            own |= {
                t.attr
                for n in ast.walk(tree)
                for t in (
                    n.targets if isinstance(n, ast.Assign) else [n.target] if isinstance(n, ast.AnnAssign) else []
                )
                if isinstance(t, ast.Attribute)
            }
            own |= {
                n.target.id for n in ast.walk(tree) if isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name)
            }
            for n in ast.walk(tree):
                if not (isinstance(n, ast.Attribute) and n.attr.startswith("_") and not n.attr.startswith("__")):
                    continue
                if isinstance(n.value, ast.Name) and n.value.id in ("self", "cls"):
                    continue
                if n.attr not in own and n.attr not in STDLIB_PRIVATE:
                    errors.append(f"{module}:{n.lineno} {ast.unparse(n)}")
    return errors


def test_no_private_attribute_crosses_a_module() -> None:
    errors = private_attributes()
    assert not errors, "a private attribute is its module's own: make it public or ask its owner:\n" + "\n".join(errors)


def test_at_most_one_common_module_per_package() -> None:
    commons = [m for m in all_modules() if m.rsplit(".", 1)[-1].startswith("_common")]
    packages = [m.rsplit(".", 1)[0] for m in commons]
    assert len(packages) == len(set(packages)), commons


def test_no_lookup_of_code_by_name() -> None:
    offenders = [
        f"{module}: {needle}"
        for module, paths in all_modules().items()
        if module not in LOOKUP_BY_NAME
        for path in paths
        for needle in ("import_module", "__import__(")
        if needle in path.read_text(encoding="utf-8")
    ]
    assert not offenders, offenders


def _loaded_by(statement: str) -> list[str]:
    code = f"import sys; {statement}; print(' '.join(sorted(sys.modules)))"
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    return run.stdout.split()


@pytest.mark.parametrize("statement", ["import nrobust", "import nrobust.quasipoly", "import nrobust.roots"])
def test_importing_the_core_loads_the_core_only(statement: str) -> None:
    """The loaded set stands for the import time, which ``benchmarks/imports.py`` measures."""
    loaded = _loaded_by(statement)
    ours = [m for m in loaded if m.startswith("nrobust")]
    wrong = [m for m in ours if layer_of(m) not in (BASE, CORE) and m != "nrobust"]
    assert not wrong, f"{statement} loads {wrong}"
    heavy = [
        m for m in loaded if _matches(m, ("matplotlib", "control", "mpmath", "flint", "dask", "tqdm", "threadpoolctl"))
    ]
    assert not heavy, f"{statement} loads {heavy}"
    if statement == "import nrobust":
        assert ours == ["nrobust", "nrobust._moved", "nrobust._version"], ours


def test_the_rules_bite(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A core module importing the plants, a private name or a process pool is reported."""
    fake = tmp_path / "nrobust"
    (fake / "hyperbolic").mkdir(parents=True)
    (fake / "__init__.py").write_text("")
    (fake / "hyperbolic" / "__init__.py").write_text("")
    (fake / "hyperbolic" / "kernels.py").write_text("")
    (fake / "sweeps").mkdir()
    (fake / "sweeps" / "__init__.py").write_text("import multiprocessing\n")
    (fake / "roots").mkdir()
    (fake / "roots" / "__init__.py").write_text("")
    (fake / "roots" / "_common.py").write_text("")
    (fake / "margins.py").write_text(
        "from .hyperbolic.kernels import _march\nfrom . import sweeps\nfrom .roots._common import x\n"
        "from concurrent import futures\n\n\ndef f(d):\n    from . import plots\n"
        "    open('a', 'w')\n    return d._pieces\n"
    )
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", fake)
    errors = forbidden_edges()
    assert any("nrobust.margins:1 (core) imports nrobust.hyperbolic.kernels" in e for e in errors), errors
    assert any("inside f()" in e for e in errors), errors
    assert any("takes _march from nrobust.hyperbolic.kernels" in e for e in private_imports())
    assert any("nrobust.margins reaches multiprocessing" in e for e in side_effects_of_the_core())
    assert any("nrobust.margins reaches concurrent.futures" in e for e in side_effects_of_the_core())
    assert any("private to nrobust.roots" in e for e in private_imports())
    assert any("open(..., 'w')" in e for e in writes_of_the_core())
    assert any("d._pieces" in e for e in private_attributes())
