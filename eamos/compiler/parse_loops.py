"""Reading drones, groups and loops: ``var Team [20]Quadcopter``, Go ``for`` statements.

The part of the parser's reader (:mod:`.parse`) for fleets: ``var`` declares
drones (``var D1 Quadcopter``) and groups; a group declaration
gives ``size`` drones of one type, addressed ``Team[i]``; a ``for`` inside a
block is read into a :class:`~.syntax.ForLoop`, expanded later
(:mod:`.instantiate`) into the statements it stands for.  Three Go forms are
accepted::

    for i, d := range Team { ... }     // over a group (or Team[a:b], a group parameter)
    for i := range 10 { ... }          // 0 .. 9
    for i := 0; i < n; i++ { ... }     // a counter: i++, i--, i += e, i -= e

Everything else a Go ``for`` can do (a bare condition, no condition, an
assignment instead of ``:=``) is a located error naming these forms.
"""

from __future__ import annotations

import dataclasses

from .constants import FoldError, fold_value, is_constant
from .errors import Diagnostic
from .limits import MAX_DRONES, MAX_LOOP_DEPTH, name_error
from .parse_declarations import DeclarationReader
from .parse_expressions import Node, text
from .syntax import DroneDecl, Expr, ForLoop, GroupDecl, Name, Num, Slice, Statement, Unary

_FORMS = (
    "for i, d := range Team { ... }, for i := range 10 { ... } or for i := 0; i < 10; i++ { ... }"
)
_COMPARISONS = ("<", "<=", ">", ">=", "!=")


