"""Reading the statements of a block: block calls, drone actions, loops and control structures.

The part of the parser's reader (:mod:`.parse`) for what a block contains.  Every Go
statement a mission does not support (``if``, ``go``, assignments ...) is reported with
the control structure to use instead, a ``for`` is read by :class:`~.parse_loops.LoopReader`,
and a control structure's arguments are checked against its signature.
"""

from __future__ import annotations

from ..program.uniform import ACTIONS
from .errors import Diagnostic
from .limits import MAX_REPEAT
from .parse_expressions import Node, text
from .parse_loops import LoopReader
from .syntax import CONTROL_KINDS, Control, Expr, Member, Statement

__all__ = ["StatementReader"]

# Go statements a mission cannot contain, and what to write instead.
_UNSUPPORTED_STATEMENTS = {
    "if_statement": (
        "a Go 'if' statement",
        "use If(cond, Then, Else) with blocks named Then and Else",
    ),
    "go_statement": ("a 'go' statement", "put the calls in a PAR_ block to run them in parallel"),
    "assignment_statement": ("an assignment", "missions have no variables; use literal values"),
    "short_var_declaration": (
        "a variable declaration",
        "missions have no variables; use literal values",
    ),
    "var_declaration": (
        "a variable declaration inside a block",
        "declare drones at the top: var Drone1 DroneType1",
    ),
    "const_declaration": ("a constant", "missions have no constants; use literal values"),
    "inc_statement": ("an increment", "missions have no variables"),
    "dec_statement": ("a decrement", "missions have no variables"),
    "return_statement": ("a 'return'", "a block ends at its closing brace"),
    "defer_statement": ("a 'defer'", "put the call last in a SEQ_ block"),
    "expression_switch_statement": ("a 'switch'", "use If(cond, Then, Else)"),
    "type_switch_statement": ("a 'switch'", "use If(cond, Then, Else)"),
    "select_statement": ("a 'select'", "use WaitUntil(cond, Body)"),
    "goto_statement": ("a 'goto'", "call blocks instead"),
    "labeled_statement": ("a label", "call blocks instead"),
    "break_statement": ("a 'break'", "use DoWhile/DoUntil to interrupt a body"),
    "continue_statement": ("a 'continue'", "use RepeatWhile/RepeatUntil"),
    "send_statement": ("a channel send", "missions synchronise through SEQ_ and PAR_ blocks"),
    "block": ("a nested block", "put the statements in a named SEQ_ or PAR_ block and call it"),
}

_CONTROL_SIGNATURES = {
    "If": "If(cond, Then[, Else])",
    "WaitWhile": "WaitWhile(cond, Body)",
    "WaitUntil": "WaitUntil(cond, Body)",
    "RepeatWhile": "RepeatWhile(cond, Body[, Exit])",
    "RepeatUntil": "RepeatUntil(cond, Body[, Exit])",
    "RepeatFor": "RepeatFor(n, Body[, Exit])",
    "PauseWhile": "PauseWhile(cond)",
    "PauseUntil": "PauseUntil(cond)",
    "DoWhile": "DoWhile(cond, Body[, Exit])",
    "DoUntil": "DoUntil(cond, Body[, Exit])",
    "Try": "Try(Body, OnFailure)",
    "Whenever": "Whenever(cond, Handler)",
    "Abandon": "Abandon()",
}


