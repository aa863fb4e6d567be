"""Reading conditions: comparisons, ``&&``/``||``/``!``, properties and group conditions.

The part of the parser's reader (:mod:`.parse`) for the conditions of control
structures: ``D3.X() > -30 && D3.Battery() > 20``, ``Team[i].Z() > 2``,
``All(Team.Z() > 2)``.  Call :meth:`~.parse_expressions.NodeReader.too_deep` on a
condition's root before reading it: this recurses.
"""

from __future__ import annotations

from ..program.uniform import PROPERTIES
from .errors import SourceLocation
from .parse_expressions import Node, NodeReader, text
from .syntax import QUANTIFIERS, Binary, Bool, Expr, Name, Num, Prop, Quantifier, Unary

_BINARY_OPS = {"&&", "||", "==", "!=", "<", "<=", ">", ">=", "+", "-", "*", "/", "%"}


class ConditionReader(NodeReader):
    """The conditions of one tree-sitter tree."""

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
            return None if value is None else Num(value, loc, kind == "int_literal")
        if kind in ("true", "false"):
            return Bool(kind == "true", loc)
        if kind == "unary_expression":
            return self._unary(node, loc)
        if kind == "binary_expression":
            return self._binary(node)
        if kind == "call_expression":
            function = text(node.child_by_field_name("function"))
            if function in QUANTIFIERS:
                return self._quantifier(function, node, loc)
            if function == "len":
                return self.length(node)
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

    def _quantifier(self, kind: str, node: Node, loc: SourceLocation) -> Expr | None:
        """``All(Team.Z() > 2)``: one condition that reads a group as if it were a drone."""
        args = node.child_by_field_name("arguments")
        given = [a for a in args.named_children if a.type != "comment"] if args else []
        if len(given) != 1:
            self.error(
                node,
                f"{kind} takes one condition that reads a group",
                f"e.g. {kind}(Team.Z() > 2): Team.Z() stands for each member's Z()",
            )
            return None
        cond = self.expr(given[0])
        if cond is None:
            return None
        return Quantifier(kind, cond, loc)  # type: ignore[arg-type]

    def _property(self, node: Node, loc: SourceLocation) -> Expr | None:
        fn = node.child_by_field_name("function")
        args = node.child_by_field_name("arguments")
        if fn is not None and fn.type == "selector_expression":
            operand = fn.child_by_field_name("operand")
            field = fn.child_by_field_name("field")
            picked = operand is not None and operand.type in (
                "index_expression",
                "slice_expression",
            )
            if operand is not None and (operand.type == "identifier" or picked) and field:
                if args is not None and args.named_child_count:
                    self.error(
                        args,
                        "drone properties take no arguments",
                        f"write {text(operand)}.{text(field)}()",
                    )
                    return None
                if not picked:
                    return Prop(text(operand), text(field), loc)
                part = self.pick(operand)
                if part is None:
                    return None
                return Prop(part.group, text(field), loc, part)
        self.error(
            node,
            "only drone properties can be called in a condition",
            "e.g. D3.X() > 10 && Drone1.Battery() > 30",
        )
        return None
