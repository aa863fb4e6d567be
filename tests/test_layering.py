"""The architecture as a test: layers import downward only, and no import cycle exists.

The map is docs/architecture.md.  Imports are read from the source (``ast``), every
``import`` counted wherever it stands (a function-level import is still a dependency), so
this test fails the moment a module reaches up or sideways.
"""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import networkx as nx
import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "eamos"

#: Package -> the eamos packages it may import (besides itself).  Top-level modules
#: (``eamos/logs.py``, ``eamos/hints.py``, ...) count as packages of their own name.
_LAYERS: dict[str, set[str]] = {
    "hints": set(),
    "logs": set(),
    "lazy": set(),
    "program": set(),
    "compiler": {"program", "hints"},
    "hal": {"program", "hints", "logs", "lazy"},
    "net": {"program", "logs"},
    "config": {"program", "hints", "hal", "net", "lazy"},
    "actors": {"program", "hints", "logs", "hal", "net", "config", "lazy"},
    "ground": {"program", "hints", "logs", "hal", "net", "config", "actors", "lazy"},
    "virtual": {"program", "hints", "logs", "hal", "actors"},
    "report": {"program", "logs", "ground", "hal"},
    "ops": {"program", "hints", "logs", "hal", "net", "config", "actors", "ground", "compiler"},
    "lsp": {"program", "hints", "compiler"},
    "check": {"program", "hints", "logs", "hal", "actors", "virtual", "compiler", "config"},
    "monitor": {"program", "hints", "logs", "hal", "net", "config", "actors", "ground", "compiler"},
}
ALLOWED: dict[str, set[str]] = dict(_LAYERS)
#: Packages only command-line code may import; nothing imports the CLI.
TOP = {"cli"}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(path: Path, name: str, modules: set[str]) -> set[str]:
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            targets = [module] + [f"{module}.{alias.name}" for alias in node.names]
        found |= {t for t in targets if t in modules and t != name}
    return found


def import_graph() -> nx.DiGraph:
    """Module -> module imports inside the eamos package."""
    paths = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = nx.DiGraph()
    graph.add_nodes_from(paths)
    for name, path in paths.items():
        graph.add_edges_from((name, target) for target in _imports(path, name, set(paths)))
    return graph


def _package(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def test_no_module_imports_itself_in_a_cycle() -> None:
    graph = import_graph()
    cycles = [c for c in nx.simple_cycles(graph) if len(c) > 1]
    assert not cycles, f"module import cycles: {cycles[:5]}"


def test_no_cycle_between_packages() -> None:
    packages = nx.DiGraph()
    for a, b in import_graph().edges:
        if _package(a) != _package(b) and "eamos" not in (_package(a), _package(b)):
            packages.add_edge(_package(a), _package(b))
    assert not list(nx.simple_cycles(packages)), sorted(packages.edges)


def test_every_package_imports_only_the_layers_below_it() -> None:
    wrong = []
    for a, b in import_graph().edges:
        pa, pb = _package(a), _package(b)
        if pa == pb or pb == "eamos":
            continue
        if pb in TOP and pa not in TOP:
            wrong.append(f"{a} -> {b} (only command-line code imports {pb})")
        elif pa in ALLOWED and pb not in ALLOWED[pa]:
            wrong.append(f"{a} -> {b} ({pa} may import {sorted(ALLOWED[pa])})")
    assert not wrong, "\n".join(wrong)


@pytest.mark.parametrize(
    "module,forbidden",
    [
        ("eamos.compiler", ["pykka", "zmq", "structlog", "msgpack", "pymavlink"]),
        ("eamos.program.format", ["networkx", "tree_sitter", "pykka", "zmq", "structlog"]),
        ("eamos.program.uniform", ["networkx", "tree_sitter", "pykka", "zmq", "structlog"]),
        ("eamos.program.conditions", ["networkx", "tree_sitter", "pykka", "zmq"]),
        ("eamos.net.wire", ["pykka", "networkx", "tree_sitter", "pymavlink"]),
        ("eamos.hal", ["pykka", "zmq", "networkx", "tree_sitter", "pymavlink"]),
    ],
)
def test_importing_a_layer_loads_nothing_from_above(module: str, forbidden: list[str]) -> None:
    code = f"import sys, {module}\nprint(','.join(m for m in {forbidden!r} if m in sys.modules))"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert out.stdout.strip() == "", f"importing {module} loaded {out.stdout.strip()}"


def test_the_layering_test_sees_a_violation() -> None:
    # The checks above must be able to fail: an upward import is found.
    assert ("eamos.compiler.phases", "eamos.program.uniform") in import_graph().edges
    assert "actors" not in ALLOWED["compiler"]


def _packages() -> list[str]:
    return sorted(_module_name(p.parent / "__init__.py") for p in PACKAGE.rglob("__init__.py"))


@pytest.mark.parametrize("package", _packages())
def test_every_package_says_what_it_offers_and_names_it(package: str) -> None:
    # Each package's __init__.py names what others may use (__all__), under a docstring
    # saying what the package offers; every name resolves, also those loaded on first use.
    module = importlib.import_module(package)
    assert (module.__doc__ or "").strip(), f"{package}/__init__.py has no docstring"
    names = getattr(module, "__all__", None)
    assert isinstance(names, list), f"{package}/__init__.py has no __all__"
    assert len(set(names)) == len(names), f"{package}.__all__ names something twice"
    missing = [name for name in names if not hasattr(module, name)]
    assert not missing, f"{package}.__all__ names what it does not have: {missing}"
    assert set(names) <= set(dir(module)), f"dir({package}) hides part of __all__"


def test_one_lazy_export_mechanism() -> None:
    # A package loading names on first use does it through eamos.lazy, not by hand.
    by_hand = [
        _module_name(path)
        for path in PACKAGE.rglob("__init__.py")
        if "def __getattr__" in path.read_text(encoding="utf-8")
    ]
    assert not by_hand, f"hand-written module __getattr__ (use eamos.lazy.lazy_exports): {by_hand}"
