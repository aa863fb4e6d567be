"""Where groups, loop variables and block parameters stand in a parsed mission.

A pure walk of the syntax (:mod:`eamos.compiler.syntax`) with the scopes the compiler
checks: a block's parameters are in scope in its body, a loop's variables in the loop's
body.  Each name a statement uses is told apart as the compiler does (a loop variable or a
parameter first, then a group, then a drone), so that renaming ``i`` in one loop leaves the
``i`` of another alone.  A variable's identity is its name and where it is declared
(:attr:`Variable.key`).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

from ..compiler.errors import SourceLocation
from ..compiler.syntax import (
    GROUP_PREFIX,
    NUMBER_TYPES,
    ActionCall,
    Binary,
    BlockCall,
    Control,
    Expr,
    ForLoop,
    Len,
    Member,
    Mission,
    Name,
    Prop,
    Quantifier,
    Slice,
    Statement,
    Unary,
)


@dataclass(frozen=True)
class Variable:
    """A loop variable or a block parameter: what it stands for, and where it is in scope.

    ``role`` is ``index`` (``i`` of ``for i, d := range Team``), ``member`` (``d``),
    ``counter`` (``i`` of ``for i := 0; ...``) or ``parameter``; ``over`` the group a
    loop ranges over (as written), ``type`` the drone type of a member or a parameter's
    type.  Lines ``first`` .. ``last`` hold its scope (a parameter: its block, to the end
    of the block's last statement).
    """

    name: str
    role: str
    loc: SourceLocation
    first: int
    last: int
    type: str = ""
    over: str = ""
    block: str = ""

    @property
    def key(self) -> str:
        """The variable's identity: two loops' ``i`` are different variables."""
        return f"{self.name}@{self.loc.line}:{self.loc.col}"


@dataclass(frozen=True)
class Use:
    """A name where a statement writes it: a group, a drone or a variable (``key``)."""

    name: str
    kind: str  # "group", "drone" or "variable"
    loc: SourceLocation
    key: str = ""


def _over_text(over: Name | Slice | None) -> str:
    return over.name if isinstance(over, Name) else over.group if over is not None else ""


class _Walker:
    def __init__(self, mission: Mission) -> None:
        self.mission = mission
        self.variables: list[Variable] = []
        self.uses: list[Use] = []

    def run(self) -> None:
        for block in self.mission.blocks.values():
            if block.loc.file:
                continue  # a library's blocks are not in this document
            last = block.end_line or _last_line(block.statements, block.loc.line)
            scope: dict[str, Variable] = {}
            for param in block.params:
                var = Variable(
                    param.name, "parameter", param.loc, block.loc.line, last, param.type, "",
                    block.name,
                )  # fmt: skip
                self.variables.append(var)
                scope[param.name] = var
            self.statements(block.statements, scope)

    # -- statements ---------------------------------------------------------------------

    def statements(self, statements: tuple[Statement, ...], scope: dict[str, Variable]) -> None:
        for stmt in statements:
            if isinstance(stmt, ForLoop):
                self.loop(stmt, scope)
            elif isinstance(stmt, ActionCall):
                self.drone(stmt.drone, stmt.pick, stmt.loc, scope)
                for expr in stmt.exprs:
                    self.expr(expr, scope)
            elif isinstance(stmt, BlockCall):
                for arg in stmt.args:
                    self.expr(arg, scope, drones=True)
            elif isinstance(stmt, Control):
                self.drone(stmt.drone, stmt.pick, stmt.loc, scope)
                for part in (stmt.cond, stmt.count_expr):
                    if part is not None:
                        self.expr(part, scope)
                for ref in (stmt.body, stmt.orelse, stmt.exit):
                    for arg in ref.args if ref is not None else ():
                        self.expr(arg, scope, drones=True)

    def loop(self, loop: ForLoop, scope: dict[str, Variable]) -> None:
        for expr in (loop.over, loop.start, loop.limit, loop.step):
            if expr is not None:
                self.expr(expr, scope)
        inner = dict(scope)
        last = loop.end_line or _last_line(loop.body, loop.loc.line)
        over = _over_text(loop.over)
        ranging = loop.over is not None and self.is_group(over, scope)
        member_type = self.group_type(over, scope) if ranging else ""
        for name, loc, role in (
            (loop.index, loop.index_loc, "index" if ranging else "counter"),
            (loop.member, loop.member_loc, "member"),
        ):
            if name is None or loc is None:
                continue
            kind = member_type if role == "member" else "int"
            var = Variable(name, role, loc, loop.loc.line, last, kind, over if ranging else "")
            self.variables.append(var)
            self.uses.append(Use(name, "variable", loc, var.key))
            inner[name] = var
        self.statements(loop.body, inner)

    # -- names ----------------------------------------------------------------------------

    def is_group(self, name: str, scope: dict[str, Variable]) -> bool:
        var = scope.get(name)
        if var is not None:
            return var.type.startswith(GROUP_PREFIX)
        return name in self.mission.groups

    def group_type(self, name: str, scope: dict[str, Variable]) -> str:
        var = scope.get(name)
        if var is not None:
            return var.type.removeprefix(GROUP_PREFIX)
        decl = self.mission.groups.get(name)
        return decl.type if decl is not None else ""

    def name(
        self, name: str, loc: SourceLocation, scope: dict[str, Variable], drones: bool
    ) -> None:
        var = scope.get(name)
        if var is not None:
            self.uses.append(Use(name, "variable", loc, var.key))
        elif name in self.mission.groups:
            self.uses.append(Use(name, "group", loc))
        elif drones and name in self.mission.drones:
            self.uses.append(Use(name, "drone", loc))

    def drone(
        self, name: str | None, pick: Member | None, loc: SourceLocation, scope: dict[str, Variable]
    ) -> None:
        if pick is not None:
            self.expr(pick, scope)
        elif name is not None and (name in scope or name in self.mission.groups):
            self.name(name, loc, scope, drones=False)

    def expr(self, expr: Expr, scope: dict[str, Variable], drones: bool = False) -> None:
        stack: list[Expr | None] = [expr]
        while stack:
            node = stack.pop()
            if isinstance(node, Name):
                self.name(node.name, node.loc, scope, drones)
            elif isinstance(node, Member | Slice):
                self.name(node.group, node.loc, scope, drones=False)
                parts = (node.index,) if isinstance(node, Member) else (node.low, node.high)
                stack.extend(parts)
            elif isinstance(node, Len):
                stack.append(node.group)
            elif isinstance(node, Prop):
                if node.pick is not None:
                    stack.append(node.pick)
                elif node.drone in scope or node.drone in self.mission.groups:
                    self.name(node.drone, node.loc, scope, drones=False)
            elif isinstance(node, Quantifier):
                stack.append(node.cond)
            elif isinstance(node, Unary):
                stack.append(node.operand)
            elif isinstance(node, Binary):
                stack.extend((node.right, node.left))


def _last_line(statements: tuple[Statement, ...], first: int) -> int:
    """The last line a body's statements reach (loops: their closing brace)."""
    last = first
    for stmt in statements:
        end = stmt.end_line if isinstance(stmt, ForLoop) and stmt.end_line else stmt.loc.line
        last = max(last, end)
    return last


def names_in_scope(mission: Mission) -> tuple[list[Variable], list[Use]]:
    """Every loop variable and parameter declared in the mission file, and every use of a
    variable, a group (and a drone passed to a block) by its statements."""
    walker = _Walker(mission)
    walker.run()
    return walker.variables, walker.uses


def in_scope(variables: list[Variable], line: int) -> Iterator[Variable]:
    """The variables in scope on ``line`` (innermost last)."""
    for var in variables:
        if var.first <= line <= var.last:
            yield var


def is_number(var: Variable) -> bool:
    """A loop counter or index, or a number parameter."""
    return var.type in NUMBER_TYPES
