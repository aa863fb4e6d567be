"""Reading tree-sitter nodes: locations, syntax errors, names, numbers and arguments.

The base of the parser's reader (:mod:`.parse`): every located diagnostic,
syntax error, over-long name, number and argument (a constant expression, a
group's member or part, ``len``) of a mission is read here; conditions in
:mod:`.parse_conditions`.  Locations are character columns (see
:mod:`.source`).  Numbers must be finite; conditions
and arguments nest at most :data:`~.limits.MAX_EXPRESSION_DEPTH` operators and
parentheses, checked by an explicit-stack walk *before* the recursive reading,
so no input reaches Python's recursion limit.
"""

from __future__ import annotations

import math
import re
from typing import Any

from .errors import Diagnostic, SourceLocation
from .limits import MAX_ERRORS, MAX_EXPRESSION_DEPTH, MAX_NAME_BYTES, MAX_NAME_CHARS, name_error
from .source import SourceText, display_line, split_lines
from .syntax import (
    Binary,
    Expr,
    Len,
    Member,
    Name,
    Num,
    Slice,
    Unary,
)

Node = Any  # tree_sitter.Node; typed loosely so the module imports without it

_BINARY_OPS = {"&&", "||", "==", "!=", "<", "<=", ">", ">=", "+", "-", "*", "/", "%"}
_ARITHMETIC = ("+", "-", "*", "/", "%")
# The node kinds that nest an expression one level deeper, as a person counts them.
_NESTING = frozenset({"unary_expression", "binary_expression", "parenthesized_expression"})