class StatementReader(LoopReader):
    """The statements of a block (the file's top level is :class:`~.parse._Reader`'s)."""

    def statements_of(self, body: Node) -> tuple[list[Statement], bool]:
        """The statements of a ``{ ... }`` body, and whether none was lost to an error."""
        statements: list[Statement] = []
        complete = True
        for stmt_node in self._statement_nodes(body):
            stmt = self._statement(stmt_node)
            if stmt is not None:
                statements.append(stmt)
            else:
                complete = False
        return statements, complete

    def _statement_nodes(self, body: Node) -> list[Node]:
        out: list[Node] = []
        for child in body.named_children:
            if child.type == "statement_list":
                out.extend(c for c in child.named_children)
            else:
                out.append(child)
        return [c for c in out if c.type not in ("comment", "empty_statement")]

    # -- statements ---------------------------------------------------------

    def _statement(self, node: Node) -> Statement | None:
        if node.type == "ERROR":
            return None
        if node.type == "for_statement":
            return self.for_loop(node)
        if node.type in _UNSUPPORTED_STATEMENTS:
            what, hint = _UNSUPPORTED_STATEMENTS[node.type]
            self.error(node, f"{what} is not supported in missions", hint)
            return None
        if node.type != "expression_statement" or node.named_child_count != 1:
            self.error(
                node,
                "a statement is a block call, a drone action or a control structure",
                "e.g. SEQ_Fly(), Drone1.Takeoff(1.5) or WaitUntil(D1.Z() > 1, SEQ_Go)",
            )
            return None
        call = node.named_children[0]
        if call.type != "call_expression":
            self.error(
                call,
                "a statement is a block call, a drone action or a control structure",
                "e.g. SEQ_Fly(), Drone1.Takeoff(1.5) or WaitUntil(D1.Z() > 1, SEQ_Go)",
            )
            return None
        function = call.child_by_field_name("function")
        args_node = call.child_by_field_name("arguments")
        args = [a for a in args_node.named_children if a.type != "comment"] if args_node else []
        if function is None:
            return None
        if function.type == "identifier":
            name = text(function)
            if name in CONTROL_KINDS:
                return self._control(name, None, call, args)
            if name == "PauseFor":
                # A bare PauseFor(s) is an action without a drone: it runs on the
                # drone of the preceding statement (the ground station at the start).
                return self._action_call(None, name, call, args, function)
            if name in ACTIONS:
                self.error(
                    function,
                    f"'{name}' is an action and needs a drone",
                    f"write Drone1.{name}(...)",
                )
                return None
            return self._block_call(self.qualify(name), call, args, function)
        if function.type == "selector_expression":
            operand = function.child_by_field_name("operand")
            field = function.child_by_field_name("field")
            member: Member | None = None
            if operand is not None and operand.type == "index_expression" and field is not None:
                if self.too_deep(operand, "this index"):
                    return None
                picked = self.pick(operand)  # Team[i].Arm(): a member of a group
                if not isinstance(picked, Member):
                    return None
                member = picked
            elif operand is None or field is None or operand.type != "identifier":
                self.error(
                    function,
                    "an action is called on a drone by name",
                    "e.g. Drone1.Takeoff(1.5), or Team[i].Takeoff(1.5) on a group's member",
                )
                return None
            drone = member.group if member is not None else text(operand)
            action = text(field)
            if drone in self.packages and member is None:
                return self._block_call(f"{drone}.{action}", call, args, function)
            if action in ("PauseWhile", "PauseUntil"):
                return self._control(action, drone, call, args, member)
            if action in CONTROL_KINDS:
                self.error(
                    field,
                    f"{action} is a control structure, not an action of {drone}",
                    f"write {_CONTROL_SIGNATURES[action]}",
                )
                return None
            return self._action_call(drone, action, call, args, field, member)
        self.error(
            function,
            "a statement is a block call, a drone action or a control structure",
            "e.g. SEQ_Fly(), Drone1.Takeoff(1.5)",
        )
        return None

    def _control(
        self,
        kind: str,
        drone: str | None,
        call: Node,
        args: list[Node],
        member: Member | None = None,
    ) -> Control | None:
        sig = _CONTROL_SIGNATURES[kind]
        loc = self.loc(call)
        needs_cond = kind != "RepeatFor"
        min_args, max_args = {
            "If": (2, 3),
            "WaitWhile": (2, 2),
            "WaitUntil": (2, 2),
            "RepeatWhile": (2, 3),
            "RepeatUntil": (2, 3),
            "RepeatFor": (2, 3),
            "PauseWhile": (1, 1),
            "PauseUntil": (1, 1),
            "DoWhile": (2, 3),
            "DoUntil": (2, 3),
            "Try": (2, 2),
            "Whenever": (2, 2),
            "Abandon": (0, 0),
        }[kind]
        if not (min_args <= len(args) <= max_args):
            self.diags.append(
                Diagnostic(
                    "error",
                    loc,
                    f"{kind} takes {_count(min_args, max_args)}, got {len(args)}",
                    f"write {sig}",
                    self.end_col(call),
                )
            )
            return None
        if kind == "Try":
            # No condition: both arguments are blocks (Body, then OnFailure).
            refs = self.control_refs(kind, sig, args)
            if refs is None:
                return None
            return Control("Try", loc, body=refs[0], exit=refs[1])
        if kind == "Abandon":
            return Control("Abandon", loc)
        cond: Expr | None = None
        count: int | None = None
        count_expr: Expr | None = None
        if self.too_deep(args[0], "this condition" if needs_cond else "this count"):
            return None
        if needs_cond:
            cond = self.expr(args[0])
            if cond is None:
                return None
        elif _reads_names(args[0]):
            count_expr = self.const_expr(args[0])
            if count_expr is None:
                return None
        else:
            value = self.number(args[0])
            if value is None:
                return None
            if value != int(value) or not 0 <= value <= MAX_REPEAT:
                self.error(
                    args[0],
                    f"RepeatFor repeats a whole number of times, 0 to {MAX_REPEAT}",
                    "e.g. RepeatFor(3, SEQ_Body)",
                )
                return None
            count = int(value)
        refs = self.control_refs(kind, sig, args[1:])
        if refs is None:
            return None
        body = refs[0] if refs else None
        rest = refs[1] if len(refs) > 1 else None
        if kind == "If":
            return Control("If", loc, cond=cond, body=body, orelse=rest)  # type: ignore[arg-type]
        return Control(
            kind,  # type: ignore[arg-type]
            loc,
            cond=cond,
            count=count,
            body=body,
            exit=rest,
            drone=drone,
            count_expr=count_expr,
            pick=member,
        )


def _reads_names(node: Node) -> bool:
    """True if an argument's text names something (a parameter), not only numbers."""
    stack = [node]
    while stack:
        current = stack.pop()
        if current.type == "identifier":
            return True
        stack.extend(current.named_children)
    return False


def _count(lo: int, hi: int) -> str:
    plural = "s" if hi != 1 else ""
    return f"{lo} argument{plural}" if lo == hi else f"{lo} or {hi} arguments"
