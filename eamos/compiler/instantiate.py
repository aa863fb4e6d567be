"""Expanding blocks with parameters, loops and groups: a mission of plain blocks.

After the checks, every call of a block with parameters, ``SEQ_Hop(D1, 5)``,
is replaced by a call of a copy of the block with its parameters replaced by
the call's values (a drone's name, a number, a group): the copy is named
``SEQ_Hop(D1, 5)``, its action arguments are folded to numbers
(:mod:`.constants`), and its conditions read the given drone.  Calls with the
same values share one copy.

Every ``for`` loop is written out into its iterations, with its variables'
values put in (:mod:`.bindings`): in a ``SEQ_`` block, the iterations' statements
follow each other in place; in a ``PAR_`` block each iteration is one parallel
branch, its statements in order (an iteration of several statements becomes a
``SEQ`` block named ``PAR_Block[i=3]``, one of a single statement stays that
statement).  A group's member ``Team[3]`` becomes the drone ``Team_3``, a group
condition ``All(Team.Z() > 2)`` one condition over the members.  The mission that
comes out has no parameters, loops or groups left: the mission tree, the graphs and
the runtime are those of a mission written out by hand.

The expansion is a work list (no recursion but the loops' nesting, capped by
:data:`~.limits.MAX_LOOP_DEPTH`), it follows the checked block calls, which are
acyclic, and it counts: the loops run at most :data:`~.limits.MAX_TREE_NODES`
iterations and write at most that many statements, and the copies of blocks are
at most that many, so no file can make it exhaust the memory.  An error found
here is located in the mission (``file:line:col``) and names the copy and the
iteration it happens in (``in SEQ_Hop(D1, 0), iteration i=3``).
"""

from __future__ import annotations

import dataclasses
import operator
from collections.abc import Callable

from ..program.uniform import ACTIONS
from .bindings import Binding, Group, Resolver
from .check import argument_problem
from .constants import FoldError, Value, show
from .errors import Diagnostic, SourceLocation
from .limits import MAX_REPEAT, MAX_TREE_NODES, amount
from .syntax import (
    NUMBER,
    WHOLE,
    ActionCall,
    Block,
    BlockCall,
    BlockRef,
    Control,
    DroneDecl,
    Expr,
    ForLoop,
    Member,
    Mission,
    Name,
    Slice,
    Statement,
    expansion_needed,
)

_COMPARE: dict[str, Callable[[Value, Value], bool]] = {
    "<": operator.lt,
    "<=": operator.le,
    ">": operator.gt,
    ">=": operator.ge,
    "!=": operator.ne,
}


class _Stop(Exception):
    """The expansion went over a limit (reported): nothing more is written."""


