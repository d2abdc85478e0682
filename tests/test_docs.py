"""The documentation stays true: cross-references resolve and the examples run.

* Every Sphinx-style reference (``:func:``, ``:class:``, ``:meth:``, ``:mod:``,
  ``:data:``) in a docstring of an nrobust module names an object that exists and is of
  that kind.
* Every dotted ``nrobust.xxx`` name in backticks in ``README.md`` and ``docs/*.md``
  resolves (except a former home, written ``was `nrobust.old```), and every file path
  in backticks (``nrobust/...``, ``tests/...``, ...) exists.
* The SYSTEM.toml of ``docs/getting_started.md`` (its ```toml block with a ``[design]`` table) runs
  verbatim under ``nrobust design``, and the error it documents is the one printed.
* Every ```python block of ``docs/*.md`` runs: the blocks of one page run in order as
  one script (later blocks use the names of earlier ones), in a temporary directory,
  with matplotlib's Agg backend and warnings as errors. A block whose first line is
  ``# not run: <reason>`` is skipped (a cluster address, names defined elsewhere).
"""

from __future__ import annotations

import ast
import builtins
import importlib
import inspect
import os
import pkgutil
import re
import subprocess
import sys
import warnings
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

import nrobust

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted((ROOT / "docs").glob("*.md"))
PAGES = [ROOT / "README.md", *DOCS]
NOT_RUN = "# not run:"

_ROLE = re.compile(r":(func|class|meth|mod|data):`([^`]+)`")
_FENCE = re.compile(r"^```([\w-]*)\n(.*?)^```", re.S | re.M)
# an inline code span, unless it names a former home: "(was `nrobust.rouche`)"
_INLINE = re.compile(r"(\bwas )?`([^`\n]+)`")
_DOTTED = re.compile(r"(?<![\w.])nrobust(?:\.[A-Za-z_]\w*)+")
_MISSING = object()
_PATH = re.compile(r"(?<![\w./])((?:nrobust|tests|examples|benchmarks|docs)/[\w./-]*\w)")


def _modules() -> list[ModuleType]:
    """nrobust and every module under it (``__main__`` would run the command line)."""
    names = [m.name for m in pkgutil.walk_packages(nrobust.__path__, "nrobust.") if not m.name.endswith("__main__")]
    return [nrobust, *(importlib.import_module(name) for name in sorted(names))]


def _docstrings(module: ModuleType) -> Iterator[tuple[list[str], str, int]]:
    """``(enclosing class names, docstring, line)`` of the module and of every class and function in it."""
    tree = ast.parse(inspect.getsource(module))

    def walk(node: ast.AST, scope: list[str]) -> Iterator[tuple[list[str], str, int]]:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
                inner = [*scope, child.name] if isinstance(child, ast.ClassDef) else scope
                doc = ast.get_docstring(child, clean=False)
                if doc:
                    yield inner, doc, child.lineno
                yield from walk(child, inner)

    doc = ast.get_docstring(tree, clean=False)
    if doc:
        yield [], doc, 1
    yield from walk(tree, [])


def _getattr(obj: Any, attr: str) -> Any:
    """``getattr`` that treats a deprecated alias (a ``DeprecationWarning``) as missing."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        try:
            return getattr(obj, attr, _MISSING)
        except DeprecationWarning:
            return _MISSING


def _candidates(name: str) -> Iterator[Any]:
    """Objects a dotted name can denote: ``import a.b`` then ``getattr`` the rest, for every split."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            with warnings.catch_warnings():  # a deprecated alias of a moved module is not a home
                warnings.simplefilter("error", DeprecationWarning)
                obj: Any = importlib.import_module(".".join(parts[:i]))
        except (ImportError, DeprecationWarning):
            continue
        for attr in parts[i:]:
            obj = _getattr(obj, attr)
            if obj is _MISSING:
                break
        if obj is not _MISSING:
            yield obj


