"""Expanding blocks with parameters: one plain block per distinct call.

After the checks, every call of a block with parameters, ``SEQ_Hop(D1, 5)``,
is replaced by a call of a copy of the block with its parameters replaced by
the call's values (a drone's name, a number): the copy is named
``SEQ_Hop(D1, 5)``, its action arguments are folded to numbers
(:func:`~.constants.fold`), and its conditions read the given drone.  Calls
with the same values share one copy.  The mission that comes out has no
parameters left, so the mission tree, the graphs and the runtime are those of
a mission written out by hand.

The expansion is a work list (no recursion), and it follows the checked block
calls, which are acyclic and whose expanded size is within
:data:`~.limits.MAX_TREE_NODES`: the copies it makes are at most that many.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from ..program.uniform import ACTIONS
from .check import argument_problem
from .constants import FoldError, fold, show
from .drone_types import NUMBER
from .errors import Diagnostic, SourceLocation
from .limits import MAX_REPEAT, MAX_TREE_NODES, amount
from .syntax import (
    ActionCall,
    Binary,
    Block,
    BlockCall,
    BlockRef,
    Control,
    Expr,
    Mission,
    Name,
    Num,
    Prop,
    Statement,
    Unary,
)


@dataclass(frozen=True)
class _Binding:
    """What a copy's parameters stand for."""

    drones: dict[str, str] = field(default_factory=dict)
    numbers: dict[str, float] = field(default_factory=dict)


class _Expander:
    def __init__(self, mission: Mission) -> None:
        self.mission = mission
        self.out: dict[str, Block] = {}
        self.todo: list[tuple[str, Block, _Binding]] = []
        self.diags: list[Diagnostic] = []

    def run(self) -> Mission:
        for name, block in self.mission.blocks.items():
            if not block.params:
                self.out[name] = self.copy(block, name, _Binding())
        while self.todo:
            name, block, binding = self.todo.pop()
            self.out[name] = self.copy(block, name, binding)
        return dataclasses.replace(self.mission, blocks=self.out)

    def copy(self, block: Block, name: str, binding: _Binding) -> Block:
        statements = [self.statement(s, name, binding) for s in block.statements]
        return dataclasses.replace(
            block,
            name=name,
            params=(),
            statements=tuple(s for s in statements if s is not None),
        )

    def statement(self, stmt: Statement, where: str, b: _Binding) -> Statement | None:
        if isinstance(stmt, ActionCall):
            return self.action(stmt, where, b)
        if isinstance(stmt, BlockCall):
            return self.call(stmt, where, b)
        if isinstance(stmt, Control):
            return self.control(stmt, where, b)
        return stmt  # pragma: no cover - the statements are the three above

    def control(self, ctl: Control, where: str, b: _Binding) -> Control | None:
        refs: list[BlockRef | None] = []
        for ref in (ctl.body, ctl.orelse, ctl.exit):
            if ref is not None and ref.args:
                name = self.instance(ref.name, ref.args, ref.loc, where, b)
                if name is None:
                    return None
                ref = BlockRef(name, ref.loc)
            refs.append(ref)
        count = ctl.count
        if ctl.count_expr is not None:
            try:
                value = fold(ctl.count_expr, b.numbers)
            except FoldError as exc:
                self.diags.append(Diagnostic("error", exc.loc, str(exc), f"in {where}"))
                return None
            if value != int(value) or not 0 <= value <= MAX_REPEAT:
                self.diags.append(
                    Diagnostic(
                        "error",
                        ctl.count_expr.loc,
                        f"RepeatFor repeats a whole number of times, 0 to {MAX_REPEAT}; "
                        f"got {show(value)}",
                        f"in {where}",
                    )
                )
                return None
            count = int(value)
        return dataclasses.replace(
            ctl,
            drone=b.drones.get(ctl.drone, ctl.drone) if ctl.drone else ctl.drone,
            cond=None if ctl.cond is None else _bind(ctl.cond, b),
            body=refs[0],
            orelse=refs[1],
            exit=refs[2],
            count=count,
            count_expr=None,
        )

    def action(self, call: ActionCall, where: str, b: _Binding) -> ActionCall | None:
        drone = b.drones.get(call.drone, call.drone) if call.drone else call.drone
        if not call.exprs:
            return call if drone == call.drone else dataclasses.replace(call, drone=drone)
        values: list[float] = []
        spec = ACTIONS.get(call.action)
        for i, expr in enumerate(call.exprs):
            try:
                value = fold(expr, b.numbers)
            except FoldError as exc:
                self.diags.append(Diagnostic("error", exc.loc, str(exc), f"in {where}"))
                return None
            loc = call.arg_locs[i] if i < len(call.arg_locs) else call.loc
            problem = argument_problem(call.action, spec.params[i], value) if spec else ""
            if problem:
                self.diags.append(Diagnostic("error", loc, problem, f"in {where}"))
                return None
            values.append(value)
        return dataclasses.replace(call, drone=drone, args=tuple(values), exprs=())

    def call(self, call: BlockCall, where: str, b: _Binding) -> BlockCall | None:
        if not call.args:
            return call
        name = self.instance(call.name, call.args, call.loc, where, b)
        return None if name is None else BlockCall(name, call.loc)

    def instance(
        self, block: str, args: tuple[Expr, ...], loc: SourceLocation, where: str, b: _Binding
    ) -> str | None:
        """The name of the copy of ``block`` for these arguments (made if new), or None."""
        callee = self.mission.blocks[block]
        drones: dict[str, str] = {}
        numbers: dict[str, float] = {}
        shown: list[str] = []
        for arg, param in zip(args, callee.params, strict=True):
            if param.type == NUMBER:
                try:
                    numbers[param.name] = fold(arg, b.numbers)
                except FoldError as exc:
                    self.diags.append(Diagnostic("error", exc.loc, str(exc), f"in {where}"))
                    return None
                shown.append(show(numbers[param.name]))
            else:
                assert isinstance(arg, Name)  # checked
                drones[param.name] = b.drones.get(arg.name, arg.name)
                shown.append(drones[param.name])
        name = f"{block}({', '.join(shown)})"
        if name not in self.out:
            if len(self.out) >= MAX_TREE_NODES:
                self.diags.append(
                    Diagnostic(
                        "error",
                        loc,
                        f"the calls make more than {amount(MAX_TREE_NODES)} copies of blocks",
                        "call blocks with parameters with fewer different values",
                    )
                )
                return None
            # Reserve the name so that later calls with the same values share the copy.
            self.out[name] = callee
            self.todo.append((name, callee, _Binding(drones, numbers)))
        return name


def _bind(expr: Expr, b: _Binding) -> Expr:
    """A condition with its parameters replaced (depth bounded by the parser's limit)."""
    if isinstance(expr, Name):
        return Num(b.numbers.get(expr.name, 0.0), expr.loc)
    if isinstance(expr, Prop):
        return dataclasses.replace(expr, drone=b.drones.get(expr.drone, expr.drone))
    if isinstance(expr, Unary):
        return dataclasses.replace(expr, operand=_bind(expr.operand, b))
    if isinstance(expr, Binary):
        return dataclasses.replace(expr, left=_bind(expr.left, b), right=_bind(expr.right, b))
    return expr


def instantiate(mission: Mission) -> tuple[Mission, list[Diagnostic]]:
    """The mission with every call of a block with parameters expanded, and any errors.

    A mission without parameters comes back unchanged.
    """
    if not any(block.params for block in mission.blocks.values()):
        return mission, []
    expander = _Expander(mission)
    expanded = expander.run()
    return expanded, expander.diags
