"""Conditions as data: a tiny expression form the runtime evaluates safely.

A condition is a nested JSON-able list: ``["num", 5.0]``, ``["bool", true]``,
``["prop", "D3", "X"]``, ``["not", e]``, ``["neg", e]``, or ``[op, a, b]``
with ``op`` one of ``&& || == != < <= > >= + - * /``.  It is evaluated by a
small interpreter over telemetry values, never by ``eval``.

A condition nests at most :data:`MAX_DEPTH` operators: the compiler refuses
deeper ones and :func:`validate` rejects them in a loaded program, so the
recursive :func:`evaluate` and :func:`to_text` stay far from Python's stack limit.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

Condition = list[Any]

#: Most operators nested in one condition (``!``, ``-``, ``&&`` ... each count one).
MAX_DEPTH = 100

BINARY_OPS: dict[str, Callable[[Any, Any], Any]] = {
    "<": lambda a, b: a < b,
    "<=": lambda a, b: a <= b,
    ">": lambda a, b: a > b,
    ">=": lambda a, b: a >= b,
    "==": lambda a, b: a == b,
    "!=": lambda a, b: a != b,
    "+": lambda a, b: a + b,
    "-": lambda a, b: a - b,
    "*": lambda a, b: a * b,
    # Division by zero yields infinity rather than crashing a flying mission.
    "/": lambda a, b: a / b if b else (float("inf") if a > 0 else float("-inf") if a < 0 else 0.0),
}


class ConditionError(ValueError):
    """A condition in a drone program is malformed."""


class Unknown(Exception):
    """A property the condition needs has no value yet."""


Lookup = Callable[[str, str], float | bool | None]


def evaluate(cond: Condition, lookup: Lookup) -> bool | float:
    """Evaluate ``cond``; ``lookup(drone, prop)`` returns a value or None if unknown.

    Raises :class:`Unknown` when a needed value is missing; ``&&`` and ``||``
    short-circuit, so a known false left side decides without the right side.
    """
    tag = cond[0]
    if tag == "num":
        return float(cond[1])
    if tag == "bool":
        return bool(cond[1])
    if tag == "prop":
        value = lookup(cond[1], cond[2])
        if value is None:
            raise Unknown(f"{cond[1]}.{cond[2]}()")
        return value
    if tag == "not":
        return not evaluate(cond[1], lookup)
    if tag == "neg":
        return -evaluate(cond[1], lookup)
    if tag == "&&":
        return bool(evaluate(cond[1], lookup)) and bool(evaluate(cond[2], lookup))
    if tag == "||":
        return bool(evaluate(cond[1], lookup)) or bool(evaluate(cond[2], lookup))
    op = BINARY_OPS.get(tag)
    if op is None:
        raise ConditionError(f"unknown operator {tag!r}")
    return op(evaluate(cond[1], lookup), evaluate(cond[2], lookup))  # type: ignore[no-any-return]


def properties(cond: Condition | None) -> list[tuple[str, str]]:
    """Every (drone, property) a condition reads, in order, without repeats."""
    out: list[tuple[str, str]] = []
    todo = [cond] if cond is not None else []
    while todo:  # an explicit stack: no recursion, whatever the depth
        c = todo.pop()
        if c[0] == "prop":
            if (c[1], c[2]) not in out:
                out.append((c[1], c[2]))
        elif c[0] not in ("num", "bool"):
            todo.extend(reversed(c[1:]))
    return out


def validate(cond: Any) -> None:
    """Raise :class:`ConditionError` unless ``cond`` is a well-formed condition.

    Iterative, so a hostile program nested thousands deep is rejected, not a crash.
    """
    todo: list[tuple[Any, int]] = [(cond, 0)]
    while todo:
        c, depth = todo.pop()
        _validate_one(c)
        if c[0] in ("num", "bool", "prop"):
            continue
        if depth >= MAX_DEPTH:
            raise ConditionError(f"a condition nests more than {MAX_DEPTH} operators")
        todo.extend((sub, depth + 1) for sub in c[1:])


def _validate_one(cond: Any) -> None:
    """Check one level of a condition (its operands are checked by the caller)."""
    if not isinstance(cond, list) or not cond:
        raise ConditionError("a condition is a non-empty list")
    tag = cond[0]
    if not isinstance(tag, str):
        raise ConditionError("a condition starts with its operator's name")
    if tag == "num":
        if (
            len(cond) != 2
            or not isinstance(cond[1], int | float)
            or isinstance(cond[1], bool)
            or not math.isfinite(cond[1])
        ):
            raise ConditionError("['num', value] needs a finite number")
    elif tag == "bool":
        if len(cond) != 2 or not isinstance(cond[1], bool):
            raise ConditionError("['bool', value] needs true/false")
    elif tag == "prop":
        if len(cond) != 3 or not all(isinstance(x, str) for x in cond[1:]):
            raise ConditionError("['prop', drone, name] needs two names")
    elif tag in ("not", "neg"):
        if len(cond) != 2:
            raise ConditionError(f"[{tag!r}, e] takes one operand")
    elif tag in BINARY_OPS or tag in ("&&", "||"):
        if len(cond) != 3:
            raise ConditionError(f"[{tag!r}, a, b] takes two operands")
    else:
        raise ConditionError(f"unknown operator {tag!r}")


#: Go's operator precedence (higher binds tighter); atoms and unary operators above all.
_PRECEDENCE = {
    "||": 1,
    "&&": 2,
    **dict.fromkeys(("==", "!=", "<", "<=", ">", ">="), 3),
    **dict.fromkeys(("+", "-"), 4),
    **dict.fromkeys(("*", "/", "%"), 5),
    "not": 6,
    "neg": 6,
}
_ATOM = 7


def to_text(cond: Condition | None) -> str:
    """Go text of a condition, for labels and logs: as a person writes it.

    Parentheses only where Go's precedence needs them
    (``D1.X() > 5 && (D2.Z() < 1 || D3.Battery() < 20)``), so the text reads
    as the mission wrote it, less any redundant brackets.
    """
    if cond is None:
        return ""
    tag = cond[0]
    if tag == "num":
        return f"{cond[1]:g}"
    if tag == "bool":
        return "true" if cond[1] else "false"
    if tag == "prop":
        return f"{cond[1]}.{cond[2]}()"
    mine = _PRECEDENCE.get(tag, _ATOM)
    if tag in ("not", "neg"):
        return ("!" if tag == "not" else "-") + _operand(cond[1], mine, right=True)
    return f"{_operand(cond[1], mine, right=False)} {tag} {_operand(cond[2], mine, right=True)}"


def _operand(cond: Condition, parent: int, *, right: bool) -> str:
    """An operand's text, bracketed when it binds looser than its operator (left-assoc)."""
    text = to_text(cond)
    mine = _PRECEDENCE.get(cond[0], _ATOM) if cond[0] not in ("num", "bool", "prop") else _ATOM
    return f"({text})" if mine < parent or (right and mine == parent) else text
