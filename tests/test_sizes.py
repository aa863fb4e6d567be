"""Size limits of DEVELOPERS.md, enforced: no module over 700 lines, no class over 350.

Split by responsibility before a limit is reached; this test names what went over.
"""

from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MAX_MODULE_LINES = 700
MAX_CLASS_LINES = 350


def _sources() -> list[Path]:
    return sorted((REPO / "eamos").rglob("*.py"))


def class_lengths(path: Path) -> dict[str, int]:
    """Lines of every class in ``path`` (decorators included), by qualified name."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out: dict[str, int] = {}

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ClassDef):
                first = min([child.lineno, *(d.lineno for d in child.decorator_list)])
                name = f"{prefix}{child.name}"
                out[name] = (child.end_lineno or child.lineno) - first + 1
                visit(child, f"{name}.")

    visit(tree, "")
    return out


def test_no_module_over_the_limit() -> None:
    over = {
        str(p.relative_to(REPO)): n
        for p in _sources()
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES
    }
    assert not over, f"modules over {MAX_MODULE_LINES} lines: {over}"


def test_no_class_over_the_limit() -> None:
    over = {
        f"{p.relative_to(REPO)}:{name}": n
        for p in _sources()
        for name, n in class_lengths(p).items()
        if n > MAX_CLASS_LINES
    }
    assert not over, f"classes over {MAX_CLASS_LINES} lines: {over}"


def test_the_class_measure_counts_what_it_should(tmp_path: Path) -> None:
    source = tmp_path / "m.py"
    source.write_text("@dec\nclass A:\n    x = 1\n\n    class B:\n        y = 2\n")
    assert class_lengths(source) == {"A": 6, "A.B": 2}