class _Expander:
    def __init__(self, mission: Mission) -> None:
        self.mission = mission
        self.out: dict[str, Block] = {}
        self.todo: list[tuple[str, Block, Binding]] = []
        self.diags: list[Diagnostic] = []
        # Where an error was reported, and how many more times it recurred (loops).
        self.reported: dict[tuple[str, int, int], int] = {}
        self.repeats: dict[int, int] = {}
        self.iterations = 0
        self.written = 0

    def run(self) -> Mission:
        try:
            for name, block in self.mission.blocks.items():
                if not block.params:
                    self.out[name] = self.copy(block, name, Binding())
            while self.todo:
                name, block, binding = self.todo.pop()
                self.out[name] = self.copy(block, name, binding)
        except _Stop:
            pass
        for index, more in self.repeats.items():
            d = self.diags[index]
            again = "once more" if more == 1 else f"{more} more times"
            self.diags[index] = dataclasses.replace(
                d, hint=f"{d.hint} (and {again} in other iterations)".lstrip()
            )
        drones = dict(self.mission.drones)
        for group in self.mission.groups.values():
            for member in Group.declared(group).members:
                drones[member] = DroneDecl(
                    member, group.type, group.loc, group.type_loc, group.name
                )
        return dataclasses.replace(self.mission, blocks=self.out, drones=drones)

    # -- reporting -----------------------------------------------------------------

    def error(self, loc: SourceLocation, message: str, b: Binding, hint: str = "") -> None:
        """Report once per place: the same mistake in every iteration is one error."""
        key = (loc.file, loc.line, loc.col)
        if key in self.reported:
            index = self.reported[key]
            self.repeats[index] = self.repeats.get(index, 0) + 1
            return
        self.reported[key] = len(self.diags)
        where = b.where()
        hint = f"{hint} ({where})" if hint and where else hint or where
        self.diags.append(Diagnostic("error", loc, message, hint))

    def failed(self, exc: FoldError, b: Binding) -> None:
        self.error(exc.loc, str(exc), b)

    def spend(
        self, loc: SourceLocation, b: Binding, *, iterations: int = 0, statements: int = 0
    ) -> None:
        """Count what the expansion does; over the cap, report once and stop expanding."""
        self.iterations += iterations
        self.written += statements
        if self.iterations > MAX_TREE_NODES:
            message = f"the loops run more than {amount(MAX_TREE_NODES)} iterations"
        elif self.written > MAX_TREE_NODES:
            message = (
                f"the loops and block copies write out more than {amount(MAX_TREE_NODES)} "
                "statements"
            )
        else:
            return
        self.error(
            loc,
            message,
            b,
            "loop over fewer drones or numbers; the limit is the mission tree's",
        )
        raise _Stop

    # -- blocks --------------------------------------------------------------------

    def copy(self, block: Block, name: str, b: Binding) -> Block:
        errors = len(self.diags)
        statements = self.statements(block.statements, name, block.mode, b)
        if not statements and block.statements and len(self.diags) == errors:
            loops = [s for s in block.statements if isinstance(s, ForLoop)]
            if loops and len(loops) == len(block.statements):
                self.error(
                    block.loc,
                    f"block '{name}' is empty once its loops are written out",
                    b,
                    f"the loop at line {loops[0].loc.line} runs no iteration",
                )
        return dataclasses.replace(block, name=name, params=(), statements=tuple(statements))

    def statements(
        self, stmts: tuple[Statement, ...], name: str, mode: str, b: Binding
    ) -> list[Statement]:
        out: list[Statement] = []
        for stmt in stmts:
            if isinstance(stmt, ForLoop):
                out.extend(self.loop(stmt, name, mode, b))
                continue
            done = self.statement(stmt, b)
            if done is not None:
                self.spend(stmt.loc, b, statements=1)
                out.append(done)
        return out

    def statement(self, stmt: Statement, b: Binding) -> Statement | None:
        if isinstance(stmt, ActionCall):
            return self.action(stmt, b)
        if isinstance(stmt, BlockCall):
            return self.call(stmt, b)
        if isinstance(stmt, Control):
            return self.control(stmt, b)
        return stmt  # pragma: no cover - loops are written out by statements()

    # -- loops ---------------------------------------------------------------------

    def loop(self, loop: ForLoop, name: str, mode: str, b: Binding) -> list[Statement]:
        """A loop's iterations: in place (SEQ), or one parallel branch each (PAR)."""
        iterations = self.iterations_of(loop, b)
        out: list[Statement] = []
        for label, inner in iterations:
            body = self.statements(loop.body, name, "SEQ", inner)
            if mode == "SEQ" or len(body) <= 1:
                out.extend(body)
                continue
            branch = self.branch_name(name, label, loop)
            self.out[branch] = Block(branch, "SEQ", tuple(body), loop.loc)
            out.append(BlockCall(branch, loop.loc))
        return out

    def branch_name(self, block: str, label: str, loop: ForLoop) -> str:
        """``PAR_Up[i=3]``: the block of one iteration (the loop's place if that is taken)."""
        name = f"{block}[{label}]"
        if name in self.out or name in self.mission.blocks:
            name = f"{block}[line {loop.loc.line}:{loop.loc.col} {label}]"
        return name

    def iterations_of(self, loop: ForLoop, b: Binding) -> list[tuple[str, Binding]]:
        """Each iteration's label (``i=3``) and binding, or none if the loop is wrong here."""
        resolver = Resolver(self.mission.groups, b)
        try:
            if loop.over is not None and self.is_group(loop.over, b):
                group = resolver.group(loop.over)
                self.spend(loop.loc, b, iterations=len(group.members))
                return [
                    self.iteration(loop, b, k, member) for k, member in enumerate(group.members)
                ]
            counts = self.counter_values(loop, resolver)
        except FoldError as exc:
            self.failed(exc, b)
            return []
        return [self.iteration(loop, b, value, None, k) for k, value in enumerate(counts)]

    def is_group(self, over: Name | Slice, b: Binding) -> bool:
        if isinstance(over, Slice):
            return True
        return over.name in b.groups or (
            over.name in self.mission.groups and over.name not in b.numbers
        )

    def iteration(
        self, loop: ForLoop, b: Binding, value: Value, member: str | None, k: int | None = None
    ) -> tuple[str, Binding]:
        numbers: dict[str, Value] = {loop.index: value} if loop.index else {}
        drones = {loop.member: member} if loop.member and member is not None else {}
        if loop.index:
            label = f"{loop.index}={show(value)}"
        elif loop.member and member is not None:
            label = f"{loop.member}={member}"
        else:
            label = f"#{value if k is None else k}"
        return label, b.inside(label, numbers, drones)

    def counter_values(self, loop: ForLoop, resolver: Resolver) -> list[Value]:
        """The values a counting loop's counter takes (raises FoldError)."""
        over = loop.over
        start: Value
        step: Value
        if isinstance(over, Name):  # ``for i := range n``
            start, limit, step, op = 0, resolver.number(over), 1, "<"
        else:
            assert loop.start is not None and loop.limit is not None and loop.step is not None
            start = resolver.number(loop.start)
            limit, step = resolver.number(loop.limit), resolver.number(loop.step)
            op = loop.op
        if isinstance(start, int) and isinstance(step, float) and step.is_integer():
            step = int(step)
        if isinstance(step, float) or isinstance(start, float):
            start, step = float(start), float(step)
        holds = _COMPARE[op]
        if holds(start, limit) and (step == 0 or not _approaches(start, limit, step, op)):
            where = loop.limit.loc if loop.limit is not None else loop.loc
            moves = "stays" if step == 0 else "moves away from"
            raise FoldError(
                f"this loop never ends: its counter {moves} {show(limit)} "
                f"(from {show(start)}, step {show(step)})",
                where,
            )
        values: list[Value] = []
        value = start
        while holds(value, limit):
            values.append(value)
            if self.iterations + len(values) > MAX_TREE_NODES:
                break  # one past the cap: spend() reports it
            value = value + step
        self.spend(loop.loc, resolver.b, iterations=len(values))
        return values

    # -- statements ------------------------------------------------------------------

    def action(self, call: ActionCall, b: Binding) -> ActionCall | None:
        resolver = Resolver(self.mission.groups, b)
        try:
            drone = resolver.drone(call.drone, call.pick) if call.drone is not None else None
        except FoldError as exc:
            self.failed(exc, b)
            return None
        if not call.exprs:
            if drone == call.drone and call.pick is None:
                return call
            return dataclasses.replace(call, drone=drone, pick=None)
        values: list[float] = []
        spec = ACTIONS.get(call.action)
        for i, expr in enumerate(call.exprs):
            try:
                value = float(resolver.number(expr))
            except FoldError as exc:
                self.failed(exc, b)
                return None
            loc = call.arg_locs[i] if i < len(call.arg_locs) else call.loc
            problem = argument_problem(call.action, spec.params[i], value) if spec else ""
            if problem:
                self.error(loc, problem, b)
                return None
            values.append(value)
        return dataclasses.replace(call, drone=drone, args=tuple(values), exprs=(), pick=None)

    def call(self, call: BlockCall, b: Binding) -> BlockCall | None:
        if not call.args:
            return call
        name = self.instance(call.name, call.args, call.loc, b)
        return None if name is None else BlockCall(name, call.loc)

    def control(self, ctl: Control, b: Binding) -> Control | None:
        refs: list[BlockRef | None] = []
        for ref in (ctl.body, ctl.orelse, ctl.exit):
            if ref is not None and ref.args:
                name = self.instance(ref.name, ref.args, ref.loc, b)
                if name is None:
                    return None
                ref = BlockRef(name, ref.loc)
            refs.append(ref)
        resolver = Resolver(self.mission.groups, b)
        count = ctl.count
        try:
            drone = resolver.drone(ctl.drone, ctl.pick) if ctl.drone is not None else None
            cond, text = resolver.condition(ctl.cond) if ctl.cond is not None else (None, "")
            if ctl.count_expr is not None:
                count = self.repeat_count(ctl.count_expr, resolver)
        except FoldError as exc:
            self.failed(exc, b)
            return None
        return dataclasses.replace(
            ctl,
            drone=drone,
            pick=None,
            cond=cond,
            text=text,
            body=refs[0],
            orelse=refs[1],
            exit=refs[2],
            count=count,
            count_expr=None,
        )

    def repeat_count(self, expr: Expr, resolver: Resolver) -> int:
        value = resolver.number(expr)
        if value != int(value) or not 0 <= value <= MAX_REPEAT:
            raise FoldError(
                f"RepeatFor repeats a whole number of times, 0 to {MAX_REPEAT}; got {show(value)}",
                expr.loc,
            )
        return int(value)

    def instance(
        self, block: str, args: tuple[Expr, ...], loc: SourceLocation, b: Binding
    ) -> str | None:
        """The name of the copy of ``block`` for these arguments (made if new), or None."""
        callee = self.mission.blocks[block]
        resolver = Resolver(self.mission.groups, b)
        bound = Binding()
        shown: list[str] = []
        for arg, param in zip(args, callee.params, strict=True):
            try:
                shown.append(self.argument(arg, param.name, param.type, resolver, bound))
            except FoldError as exc:
                self.failed(exc, b)
                return None
        name = f"{block}({', '.join(shown)})"
        if name not in self.out:
            if len(self.out) >= MAX_TREE_NODES:
                self.error(
                    loc,
                    f"the calls make more than {amount(MAX_TREE_NODES)} copies of blocks",
                    b,
                    "call blocks with parameters with fewer different values",
                )
                raise _Stop
            # Reserve the name so that later calls with the same values share the copy.
            self.out[name] = callee
            self.todo.append((name, callee, dataclasses.replace(bound, copy=name)))
        return name

    def argument(self, arg: Expr, param: str, kind: str, resolver: Resolver, bound: Binding) -> str:
        """Bind one parameter of a copy (into ``bound``); how the copy's name shows it."""
        if kind == NUMBER:
            bound.numbers[param] = float(resolver.number(arg))
            return show(bound.numbers[param])
        if kind == WHOLE:
            bound.numbers[param] = resolver.whole(arg, f"parameter '{param}' (int)")
            return str(bound.numbers[param])
        if isinstance(arg, Slice) or (isinstance(arg, Name) and kind.startswith("[]")):
            group = resolver.group(arg)
            bound.groups[param] = group
            return group.shown
        if isinstance(arg, Member):
            bound.drones[param] = resolver.member(arg)
        else:
            assert isinstance(arg, Name)  # checked
            bound.drones[param] = resolver.drone(arg.name, None)
        return bound.drones[param]


def _approaches(start: Value, limit: Value, step: Value, op: str) -> bool:
    """True if adding ``step`` moves the counter toward making ``op`` false."""
    if op in ("<", "<="):
        return step > 0
    if op in (">", ">="):
        return step < 0
    return (limit - start) * step > 0 and (limit - start) % step == 0  # "!=": must hit it


def instantiate(mission: Mission) -> tuple[Mission, list[Diagnostic]]:
    """The mission with every call of a block with parameters, every loop and every group
    expanded, and any errors.  A mission without them comes back unchanged."""
    if not expansion_needed(mission):
        return mission, []
    expander = _Expander(mission)
    expanded = expander.run()
    return expanded, expander.diags
