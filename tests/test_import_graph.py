"""The import graph of the vibrospeed package: no cycles, and every import goes to the module's
own layer or a lower one.

The graph is read from the source (``ast`` of every ``src/vibrospeed/**.py``), with the imports
inside functions (deferred imports still make a cycle of meaning, and an upward import is an
upward dependency wherever it sits); imports under ``if TYPE_CHECKING:`` are left out (they
exist for annotations only and never run). An edge goes to the module named: ``from a.b import
c`` is an edge to ``a.b.c`` when that is a module of the package, else to ``a.b``; the parent
packages Python imports on the way are not edges (a package's ``__init__`` may re-export its
submodules).

The layer rule (also in the docstring of :mod:`vibrospeed`), lowest first::

    0  vibrospeed (the package root), vibrospeed.types, .errors, .config, .presets
    1  vibrospeed.models, .signal, .io
    2  vibrospeed.sim, .estimators
    3  vibrospeed.eval
    4  vibrospeed.batch
    5  vibrospeed.cli, vibrospeed.__main__

A module may import from its own layer or a lower one, never from a higher one.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
PKG = SRC / "vibrospeed"

#: top-level part of a module name (after ``vibrospeed.``) -> layer; "" is the package root
LAYERS = {
    "": 0, "types": 0, "errors": 0, "config": 0, "presets": 0,
    "models": 1, "signal": 1, "io": 1,
    "sim": 2, "estimators": 2,
    "eval": 3,
    "batch": 4,
    "cli": 5, "__main__": 5,
}


def _modules() -> dict[str, Path]:
    out = {}
    for p in sorted(PKG.rglob("*.py")):
        parts = list(p.relative_to(SRC).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


MODULES = _modules()


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _imports(name: str, path: Path) -> set[str]:
    """Package modules imported by module ``name`` (its file ``path``)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    is_pkg = path.name == "__init__.py"
    found: set[str] = set()

    def target(mod: str, names: list[str]) -> None:
        for n in names:
            full = f"{mod}.{n}"
            if full in MODULES:
                found.add(full)
            elif mod in MODULES:
                found.add(mod)

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name in MODULES:
                    found.add(a.name)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_pkg else name.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.split(".")[0] == "vibrospeed":
                target(mod, [a.name for a in node.names])
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    found.discard(name)
    return found


GRAPH = {name: _imports(name, path) for name, path in MODULES.items()}


def _layer(module: str) -> int:
    parts = module.split(".")
    top = parts[1] if len(parts) > 1 else ""
    if top not in LAYERS:
        raise AssertionError(f"module {module} has no layer: add its top-level name to LAYERS "
                             "here and to the rule in vibrospeed/__init__.py")
    return LAYERS[top]


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def strong(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            strong(v)
    return out


def test_graph_is_read():
    # the reader finds the package's known edges (a broken reader would pass the tests below)
    assert len(MODULES) > 50
    assert "vibrospeed.estimators.grid.filter" in GRAPH["vibrospeed.estimators.rbpmf"]
    assert "vibrospeed.types" in GRAPH["vibrospeed.estimators.ekf"]
    # a function-level import
    assert "vibrospeed.signal.standstill" in GRAPH["vibrospeed.estimators.grid.method"]


def test_cycle_finder_finds_a_cycle():
    g = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycles(g) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_relative_and_type_checking_imports(tmp_path):
    src = ("from typing import TYPE_CHECKING\n"
           "from . import filter\n"
           "from .config import Config\n"
           "if TYPE_CHECKING:\n"
           "    from vibrospeed.eval import metrics\n"
           "def f():\n"
           "    from vibrospeed.signal import prefilter\n")
    p = tmp_path / "x.py"
    p.write_text(src)
    got = _imports("vibrospeed.estimators.grid.x", p)
    assert got == {"vibrospeed.estimators.grid.filter", "vibrospeed.estimators.grid.config",
                   "vibrospeed.signal.prefilter"}


def test_no_import_cycles():
    cycles = _cycles(GRAPH)
    assert not cycles, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in cycles)


@pytest.mark.parametrize("module", sorted(MODULES))
def test_layer_rule(module):
    mine = _layer(module)
    upward = sorted(m for m in GRAPH[module] if _layer(m) > mine)
    assert not upward, (f"{module} (layer {mine}) imports from higher layers: "
                        + ", ".join(f"{m} (layer {_layer(m)})" for m in upward))


def test_rule_is_documented():
    import vibrospeed

    doc = vibrospeed.__doc__ or ""
    for line in ("types, errors, config, presets", "models, signal, io", "sim, estimators",
                 "eval", "batch", "cli"):
        assert line in doc