def _kind_ok(role: str, obj: Any) -> bool:
    """``obj`` is what the role says: a module, a class, a callable (or property), anything for data."""
    if role == "mod":
        return inspect.ismodule(obj)
    if role == "class":
        return inspect.isclass(obj)
    if role in ("func", "meth"):
        return (callable(obj) and not inspect.ismodule(obj)) or isinstance(obj, property)
    return not inspect.ismodule(obj)


def _resolve(role: str, target: str, module: ModuleType, scope: list[str]) -> bool:
    """A reference as Sphinx would read it: absolute, or relative to the enclosing classes and module."""
    target = target.lstrip("~").removesuffix("()")
    if target.startswith("."):  # Sphinx: a suffix of a name, searched from the current module's package
        target = f"{module.__name__.rpartition('.')[0]}{target}"
    found = list(_candidates(target))
    # relative names: inside the enclosing classes (innermost first), the module, the builtins
    bases: list[Any] = []
    for depth in range(len(scope), 0, -1):
        obj: Any = module
        for cls in scope[:depth]:
            obj = getattr(obj, cls)
        bases.append(obj)
    bases += [module, builtins]
    for base in bases:
        obj = base
        for attr in target.split("."):
            obj = _getattr(obj, attr)
            if obj is _MISSING:
                break
        if obj is not _MISSING:
            found.append(obj)
    return any(_kind_ok(role, obj) for obj in found)


def _references() -> list[tuple[str, str, str, ModuleType, list[str]]]:
    refs = []
    for module in _modules():
        path = Path(inspect.getfile(module)).relative_to(ROOT)
        for scope, doc, line in _docstrings(module):
            for m in _ROLE.finditer(doc):
                where = f"{path}:{line + doc[: m.start()].count(chr(10))}"
                refs.append((where, m.group(1), m.group(2), module, scope))
    return refs


def test_docstring_references_resolve():
    refs = _references()
    assert len(refs) > 100  # the collector sees the package
    broken = [f"{where}: :{role}:`{target}`" for where, role, target, module, scope in refs]
    broken = [b for b, ref in zip(broken, refs) if not _resolve(ref[1], ref[2], ref[3], ref[4])]
    assert not broken, "unresolvable references in docstrings:\n" + "\n".join(broken)


def _spans(text: str) -> list[str]:
    """Fenced blocks and inline code spans of a markdown page."""
    fences = [m.group(2) for m in _FENCE.finditer(text)]
    prose = _FENCE.sub("", text)
    return fences + [code for former, code in _INLINE.findall(prose) if not former]


def test_markdown_names_resolve():
    broken = []
    seen = 0
    for page in PAGES:
        for span in _spans(page.read_text()):
            for name in _DOTTED.findall(span):
                seen += 1
                if not any(True for _ in _candidates(name)):
                    broken.append(f"{page.relative_to(ROOT)}: {name}")
    assert seen > 30
    assert not broken, "unresolvable nrobust names in the docs:\n" + "\n".join(sorted(set(broken)))


# Written by `make docs`, not kept in the repository (.gitignore).
BUILD_OUTPUT = ("docs/_build",)


def test_markdown_paths_exist():
    missing = []
    for page in PAGES:
        for span in _spans(page.read_text()):
            for path in _PATH.findall(span):
                if path.startswith(BUILD_OUTPUT):
                    continue
                if not (ROOT / path.split("::")[0]).exists():
                    missing.append(f"{page.relative_to(ROOT)}: {path}")
    assert not missing, "files named in the docs that do not exist:\n" + "\n".join(sorted(set(missing)))