# Any name too long for the limits has at least this many characters: a cheap first filter.
# A name's characters are word characters or any other non-ASCII, non-space one: ``\w``
# alone misses the combining marks an identifier may hold ('D' + 'x\u0301' * 100 is 201
# characters), and tree-sitter says which candidates are names anyway.
_LONG_WORD = re.compile(
    # One character class, not an alternation of overlapping ones: that backtracks
    # exponentially on a long run of non-ASCII letters.  ASCII word characters, and any
    # non-ASCII character that is not a space.
    r"[^\x00-\x2f\x3a-\x40\x5b-\x5e\x60\x7b-\x7f\s]"
    + "{"
    + str(min(MAX_NAME_CHARS, MAX_NAME_BYTES // 4) + 1)
    + ",}"
)
_NAME_NODES = frozenset({"identifier", "field_identifier", "type_identifier", "package_identifier"})


def text(node: Node | None) -> str:
    """The source text of a node ("" for a node tree-sitter could not build)."""
    return "" if node is None else bytes(node.text).decode("utf-8", errors="replace")


def nesting_depth(node: Node, limit: int) -> int:
    """Operators and parentheses nested in ``node`` (stops counting past ``limit``)."""
    best = 0
    stack = [(node, 0)]
    while stack:
        current, depth = stack.pop()
        if current.type in _NESTING:
            depth += 1
            if depth > best:
                best = depth
                if best > limit:
                    return best
        stack.extend((child, depth) for child in current.named_children)
    return best


class NodeReader:
    """Locations, diagnostics, numbers and conditions of one tree-sitter tree."""

    def __init__(self, source: SourceText, file: str = "") -> None:
        self.source = source
        self.file = file
        self.diags: list[Diagnostic] = []
        # Errors past MAX_ERRORS are counted, not kept: a file of junk has hundreds of
        # thousands, and making, sorting and printing them cost seconds (issue 28).
        self.errors_kept = 0
        self.dropped_errors = 0
        self.first_dropped: SourceLocation | None = None
        # The parameters of the block being read: names its conditions may use.
        self.param_names: frozenset[str] = frozenset()

    # -- locations and diagnostics ------------------------------------------

    def loc(self, node: Node) -> SourceLocation:
        row, byte_col = node.start_point
        return SourceLocation(row + 1, self.source.column(row, byte_col), self.file)

    def end_col(self, node: Node) -> int | None:
        if node.end_point.row != node.start_point.row:
            return None
        row, byte_col = node.end_point
        return self.source.column(row, byte_col)

    def error(self, node: Node, message: str, hint: str = "") -> None:
        if self.errors_kept >= MAX_ERRORS:
            self.dropped_errors += 1
            if self.first_dropped is None:
                self.first_dropped = self.loc(node)
            return
        self.errors_kept += 1
        self.diags.append(Diagnostic("error", self.loc(node), message, hint, self.end_col(node)))

    def dropped(self) -> Diagnostic | None:
        """The error saying how many errors were not kept (None when all were)."""
        if not self.dropped_errors or self.first_dropped is None:
            return None
        return Diagnostic(
            "error",
            self.first_dropped,
            f"{self.dropped_errors} more errors from here on are not shown "
            f"(only the first {MAX_ERRORS} are)",
            "fix the first ones: the rest often follow from them",
        )

    def warn(self, node: Node, message: str, hint: str = "") -> None:
        self.diags.append(Diagnostic("warning", self.loc(node), message, hint, self.end_col(node)))

    def too_deep(self, node: Node, what: str) -> bool:
        """Report (and return True) if ``node`` nests past the expression limit."""
        if nesting_depth(node, MAX_EXPRESSION_DEPTH) <= MAX_EXPRESSION_DEPTH:
            return False
        self.error(
            node,
            f"{what} nests operators and parentheses more than {MAX_EXPRESSION_DEPTH} deep",
            "split it: test parts in nested If/WaitUntil blocks, or simplify it",
        )
        return True

    # -- whole-tree checks ---------------------------------------------------

    def long_names(self, root: Node) -> None:
        """Report every drone, block, type or package name over the length limits.

        Names become file names on the drones.  A regular expression finds the
        candidates in one pass over the text; tree-sitter says which are names
        (not comments or numbers).
        """
        matches = list(_LONG_WORD.finditer(self.source.text))
        if not matches:
            return
        offsets = self.source.char_to_byte([o for m in matches for o in m.span()])
        for i, match in enumerate(matches):
            start, end = offsets[2 * i], offsets[2 * i + 1]
            node = root.descendant_for_byte_range(start, end)
            if node is None or node.type not in _NAME_NODES:
                continue
            if node.start_byte != start or node.end_byte != end:
                continue
            found = name_error(match.group(), self.loc(node))
            if found is not None:
                self.diags.append(found)

    # -- syntax errors ------------------------------------------------------

    def syntax_errors(self, root: Node) -> None:
        """Report each ERROR / MISSING node once, at its innermost position."""
        stack = [root]
        while stack:
            node = stack.pop()
            if node.is_missing:
                self.error(node, f"syntax error: missing '{node.type}'", "check the line above")
                continue
            if node.type == "ERROR":
                stripped = text(node).strip()
                snippet = display_line(split_lines(stripped)[0][:40]) if stripped else ""
                self.error(
                    node,
                    f"syntax error near '{snippet}'" if snippet else "syntax error",
                    "check brackets, parentheses and commas",
                )
                continue
            if node.has_error:
                stack.extend(reversed(node.children))

    # -- numbers ------------------------------------------------------------

    def number(self, node: Node) -> float | None:
        """A literal, finite number (with optional signs and parentheses), or None (reported)."""
        sign = 1.0
        inner = node
        while True:  # a loop, not recursion: -(-(+(1))) may nest deep
            if inner.type == "unary_expression" and text(inner.child_by_field_name("operator")) in (
                "+",
                "-",
            ):
                if text(inner.child_by_field_name("operator")) == "-":
                    sign = -sign
                operand = inner.child_by_field_name("operand")
                if operand is None:
                    return None
                inner = operand
            elif inner.type == "parenthesized_expression" and inner.named_child_count == 1:
                inner = inner.named_children[0]
            else:
                break
        if inner.type in ("int_literal", "float_literal"):
            literal = text(inner)
            try:
                digits = literal.replace("_", "")
                value = float(int(digits, 0)) if inner.type == "int_literal" else float(digits)
            except OverflowError:
                value = math.inf
            except ValueError:
                self.error(
                    inner,
                    f"'{_short(literal)}' is not a number this compiler understands",
                    "write decimal numbers like 1.5 or -2",
                )
                return None
            if not math.isfinite(value):
                self.error(
                    inner,
                    f"'{_short(literal)}' is too large a number",
                    "numbers must be finite; see the limits in docs/mission-language.md",
                )
                return None
            return sign * value
        kind = {
            "interpreted_string_literal": "a string",
            "raw_string_literal": "a string",
            "true": "a boolean",
            "false": "a boolean",
            "identifier": "a name",
        }.get(inner.type, "an expression")
        self.error(
            node,
            f"action arguments are literal numbers, not {kind}",
            "write the value itself, e.g. Drone1.Takeoff(1.5)",
        )
        return None

    def const_expr(self, node: Node) -> Expr | None:
        """An argument: numbers and names joined by ``+ - * / %``, unary minus, parentheses.

        Names are block parameters and loop variables (or drones and groups, for a
        block's drone and group parameters), ``len(Team)`` a group's size, ``Team[i]`` a
        member and ``Team[a:b]`` part of a group; what they stand for is checked later.
        Call :meth:`too_deep` first.
        """
        if node is None:
            return None
        kind = node.type
        if kind in ("int_literal", "float_literal"):
            value = self.number(node)
            return None if value is None else Num(value, self.loc(node), kind == "int_literal")
        if kind == "identifier":
            return Name(text(node), self.loc(node))
        if kind == "parenthesized_expression":
            inner = [c for c in node.named_children if c.type != "comment"]
            return self.const_expr(inner[0]) if len(inner) == 1 else None
        if kind == "unary_expression":
            op = text(node.child_by_field_name("operator"))
            operand = node.child_by_field_name("operand")
            if op in ("+", "-") and operand is not None:
                inner_expr = self.const_expr(operand)
                if inner_expr is None or op == "+":
                    return inner_expr
                return Unary("-", inner_expr, self.loc(node))
        if kind == "binary_expression":
            operator = node.child_by_field_name("operator")
            op = text(operator)
            if op in _ARITHMETIC:
                left = self.const_expr(node.child_by_field_name("left"))
                right = self.const_expr(node.child_by_field_name("right"))
                if left is None or right is None:
                    return None
                return Binary(op, left, right, self.loc(operator))
        if kind in ("index_expression", "slice_expression"):
            return self.pick(node)
        if kind == "call_expression" and text(node.child_by_field_name("function")) == "len":
            return self.length(node)
        what = {
            "interpreted_string_literal": "a string",
            "raw_string_literal": "a string",
            "true": "a boolean",
            "false": "a boolean",
        }.get(kind, "an expression")
        self.error(
            node,
            f"action arguments are literal numbers, not {what}",
            "write the value itself, e.g. Drone1.Takeoff(1.5), or an expression of numbers, "
            "the block's parameters and loop variables with + - * / %",
        )
        return None

    # -- groups -------------------------------------------------------------

    def pick(self, node: Node) -> Member | Slice | None:
        """``Team[i]`` (a member) or ``Team[a:b]`` (part of a group), or None (reported)."""
        operand = node.child_by_field_name("operand")
        if operand is None or operand.type != "identifier":
            self.error(
                node,
                "only a group's name is indexed",
                "write Team[i] for one member, Team[a:b] for several",
            )
            return None
        group = text(operand)
        if node.type == "index_expression":
            index_node = node.child_by_field_name("index")
            index = self.const_expr(index_node) if index_node is not None else None
            return None if index is None else Member(group, index, self.loc(node))
        if node.child_by_field_name("capacity") is not None:
            self.error(node, "a part of a group is written Team[a:b]", "remove the third bound")
            return None
        bounds: list[Expr | None] = []
        for name in ("start", "end"):
            bound_node = node.child_by_field_name(name)
            if bound_node is None:
                bounds.append(None)
                continue
            bound = self.const_expr(bound_node)
            if bound is None:
                return None
            bounds.append(bound)
        return Slice(group, bounds[0], bounds[1], self.loc(node))

    def length(self, node: Node) -> Len | None:
        """``len(Team)`` or ``len(Team[a:b])``, or None (reported)."""
        args = node.child_by_field_name("arguments")
        given = [a for a in args.named_children if a.type != "comment"] if args else []
        if len(given) == 1 and given[0].type == "identifier":
            return Len(Name(text(given[0]), self.loc(given[0])), self.loc(node))
        if len(given) == 1 and given[0].type == "slice_expression":
            part = self.pick(given[0])
            return None if not isinstance(part, Slice) else Len(part, self.loc(node))
        self.error(node, "len takes one group", "e.g. len(Team)")
        return None


def _short(literal: str) -> str:
    return literal if len(literal) <= 24 else literal[:20] + "..."