class LoopReader(DeclarationReader):
    """Drone and group declarations and ``for`` statements of one file."""

    loop_depth = 0

    def statements_of(self, body: Node) -> tuple[list[Statement], bool]:
        """The statements of a ``{ ... }`` body, and whether none was lost to an error."""
        raise NotImplementedError  # pragma: no cover - the reader defines it

    # -- drones and groups ---------------------------------------------------------------

    def var_specs(self, node: Node) -> list[DroneDecl | GroupDecl]:
        """The drones and groups of a ``var`` declaration (``var ( ... )`` too)."""
        specs = [c for c in node.named_children if c.type == "var_spec"]
        for group in (c for c in node.named_children if c.type == "var_spec_list"):
            specs.extend(c for c in group.named_children if c.type == "var_spec")
        out: list[DroneDecl | GroupDecl] = []
        for spec in specs:
            names = [c for c in spec.children_by_field_name("name")]
            type_node = spec.child_by_field_name("type")
            if spec.child_by_field_name("value") is not None or type_node is None:
                self.error(
                    spec,
                    "a drone declaration names a drone and its type",
                    "write: var Drone1 DroneType1, or a group: var Team [20]Quadcopter",
                )
                continue
            if type_node.type == "array_type" and not self.prefix:
                out.extend(self.group_spec(spec, names, type_node))
                continue
            if type_node.type not in ("type_identifier", "qualified_type"):
                self.error(
                    type_node, "a drone type is a plain name", "write: var Drone1 Quadcopter"
                )
                continue
            if self.prefix:
                self.error(
                    spec,
                    "a library declares no drones",
                    "give its blocks drone parameters: func SEQ_Hop(d Quadcopter) { ... }",
                )
                continue
            kind = (
                text(type_node)
                if type_node.type == "type_identifier"
                else self.type_name(type_node)
            )
            if kind is None:
                continue
            out.extend(DroneDecl(text(n), kind, self.loc(n), self.loc(type_node)) for n in names)
        return out

    def group_spec(self, spec: Node, names: list[Node], type_node: Node) -> list[GroupDecl]:
        """``var Team [20]Quadcopter``: a group per name, or nothing (reported)."""
        length = type_node.child_by_field_name("length")
        element = type_node.child_by_field_name("element")
        hint = "write: var Team [20]Quadcopter"
        if length is None or element is None:
            self.error(type_node, "a group declaration gives its size and drone type", hint)
            return []
        if element.type not in ("type_identifier", "qualified_type"):
            self.error(element, "a group's members are drones of one type", hint)
            return []
        kind = text(element) if element.type == "type_identifier" else self.type_name(element)
        if kind is None:
            return []
        size = self.group_size(length)
        if size is None:
            return []
        out = []
        for node in names:
            name = text(node)
            # Members are named Team_<i>: the longest must fit the name limits too.
            too_long = name_error(f"{name}_{size - 1}", self.loc(node))
            if too_long is not None:
                self.diags.append(
                    Diagnostic(
                        "error",
                        self.loc(node),
                        f"the group name '{name}' is too long for its members' names "
                        f"('{name}_{size - 1}')",
                        "members are named like Team_3 in fleet files and logs: use a shorter name",
                    )
                )
                continue
            out.append(GroupDecl(name, kind, size, self.loc(node), self.loc(element)))
        return out

    def group_size(self, node: Node) -> int | None:
        """A group's size: a whole number 1 .. MAX_DRONES, written as a constant."""
        if self.too_deep(node, "this size"):
            return None
        expr = self.const_expr(node)
        if expr is None:
            return None
        problem = ""
        if not is_constant(expr):
            problem = "a group's size is a number written in the declaration"
        else:
            try:
                value = fold_value(expr, {})
            except FoldError as exc:
                problem = str(exc)
            else:
                if not isinstance(value, int) or not 1 <= value <= MAX_DRONES:
                    problem = f"a group has 1 to {MAX_DRONES} drones, not {value:g}"
        if problem:
            self.error(node, problem, "write: var Team [20]Quadcopter")
            return None
        assert isinstance(value, int)
        return value

    # -- loops ----------------------------------------------------------------

    def for_loop(self, node: Node) -> ForLoop | None:
        """A ``for`` statement, its body read with its variables in scope (None: reported)."""
        if self.loop_depth >= MAX_LOOP_DEPTH:
            self.error(
                node,
                f"loops nest more than {MAX_LOOP_DEPTH} deep",
                "call a block with parameters from the loop instead of nesting more loops",
            )
            return None
        clause = next((c for c in node.named_children if c.type not in ("block", "comment")), None)
        body = node.child_by_field_name("body")
        if body is None:
            return None
        if clause is None or clause.type not in ("range_clause", "for_clause"):
            self.error(
                node,
                "a for loop in a mission repeats a known number of times",
                f"write {_FORMS}; to repeat while a condition holds, use RepeatWhile(cond, Body)",
            )
            return None
        header = self.range_header(clause) if clause.type == "range_clause" else None
        if clause.type == "for_clause":
            header = self.counter_header(clause)
        if header is None:
            return None
        names = {n for n in (header.index, header.member) if n is not None}
        outer = self.param_names
        self.param_names = outer | names
        self.loop_depth += 1
        try:
            statements, complete = self.statements_of(body)
        finally:
            self.loop_depth -= 1
            self.param_names = outer
        return dataclasses.replace(
            header,
            body=tuple(statements),
            incomplete=not complete,
            end_line=node.end_point.row + 1,
        )

    def _variable(self, node: Node) -> tuple[str | None, Node | None]:
        if node.type != "identifier":
            self.error(node, "a loop variable is a name", f"write {_FORMS}")
            return None, None
        name = text(node)
        return (None, None) if name == "_" else (name, node)

    def range_header(self, clause: Node) -> ForLoop | None:
        """``i, d := range Team``, ``i := range 10``, ``range 3``: the loop without its body."""
        left = clause.child_by_field_name("left")
        right = clause.child_by_field_name("right")
        if right is None:
            return None
        loc = self.loc(clause.parent or clause)
        variables = [c for c in left.named_children if c.type != "comment"] if left else []
        if left is not None and ":=" not in [c.type for c in clause.children]:
            self.error(clause, "a loop declares its variables with :=", f"write {_FORMS}")
            return None
        if len(variables) > 2:
            self.error(
                left, "a range loop has at most two variables", "write for i, d := range Team"
            )
            return None
        index, index_node = self._variable(variables[0]) if variables else (None, None)
        member, member_node = self._variable(variables[1]) if len(variables) == 2 else (None, None)
        if variables and index is None and index_node is None and variables[0].type != "identifier":
            return None
        if self.too_deep(right, "this range"):
            return None
        over = self.const_expr(right)
        if over is None:
            return None
        if isinstance(over, Name | Slice):
            return ForLoop(
                loc,
                (),
                index,
                self.loc(index_node) if index_node else None,
                member,
                self.loc(member_node) if member_node else None,
                over=over,
            )
        if member is not None:
            self.error(
                variables[1],
                "a range over a number gives one variable, the counter",
                "write for i := range 10",
            )
            return None
        zero, one = Num(0.0, loc, True), Num(1.0, loc, True)
        index_loc = self.loc(index_node) if index_node else None
        return ForLoop(loc, (), index, index_loc, start=zero, op="<", limit=over, step=one)

    def counter_header(self, clause: Node) -> ForLoop | None:
        """``i := a; i < b; i++``: the loop without its body."""
        init = clause.child_by_field_name("initializer")
        cond = clause.child_by_field_name("condition")
        update = clause.child_by_field_name("update")
        if init is None or cond is None or update is None:
            self.error(
                clause,
                "a counting loop has its three parts: start; condition; step",
                "write for i := 0; i < 10; i++ { ... }",
            )
            return None
        left = init.child_by_field_name("left")
        right = init.child_by_field_name("right")
        if (
            init.type != "short_var_declaration"
            or left is None
            or right is None
            or left.named_child_count != 1
            or right.named_child_count != 1
        ):
            self.error(init, "a loop starts by declaring its counter", "write i := 0")
            return None
        index, index_node = self._variable(left.named_children[0])
        if index is None or index_node is None:
            if index_node is None and left.named_children[0].type == "identifier":
                self.error(init, "a counting loop names its counter", "write i := 0")
            return None
        start_node = right.named_children[0]
        if self.too_deep(start_node, "this start"):
            return None
        start = self.const_expr(start_node)
        limit = self._condition(cond, index)
        step = self._step(update, index)
        if start is None or limit is None or step is None:
            return None
        loc = self.loc(clause.parent or clause)
        return ForLoop(
            loc,
            (),
            index,
            self.loc(index_node),
            start=start,
            op=limit[0],
            limit=limit[1],
            step=step,
        )

    def _condition(self, cond: Node, index: str) -> tuple[str, Expr] | None:
        operator = cond.child_by_field_name("operator")
        left = cond.child_by_field_name("left")
        right = cond.child_by_field_name("right")
        op = text(operator)
        if (
            cond.type != "binary_expression"
            or op not in _COMPARISONS
            or left is None
            or right is None
            or text(left) != index
        ):
            self.error(
                cond,
                f"a counting loop's condition compares its counter: {index} < limit",
                f"write {index} < 10, {index} <= n, {index} >= 0 ...",
            )
            return None
        if self.too_deep(right, "this limit"):
            return None
        limit = self.const_expr(right)
        return None if limit is None else (op, limit)

    def _step(self, update: Node, index: str) -> Expr | None:
        target = update.named_children[0] if update.named_child_count else None
        hint = f"write {index}++, {index}--, {index} += 2 or {index} -= 2"
        loc = self.loc(update)
        if update.type in ("inc_statement", "dec_statement") and text(target) == index:
            return Num(1.0 if update.type == "inc_statement" else -1.0, loc, True)
        if update.type == "assignment_statement":
            left = update.child_by_field_name("left")
            right = update.child_by_field_name("right")
            op = text(update.child_by_field_name("operator"))
            if (
                left is not None
                and right is not None
                and text(left) == index
                and op in ("+=", "-=")
                and right.named_child_count == 1
            ):
                value = right.named_children[0]
                if self.too_deep(value, "this step"):
                    return None
                step = self.const_expr(value)
                if step is None:
                    return None
                return Unary("-", step, self.loc(value)) if op == "-=" else step
        self.error(update, "a counting loop steps its counter", hint)
        return None
