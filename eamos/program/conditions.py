"""Conditions as data: a tiny expression form the runtime evaluates safely.

A condition is a nested JSON-able list: ``["num", 5.0]``, ``["bool", true]``,
``["prop", "D3", "X"]``, ``["not", e]``, ``["neg", e]``, or ``[op, a, b]``
with ``op`` one of ``&& || == != < <= > >= + - * /``.  It is evaluated by a
small interpreter over telemetry values, never by ``eval``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

Condition = list[Any]

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

    def walk(c: Condition) -> None:
        if c[0] == "prop":
            if (c[1], c[2]) not in out:
                out.append((c[1], c[2]))
        elif c[0] in ("num", "bool"):
            return
        else:
            for sub in c[1:]:
                walk(sub)

    if cond is not None:
        walk(cond)
    return out


def validate(cond: Any) -> None:
    """Raise :class:`ConditionError` unless ``cond`` is a well-formed condition."""
    if not isinstance(cond, list) or not cond:
        raise ConditionError("a condition is a non-empty list")
    tag = cond[0]
    if tag == "num":
        if len(cond) != 2 or not isinstance(cond[1], int | float) or isinstance(cond[1], bool):
            raise ConditionError("['num', value] needs a number")
    elif tag == "bool":
        if len(cond) != 2 or not isinstance(cond[1], bool):
            raise ConditionError("['bool', value] needs true/false")
    elif tag == "prop":
        if len(cond) != 3 or not all(isinstance(x, str) for x in cond[1:]):
            raise ConditionError("['prop', drone, name] needs two names")
    elif tag in ("not", "neg"):
        if len(cond) != 2:
            raise ConditionError(f"[{tag!r}, e] takes one operand")
        validate(cond[1])
    elif tag in BINARY_OPS or tag in ("&&", "||"):
        if len(cond) != 3:
            raise ConditionError(f"[{tag!r}, a, b] takes two operands")
        validate(cond[1])
        validate(cond[2])
    else:
        raise ConditionError(f"unknown operator {tag!r}")


def to_text(cond: Condition | None) -> str:
    """Go-like text of a condition, for labels and logs."""
    if cond is None:
        return ""
    tag = cond[0]
    if tag == "num":
        return f"{cond[1]:g}"
    if tag == "bool":
        return "true" if cond[1] else "false"
    if tag == "prop":
        return f"{cond[1]}.{cond[2]}()"
    if tag == "not":
        return "!" + _paren(cond[1])
    if tag == "neg":
        return "-" + _paren(cond[1])
    return f"{_paren(cond[1])} {tag} {_paren(cond[2])}"


def _paren(cond: Condition) -> str:
    text = to_text(cond)
    return f"({text})" if cond[0] not in ("num", "bool", "prop", "not", "neg") else text