def test_broken_references_are_reported():
    """The resolver rejects what it must (a stale module, a private rename, the wrong kind)."""
    from nrobust import margins

    assert _resolve("func", "nrobust.margins.margin.delay_margin", margins, [])
    assert _resolve("func", "~nrobust.hyperbolic.loop_factors", margins, [])
    assert _resolve("meth", "to_dict", margins, ["DelayMargin"])
    assert _resolve("class", "ValueError", margins, [])
    assert not _resolve("func", "nrobust.rouche.rouche_delay_bound", margins, [])
    assert not _resolve("func", "nrobust.margins.margin.k_region", margins, [])
    assert not _resolve("func", "k_region", margins, [])
    assert not _resolve("func", "nrobust.hyperbolic.simulate.normal_form", margins, [])  # the module, not the function
    assert not _resolve("mod", "nrobust.delay_margin", margins, [])
    assert not any(True for _ in _candidates("nrobust.sweeps._nrobust_function"))
    assert not any(True for _ in _candidates("nrobust.transfer.open_loop_tf"))  # deprecated alias
    assert any(True for _ in _candidates("nrobust.sweeps.run_sweep_file"))


def _python_blocks(page: Path) -> list[str]:
    return [m.group(2) for m in _FENCE.finditer(page.read_text()) if m.group(1) == "python"]


def test_not_run_marker_is_recognised():
    blocks = _python_blocks(ROOT / "docs" / "sweeps.md")
    assert any(b.startswith(NOT_RUN) for b in blocks)
    assert any(not b.startswith(NOT_RUN) for b in blocks)


