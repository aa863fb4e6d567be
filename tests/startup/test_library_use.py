"""Libraries used as designed: what a scan of ``eamos/`` must not find, and the collector.

The scans read the source (Python's own ``ast``), so they fail when the code comes
back, whatever runs: the import system left alone (no ``sys.modules`` changes), the
garbage collector switched only in an entry point's ``main()``, structlog reached
through its public API only, no undocumented encoder of :mod:`json`.
"""

from __future__ import annotations

import ast
import gc
from collections.abc import Iterator
from pathlib import Path

from eamos.compiler import compile_mission

PACKAGE = Path(__file__).resolve().parents[2] / "eamos"

#: gc functions that change what the collector does for the whole process.
GC_SWITCHES = {"disable", "enable", "freeze", "unfreeze", "set_threshold"}
#: Methods that change a mapping.
MUTATORS = {"update", "pop", "popitem", "setdefault", "clear", "__setitem__", "__delitem__"}
#: structlog's private attributes (its bound loggers' context and wrapped logger).
STRUCTLOG_PRIVATE = {"_context", "_logger", "_processors"}


def modules() -> Iterator[tuple[str, ast.Module]]:
    for path in sorted(PACKAGE.rglob("*.py")):
        yield str(path.relative_to(PACKAGE.parent)), ast.parse(path.read_text(), str(path))


def is_name(node: ast.AST, *dotted: str) -> bool:
    """Whether ``node`` is the expression ``a.b`` for one of ``dotted`` ("sys.modules")."""
    return isinstance(node, ast.Attribute | ast.Name) and ast.unparse(node) in dotted


def findings(tree: ast.Module) -> Iterator[tuple[int, str]]:
    """(line, what) of every use the module docstring rules out."""
    functions: list[str] = []

    def visit(node: ast.AST) -> Iterator[tuple[int, str]]:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            functions.append(node.name)
        line = getattr(node, "lineno", 0)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            owner, method = node.func.value, node.func.attr
            if is_name(owner, "gc") and method in GC_SWITCHES and functions[:1] != ["main"]:
                yield line, f"gc.{method}() outside main()"
            if is_name(owner, "sys.modules") and method in MUTATORS:
                yield line, f"sys.modules.{method}()"
        if isinstance(node, ast.Assign | ast.AugAssign | ast.AnnAssign | ast.Delete):
            targets = node.targets if isinstance(node, ast.Assign | ast.Delete) else [node.target]
            for target in targets:
                if isinstance(target, ast.Subscript) and is_name(target.value, "sys.modules"):
                    yield line, "sys.modules[...] changed"
        if isinstance(node, ast.Attribute):
            if node.attr == "c_make_encoder":
                yield line, "json.encoder.c_make_encoder"
            if node.attr in STRUCTLOG_PRIVATE and not is_name(node.value, "self"):
                yield line, f"another object's {node.attr}"
        for child in ast.iter_child_nodes(node):
            yield from visit(child)
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            functions.pop()

    yield from visit(tree)


def test_eamos_leaves_the_import_system_the_collector_and_private_apis_alone() -> None:
    found = [f"{name}:{line}: {what}" for name, tree in modules() for line, what in findings(tree)]
    assert found == []


def test_the_scan_finds_what_it_looks_for() -> None:
    # The scan above must be able to fail.
    code = (
        "import gc, sys, json\n"
        "gc.disable()\n"
        "def main():\n    gc.freeze()\n"
        "def helper():\n    gc.disable()\n"
        "sys.modules['asyncio'] = None\n"
        "del sys.modules['x']\n"
        "sys.modules.update({})\n"
        "json.encoder.c_make_encoder\n"
        "bound._context.copy()\n"
        "self._logger\n"
    )
    assert [line for line, _ in findings(ast.parse(code))] == [2, 6, 7, 8, 9, 10, 11]


def test_compiling_leaves_the_collector_running() -> None:
    """The language server compiles on a worker thread: the collector goes on meanwhile."""
    started: list[int] = []

    def count(phase: str, info: dict[str, int]) -> None:
        if phase == "start":
            started.append(info["generation"])

    body = "".join(f"\tD{i % 3}.Takeoff(5)\n\tD{i % 3}.Land()\n" for i in range(200))
    gc.callbacks.append(count)
    try:
        compile_mission(f"func SEQ_M() {{\n{body}}}\n", "m.go")
    finally:
        gc.callbacks.remove(count)
    assert started  # collections ran while it compiled
