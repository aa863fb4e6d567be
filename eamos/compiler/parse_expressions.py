"""Reading tree-sitter nodes: locations, syntax errors, names, numbers and conditions.

The base of the parser's reader (:mod:`.parse`): every located diagnostic,
syntax error, over-long name, number and condition of a mission is read here.  Locations are
character columns (see :mod:`.source`).  Numbers must be finite; conditions
and arguments nest at most :data:`~.limits.MAX_EXPRESSION_DEPTH` operators and
parentheses, checked by an explicit-stack walk *before* the recursive reading,
so no input reaches Python's recursion limit.
"""

from __future__ import annotations

import math
import re
from typing import Any

from ..program.uniform import PROPERTIES
from .errors import Diagnostic, SourceLocation
from .limits import MAX_ERRORS, MAX_EXPRESSION_DEPTH, MAX_NAME_BYTES, MAX_NAME_CHARS, name_error
from .source import SourceText, display_line, split_lines
from .syntax import Binary, Bool, Expr, Name, Num, Prop, Unary

Node = Any  # tree_sitter.Node; typed loosely so the module imports without it

_BINARY_OPS = {"&&", "||", "==", "!=", "<", "<=", ">", ">=", "+", "-", "*", "/"}
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
        """An argument: numbers and names joined by ``+ - * /``, unary minus, parentheses.

        Names are block parameters (or drones, for a block's drone parameters);
        what they stand for is checked later.  Call :meth:`too_deep` first.
        """
        if node is None:
            return None
        kind = node.type
        if kind in ("int_literal", "float_literal"):
            value = self.number(node)
            return None if value is None else Num(value, self.loc(node))
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
            if op in ("+", "-", "*", "/"):
                left = self.const_expr(node.child_by_field_name("left"))
                right = self.const_expr(node.child_by_field_name("right"))
                if left is None or right is None:
                    return None
                return Binary(op, left, right, self.loc(operator))
        what = {
            "interpreted_string_literal": "a string",
            "raw_string_literal": "a string",
            "true": "a boolean",
            "false": "a boolean",
        }.get(kind, "an expression")
        self.error(
            node,
            f"action arguments are literal numbers, not {what}",
            "write the value itself, e.g. Drone1.Takeoff(1.5), or an expression of numbers "
            "and the block's parameters with + - * /",
        )
        return None

    # -- conditions ---------------------------------------------------------

    def expr(self, node: Node | None) -> Expr | None:
        """A condition (call :meth:`too_deep` on its root first: this recurses)."""
        if node is None:
            return None
        kind = node.type
        loc = self.loc(node)
        if kind == "parenthesized_expression":
            inner = [c for c in node.named_children if c.type != "comment"]
            return self.expr(inner[0]) if len(inner) == 1 else None
        if kind in ("int_literal", "float_literal"):
            value = self.number(node)
            return None if value is None else Num(value, loc)
        if kind in ("true", "false"):
            return Bool(kind == "true", loc)
        if kind == "unary_expression":
            return self._unary(node, loc)
        if kind == "binary_expression":
            return self._binary(node)
        if kind == "call_expression":
            return self._property(node, loc)
        if kind == "identifier":
            name = text(node)
            if name in self.param_names:
                return Name(name, loc)
            hint = (
                f"read it from a drone: Drone1.{name}()"
                if name in PROPERTIES
                else f"did you mean {name}.X()? properties are called with ()"
            )
            self.error(node, f"'{name}' is a bare name; conditions read drone properties", hint)
            return None
        if kind == "selector_expression":
            self.error(node, "a property is read by calling it", f"write {text(node)}()")
            return None
        self.error(
            node,
            "this expression is not supported in conditions",
            "use numbers, drone properties like D3.X(), comparisons, &&, ||, !",
        )
        return None

    def _unary(self, node: Node, loc: SourceLocation) -> Expr | None:
        op = text(node.child_by_field_name("operator"))
        operand = self.expr(node.child_by_field_name("operand"))
        if operand is None:
            return None
        if op == "+":
            return operand
        if op not in ("!", "-"):
            self.error(
                node,
                f"operator '{op}' is not supported in conditions",
                "use numbers, comparisons, &&, ||, ! and + - * /",
            )
            return None
        return Unary(op, operand, loc)  # type: ignore[arg-type]

    def _binary(self, node: Node) -> Expr | None:
        operator = node.child_by_field_name("operator")
        op = text(operator)
        left = self.expr(node.child_by_field_name("left"))
        right = self.expr(node.child_by_field_name("right"))
        if operator is None:
            return None
        if op not in _BINARY_OPS:
            self.error(
                operator,
                f"operator '{op}' is not supported in conditions",
                "use comparisons, &&, ||, ! and + - * /",
            )
            return None
        if left is None or right is None:
            return None
        return Binary(op, left, right, self.loc(operator))

    def _property(self, node: Node, loc: SourceLocation) -> Expr | None:
        fn = node.child_by_field_name("function")
        args = node.child_by_field_name("arguments")
        if fn is not None and fn.type == "selector_expression":
            operand = fn.child_by_field_name("operand")
            field = fn.child_by_field_name("field")
            if operand is not None and operand.type == "identifier" and field is not None:
                if args is not None and args.named_child_count:
                    self.error(
                        args,
                        "drone properties take no arguments",
                        f"write {text(operand)}.{text(field)}()",
                    )
                    return None
                return Prop(text(operand), text(field), loc)
        self.error(
            node,
            "only drone properties can be called in a condition",
            "e.g. D3.X() > 10 && Drone1.Battery() > 30",
        )
        return None


def _short(literal: str) -> str:
    return literal if len(literal) <= 24 else literal[:20] + "..."
