"""Constant expressions: action and block arguments folded to numbers at compile time.

An argument is numbers, block parameters, loop variables and ``len(Group)``
joined by ``+ - * / %``, unary minus and parentheses
(:meth:`~.parse_expressions.NodeReader.const_expr`).  Once the names have
values (when a call or a loop is expanded), the argument is folded here to one
finite number: a division by zero or a result too large for a float is a
located error, never ``inf`` or ``nan`` on a drone.

Whole numbers stay whole, as in Go.  A loop counter, an ``int`` parameter and
``len(...)`` are *integers*; a whole literal (``2``, not ``2.0``) takes the
kind of what it is joined with.  An operation on integers gives an integer:
``/`` drops the remainder (``7 / 2`` is 3 when one side is an integer) and
``%`` is the remainder with the sign of the left side.  As soon as a decimal
number or a ``float64`` parameter takes part, the arithmetic is decimal.
Literals alone keep the language's first rule, decimal division (``7 / 2`` is
3.5, as before loops existed; ``6 / 2`` is the whole 3).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping
from typing import Literal

from .errors import SourceLocation
from .limits import MAX_WHOLE
from .syntax import Binary, Expr, Len, Member, Name, Num, Slice, Unary

#: A folded value: a Python ``int`` is an integer (whole by type), a ``float`` a decimal.
Value = int | float
#: The size of a group named in ``len(...)``, given by whoever knows the groups.
SizeOf = Callable[[Name | Slice], int]

_Kind = Literal["int", "float", "const"]


class FoldError(ValueError):
    """An argument that has no finite value; ``loc`` is where it goes wrong."""

    def __init__(self, message: str, loc: SourceLocation) -> None:
        super().__init__(message)
        self.loc = loc


def names_in(expr: Expr) -> Iterator[Name]:
    """Every name an expression reads, in source order (iteratively: no deep recursion).

    The group of a ``len(...)`` and the index of a member are read too.
    """
    stack: list[Expr | None] = [expr]
    while stack:
        current = stack.pop()
        if isinstance(current, Name):
            yield current
        elif isinstance(current, Unary):
            stack.append(current.operand)
        elif isinstance(current, Binary):
            stack.extend((current.right, current.left))
        elif isinstance(current, Len):
            stack.append(current.group)
        elif isinstance(current, Member):
            stack.extend((current.index, Name(current.group, current.loc)))
        elif isinstance(current, Slice):
            stack.extend((current.high, current.low, Name(current.group, current.loc)))


def is_constant(expr: Expr) -> bool:
    """True if an argument reads no name: it folds to one number where it is written."""
    return not any(True for _ in names_in(expr))


def fold(expr: Expr, values: Mapping[str, Value], size: SizeOf | None = None) -> float:
    """The value of a constant expression as a float, every name taken from ``values``.

    Raises :class:`FoldError` for an unknown name, a division by zero or a
    result that is not a finite number.  The nesting is bounded by the parser
    (``limits.MAX_EXPRESSION_DEPTH``), so the recursion is too.
    """
    return float(_fold(expr, values, size)[0])


def fold_value(expr: Expr, values: Mapping[str, Value], size: SizeOf | None = None) -> Value:
    """As :func:`fold`, but an integer result stays an ``int`` (a whole literal alone too)."""
    value, kind = _fold(expr, values, size)
    return value if kind != "float" else float(value)


def _whole(value: int, loc: SourceLocation) -> int:
    if abs(value) > MAX_WHOLE:
        raise FoldError(f"this whole number is too large ({value:.3g})", loc)
    return value


def _fold(expr: Expr, values: Mapping[str, Value], size: SizeOf | None) -> tuple[Value, _Kind]:
    if isinstance(expr, Num):
        if expr.whole and expr.value.is_integer() and abs(expr.value) <= MAX_WHOLE:
            return int(expr.value), "const"
        return expr.value, "float"
    if isinstance(expr, Name):
        if expr.name not in values:
            raise FoldError(f"'{expr.name}' is not a number here", expr.loc)
        value = values[expr.name]
        return value, "int" if isinstance(value, int) else "float"
    if isinstance(expr, Len) and size is not None:
        return size(expr.group), "int"
    if isinstance(expr, Unary) and expr.op == "-":
        value, kind = _fold(expr.operand, values, size)
        return -value, kind
    if isinstance(expr, Binary) and expr.op in ("+", "-", "*", "/", "%"):
        left, lkind = _fold(expr.left, values, size)
        right, rkind = _fold(expr.right, values, size)
        if "float" in (lkind, rkind):
            return _decimal(expr, float(left), float(right)), "float"
        assert isinstance(left, int) and isinstance(right, int)
        whole: _Kind = "int" if "int" in (lkind, rkind) else "const"
        if expr.op == "/" and whole == "const" and (right == 0 or left % right):
            # Literals alone divide as decimals (the language's rule before loops).
            return _decimal(expr, float(left), float(right)), "float"
        return _integer(expr, left, right), whole
    raise FoldError("this is not a constant number", expr.loc)


def _decimal(expr: Binary, left: float, right: float) -> float:
    if expr.op == "%":
        raise FoldError(
            f"'%' takes whole numbers, got {left:g} % {right:g}",
            expr.loc,
        )
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


def _integer(expr: Binary, left: int, right: int) -> int:
    """Go's integer arithmetic: ``/`` truncates toward zero, ``%`` has the left's sign."""
    if expr.op in ("/", "%") and right == 0:
        raise FoldError(f"{'division' if expr.op == '/' else 'remainder'} by zero", expr.loc)
    if expr.op == "+":
        return _whole(left + right, expr.loc)
    if expr.op == "-":
        return _whole(left - right, expr.loc)
    if expr.op == "*":
        return _whole(left * right, expr.loc)
    quotient = abs(left) // abs(right)
    if (left < 0) != (right < 0):
        quotient = -quotient
    return quotient if expr.op == "/" else left - right * quotient


def show(value: float) -> str:
    """A folded number as labels and instance names print it (``5``, ``2.5``)."""
    return f"{value:g}"