@pytest.mark.slow
@pytest.mark.parametrize("page", [p for p in DOCS if _python_blocks(p)], ids=lambda p: p.name)
def test_docs_python_blocks_run(page: Path, tmp_path: Path):
    blocks = [b for b in _python_blocks(page) if not b.startswith(NOT_RUN)]
    script = tmp_path / f"{page.stem}.py"
    script.write_text("\n".join(blocks))
    env = {**os.environ, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    proc = subprocess.run(
        [sys.executable, "-W", "error", str(script)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=280
    )
    assert proc.returncode == 0, f"{page.name}: a python block fails\n{proc.stderr[-3000:]}"


def _stated(block: str, expression: str) -> list[str]:
    """The numbers written in the comment of the line of ``block`` that starts with ``expression``."""
    (line,) = [ln for ln in block.splitlines() if ln.startswith(expression)]
    return re.findall(r"\d+\.\d+", line.split("#", 1)[1])


def _truncation_of(value: float, stated: str) -> bool:
    """``stated`` (``0.2295391304``, written ``0.2295391304...``) is ``value`` cut after its digits."""
    digits = len(stated.split(".")[1])
    return float(stated) <= value < float(stated) + 10.0**-digits


@pytest.mark.slow
def test_margins_page_numbers_hold():
    """The margin, crossing frequency and windows written next to the example of docs/margins.md."""
    (block, *_) = _python_blocks(ROOT / "docs" / "margins.md")
    scope: dict[str, Any] = {}
    exec(compile(block, "docs/margins.md", "exec"), scope)
    dm = scope["dm"]
    margin, omega = _stated(block, "dm.margin, dm.omega")
    assert _truncation_of(dm.margin, margin) and len(margin) >= 12
    assert _truncation_of(dm.omega, omega)
    windows = _stated(block, "dm.intervals")
    assert [_truncation_of(x, s) for x, s in zip(np.ravel(dm.intervals)[1:], windows[1:])] == [True] * 3
    (d0,) = _stated(block, "nr.rouche_delay_bound")
    np.testing.assert_allclose(
        scope["nr"].rouche_delay_bound(scope["plant"], scope["nr"].ReflectionController(0.1)).delta_0,
        float(d0),
        rtol=0,
        atol=5e-6,
    )


# a LaTeX label of the paper cited as an equation: "eq. (" + "control3)", "(" + "boun_K2)"...
_LATEX_LABEL = re.compile(
    r"\beqs?\. \([A-Za-z][\w^{}]*\)|\((?:boun_K2|control3|eq_rho_q|delay_eq_alpha\w*|eq_N_tilde|u_pde)\)"
)


def test_equations_are_cited_by_their_published_numbers():
    """The reader of the published paper finds (53), not the LaTeX label of its source."""
    sources = [
        ROOT / "README.md",
        *DOCS,
        *sorted((ROOT / "nrobust").rglob("*.py")),
        *sorted((ROOT / "examples").glob("*.py")),
    ]
    found = [
        f"{path.relative_to(ROOT)}: {m.group(0)}"
        for path in sources
        for m in _LATEX_LABEL.finditer(path.read_text(encoding="utf-8"))
    ]
    assert not found, "equations cited by LaTeX label:\n" + "\n".join(found)


def test_examples_open_with_a_gallery_title():
    """sphinx-gallery (``make docs``) titles each example by the first line of its docstring,
    underlined with ``=``; the README of the gallery exists."""
    assert (ROOT / "examples" / "README.rst").exists()
    untitled = []
    for path in sorted((ROOT / "examples").glob("*.py")):
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")), clean=False) or ""
        lines = doc.splitlines()
        if len(lines) < 2 or not lines[0].strip() or lines[1] != "=" * len(lines[0]):
            untitled.append(path.name)
    assert not untitled, "examples without a title line underlined with '=': " + ", ".join(untitled)


def test_no_equation_number_inside_an_aligned_block():
    """MathJax refuses ``\\tag`` inside ``aligned`` ("\\tag not allowed in aligned environment"): a
    page would show that error instead of its equations. Numbered systems use ``align*``."""
    bad = []
    for page in sorted((ROOT / "docs").glob("*.md")):
        for block in re.findall(r"\\begin\{aligned\}(.*?)\\end\{aligned\}", page.read_text(), flags=re.S):
            if "\\tag" in block:
                bad.append(page.name)
    assert not bad, bad


def _getting_started_system() -> str:
    """The SYSTEM.toml block of docs/getting_started.md (the 2x2 plant's, with every section)."""
    text = (ROOT / "docs" / "getting_started.md").read_text()
    blocks = [m.group(2) for m in _FENCE.finditer(text) if m.group(1) == "toml"]
    (block,) = [b for b in blocks if 'type = "Hyperbolic2x2"' in b and "[design]" in b]
    return block


def test_getting_started_system_file_designs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``nrobust design`` on the schema's example as printed (the python blocks ran; this one did not, and its
    [design] table once gave both ``delays`` and ``margin_at_least``, and a margin its plant cannot reach).

    Oracle of the designed gain: U_BS2(K)'s decay rate at ``delta = 0`` is ``-ln|(rho - K) q| / tau`` (Lemma 3,
    ``tau = 1/lam + 1/mu = 2``), whatever the couplings; 1e-9 bounds the design's bracket (about 1e-11).
    The error the page quotes for ``margin_at_least = 0.2`` is the one printed."""
    import json

    from nrobust.cli import main

    block = _getting_started_system()
    path = tmp_path / "SYSTEM.toml"
    path.write_text(block)
    assert main(["design", str(path), "-o", str(tmp_path / "out")]) == 0, capsys.readouterr().err
    data = json.loads((tmp_path / "out" / "design.json").read_text())
    required = float(re.search(r"^margin_at_least = ([\d.]+)", block, re.M).group(1))
    assert data["margin_at_least"] == required and data["design"]["margin"] >= required
    K = data["design"]["K"]
    assert abs(data["design"]["decay_rate"] + np.log(abs((0.85 - K) * 1.0)) / 2.0) < 1e-9
    assert (tmp_path / "out" / "design.png").stat().st_size > 0

    quoted = re.search(
        r"`(nrobust: error: margin_at_least must be at most [^`]*\(got 0\.2\))`",
        (ROOT / "docs" / "getting_started.md").read_text(),
    )
    assert quoted is not None
    path.write_text(re.sub(r"^margin_at_least = [\d.]+", "margin_at_least = 0.2", block, flags=re.M))
    capsys.readouterr()
    assert main(["design", str(path), "-o", str(tmp_path / "refused")]) == 2
    assert " ".join(capsys.readouterr().err.split()) == " ".join(quoted.group(1).split())
