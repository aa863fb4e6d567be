"""Constant expressions: action and block arguments folded to numbers at compile time.

An argument is numbers and block parameters joined by ``+ - * /``, unary
minus and parentheses (:meth:`~.parse_expressions.NodeReader.const_expr`).
Once a block's parameters have values (when a call is expanded), the argument
is folded here to one finite number: a division by zero or a result too large
for a float is a located error, never ``inf`` or ``nan`` on a drone.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping

from .errors import SourceLocation
from .syntax import Binary, Expr, Name, Num, Unary


class FoldError(ValueError):
    """An argument that has no finite value; ``loc`` is where it goes wrong."""

    def __init__(self, message: str, loc: SourceLocation) -> None:
        super().__init__(message)
        self.loc = loc


def names_in(expr: Expr) -> Iterator[Name]:
    """Every name an expression reads, in source order (iteratively: no deep recursion)."""
    stack: list[Expr] = [expr]
    while stack:
        current = stack.pop()
        if isinstance(current, Name):
            yield current
        elif isinstance(current, Unary):
            stack.append(current.operand)
        elif isinstance(current, Binary):
            stack.extend((current.right, current.left))


def fold(expr: Expr, values: Mapping[str, float]) -> float:
    """The value of a constant expression, every name taken from ``values``.

    Raises :class:`FoldError` for an unknown name, a division by zero or a
    result that is not a finite number.  The nesting is bounded by the parser
    (``limits.MAX_EXPRESSION_DEPTH``), so the recursion is too.
    """
    if isinstance(expr, Num):
        return expr.value
    if isinstance(expr, Name):
        if expr.name not in values:
            raise FoldError(f"'{expr.name}' is not a number here", expr.loc)
        return values[expr.name]
    if isinstance(expr, Unary) and expr.op == "-":
        return -fold(expr.operand, values)
    if isinstance(expr, Binary) and expr.op in ("+", "-", "*", "/"):
        left, right = fold(expr.left, values), fold(expr.right, values)
        if expr.op == "/" and right == 0:
            raise FoldError("division by zero in this argument", expr.loc)
        try:
            value = {
                "+": lambda: left + right,
                "-": lambda: left - right,
                "*": lambda: left * right,
                "/": lambda: left / right,
            }[expr.op]()
        except OverflowError:
            value = math.inf
        if not math.isfinite(value):
            raise FoldError(
                f"this argument is not a finite number ({left:g} {expr.op} {right:g})", expr.loc
            )
        return value
    raise FoldError("this is not a constant number", expr.loc)


def show(value: float) -> str:
    """A folded number as labels and instance names print it (``5``, ``2.5``)."""
    return f"{value:g}"
