"""Checks of names in scope: parameters, loop variables, groups and block-call arguments.

The part of the checker (:mod:`.check`) for blocks with parameters and for groups::

    func SEQ_Hop(d Quadcopter, dist_m float64) { d.FlyByX(dist_m) }
    func PAR_Up(g []Quadcopter, h float64) { for _, d := range g { d.Takeoff(h) } }

A block's parameters and the variables of the loops around a statement are its
*scope*: a drone parameter (or a loop's member ``d``) stands for a drone whose
type must satisfy the parameter's, a ``float64`` or ``int`` (a loop counter)
for a number, a ``[]T`` for a group.  Arguments are constant expressions of
numbers and the names in scope; they are folded when the call is expanded
(:mod:`.instantiate`).  A group is named by its declaration ``Team``, a part of
it ``Team[a:b]`` or a group parameter; one member is ``Team[i]``.
"""

from __future__ import annotations

from collections.abc import Iterator

from ..program.uniform import DEFAULT_DRONE_TYPE, DRONE_TYPES, GROUND_STATION, DroneType
from .constants import FoldError, fold_value, is_constant
from .drone_types import Vocabulary
from .errors import Diagnostic, SourceLocation, did_you_mean
from .limits import MAX_PARAMS
from .syntax import (
    GROUP_PREFIX,
    NUMBER_TYPES,
    Binary,
    Block,
    BlockCall,
    BlockRef,
    Control,
    Expr,
    Len,
    Member,
    Mission,
    Name,
    Param,
    Slice,
    Statement,
    Unary,
    scoped_statements,
)


def signature(block: Block) -> str:
    """``SEQ_Hop(d Quadcopter, dist_m float64)``, as messages show a block."""
    return f"{block.name}(" + ", ".join(f"{p.name} {p.type}" for p in block.params) + ")"


def is_group_type(kind: str) -> bool:
    """True for a group parameter's type, ``[]Quadcopter``."""
    return kind.startswith(GROUP_PREFIX)


def _shown(expr: Expr) -> str:
    """A group or member as messages name it."""
    if isinstance(expr, Member):
        return f"{expr.group}[...]"
    if isinstance(expr, Slice):
        return f"{expr.group}[...:...]"
    return expr.name if isinstance(expr, Name) else "this"


def _terms(expr: Expr) -> Iterator[Expr]:
    """Every sub-expression of an argument, outermost first (iteratively)."""
    stack: list[Expr] = [expr]
    while stack:
        current = stack.pop()
        yield current
        if isinstance(current, Unary):
            stack.append(current.operand)
        elif isinstance(current, Binary):
            stack.extend((current.right, current.left))


class CallChecks:
    """Scopes, groups and block calls; mixed into the checker, which provides the state."""

    mission: Mission
    vocab: Vocabulary
    types: dict[str, DroneType]
    diags: list[Diagnostic]
    scope: dict[str, Param]

    def error(self, loc: SourceLocation, message: str, hint: str = "", width: int = 1) -> None:
        raise NotImplementedError  # pragma: no cover - the checker defines it

    def enter(self, block: Block) -> None:
        """Start checking ``block``: its parameters become the names in scope."""
        self.scope = {p.name: p for p in block.params}
        if len(block.params) > MAX_PARAMS:
            self.error(
                block.params[MAX_PARAMS].loc,
                f"block '{block.name}' has more than {MAX_PARAMS} parameters",
                "split it into smaller blocks",
            )
        for param in block.params:
            element = param.type.removeprefix(GROUP_PREFIX)
            if param.type not in NUMBER_TYPES and element not in self.vocab.types:
                self.error(
                    param.type_loc or param.loc,
                    f"unknown parameter type '{param.type}'",
                    did_you_mean(param.type, [*NUMBER_TYPES, *self.vocab.types]),
                    len(param.type),
                )
            if param.name in self.mission.drones or param.name in self.mission.groups:
                what = "a drone" if param.name in self.mission.drones else "a group"
                self.error(
                    param.loc,
                    f"parameter '{param.name}' has the name of {what} of the mission",
                    "rename the parameter",
                )
        if block.params and block.name == self.mission.entry:
            self.error(
                block.params[0].loc,
                f"block '{block.name}' takes no parameters",
                "it is where the mission starts; call a block with parameters from it",
            )

    # -- what a name stands for ---------------------------------------------------

    def drone_param(self, name: str) -> DroneType | None:
        """The type of a drone parameter (or loop member) in scope; None if not one."""
        param = self.scope.get(name)
        if param is None or param.type in NUMBER_TYPES or is_group_type(param.type):
            return None
        return self.vocab.types.get(param.type, DRONE_TYPES[DEFAULT_DRONE_TYPE])

    def group_type(self, name: str) -> DroneType | None:
        """The members' type of the group ``name`` here (a group parameter or a declared
        group), or None if ``name`` is not a group."""
        param = self.scope.get(name)
        if param is not None:
            if not is_group_type(param.type):
                return None
            element = param.type.removeprefix(GROUP_PREFIX)
        elif name in self.mission.groups:
            element = self.mission.groups[name].type
        else:
            return None
        return self.vocab.types.get(element, DRONE_TYPES[DEFAULT_DRONE_TYPE])

    def group_size(self, name: str) -> int | None:
        """A declared group's size (None for a group parameter: known once expanded)."""
        if name in self.scope or name not in self.mission.groups:
            return None
        return self.mission.groups[name].size

    def not_a_group(self, name: str, loc: SourceLocation) -> None:
        known = [*self.mission.groups, *(p for p, v in self.scope.items() if is_group_type(v.type))]
        hint = did_you_mean(name, known) if known else ""
        self.error(
            loc,
            f"'{name}' is not a group of drones",
            hint or "declare one: var Team [10]Quadcopter",
            len(name),
        )

    def member_ref(self, member: Member) -> DroneType | None:
        """``Team[i]``: the members' type, once the group and index are checked (or None)."""
        dtype = self.group_type(member.group)
        if dtype is None:
            self.not_a_group(member.group, member.loc)
            return None
        if not self.numbers_only(member.index, "indices"):
            return None
        size = self.group_size(member.group)
        if size is not None and is_constant(member.index):
            self.index_in_range(member.index, size, member.group, inclusive=False)
        return dtype

    def group_ref(self, ref: Name | Slice) -> DroneType | None:
        """``Team``, ``g`` or ``Team[a:b]``: the members' type (or None, reported)."""
        dtype = self.group_type(ref.group if isinstance(ref, Slice) else ref.name)
        if dtype is None:
            self.not_a_group(ref.group if isinstance(ref, Slice) else ref.name, ref.loc)
            return None
        if isinstance(ref, Slice):
            size = self.group_size(ref.group)
            for bound in (ref.low, ref.high):
                if bound is None or not self.numbers_only(bound, "the bounds of a part of a group"):
                    continue
                if size is not None and is_constant(bound):
                    self.index_in_range(bound, size, ref.group, inclusive=True)
        return dtype

    def index_in_range(self, expr: Expr, size: int, group: str, *, inclusive: bool) -> None:
        """A constant index (``inclusive``: a slice bound, may equal the size) of a group."""
        try:
            value = fold_value(expr, {})
        except FoldError as exc:
            self.error(exc.loc, str(exc))
            return
        top = size if inclusive else size - 1
        if not float(value).is_integer() or not 0 <= value <= top:
            self.error(
                expr.loc,
                f"index {value:g} is outside {group}, whose members are {group}[0] .. "
                f"{group}[{size - 1}]",
                "an index is a whole number from 0 to the group's size minus one",
            )

    def numbers_only(self, expr: Expr, what: str) -> bool:
        """Report every name in ``expr`` that is not a number in scope (and bad ``len``)."""
        ok = True
        for term in _terms(expr):
            if isinstance(term, Len):
                ok = self.group_ref(term.group) is not None and ok
            elif isinstance(term, Member | Slice):
                ok = False
                self.error(
                    term.loc,
                    f"'{_shown(term)}' is {'a drone' if isinstance(term, Member) else 'a group'}, "
                    "not a number",
                    f"{what} are numbers",
                )
            elif isinstance(term, Name):
                ok = self._number_name(term, what) and ok
        return ok

    def _number_name(self, name: Name, what: str) -> bool:
        param = self.scope.get(name.name)
        if param is not None and param.type in NUMBER_TYPES:
            return True
        if self.group_type(name.name) is not None:
            message = f"'{name.name}' is a group of drones, not a number"
        elif param is not None:
            message = f"'{name.name}' is a drone ({param.type}), not a number"
        elif name.name in self.types:
            message = f"'{name.name}' is a drone ({self.types[name.name].name}), not a number"
        else:
            numbers = [p.name for p in self.scope.values() if p.type in NUMBER_TYPES]
            hint = did_you_mean(name.name, numbers) if numbers else ""
            self.error(
                name.loc,
                f"unknown name '{name.name}'",
                hint or f"{what} are numbers, or the block's number parameters and loop counters",
                len(name.name),
            )
            return False
        self.error(name.loc, message, f"{what} are numbers", len(name.name))
        return False

    # -- block calls ---------------------------------------------------------------

    def block_call(self, call: BlockCall) -> None:
        """A call's callee exists and its arguments fit the callee's parameters."""
        callee = self.mission.blocks.get(call.name)
        if callee is None:
            return  # reported as an undefined block
        if len(call.args) != len(callee.params):
            want = len(callee.params)
            self.error(
                call.loc,
                f"{call.name} takes {want} argument{'s' if want != 1 else ''}, "
                f"got {len(call.args)}",
                signature(callee),
                len(call.name),
            )
            return
        for arg, param in zip(call.args, callee.params, strict=True):
            if param.type in NUMBER_TYPES:
                self.numbers_only(arg, f"the arguments of {call.name}")
            elif is_group_type(param.type):
                self.group_argument(call, arg, param)
            else:
                self.drone_argument(call, arg, param)

    def _satisfies(
        self, call: BlockCall, arg: Expr, shown: str, have: DroneType, param: Param
    ) -> None:
        want = self.vocab.types.get(param.type.removeprefix(GROUP_PREFIX))
        if want is None:
            return  # an unknown type, reported at its declaration
        missing = self.vocab.missing(have, want)
        if missing:
            listed = ", ".join(missing[:6]) + (" ..." if len(missing) > 6 else "")
            members = "'s members" if is_group_type(param.type) else ""
            self.error(
                arg.loc,
                f"{shown}{members} ({have.name}) {'are' if members else 'is'} not "
                f"{'' if members else 'a '}{want.name}: {'they have' if members else 'it has'} "
                f"no {listed}",
                f"{call.name} needs {'a group of ' if members else 'a drone of type '}"
                f"{want.name}, or one that embeds it",
                len(shown) if isinstance(arg, Name) else 1,
            )

    def drone_argument(self, call: BlockCall, arg: Expr, param: Param) -> None:
        """A drone argument names a drone whose type satisfies the parameter's."""
        if isinstance(arg, Member):
            have: DroneType | None = self.member_ref(arg)
            if have is not None:
                self._satisfies(call, arg, f"{arg.group}[...]", have, param)
            return
        if not isinstance(arg, Name):
            self.error(
                arg.loc,
                f"{call.name}'s parameter '{param.name}' is a drone ({param.type})",
                "pass a drone by its name, e.g. Drone1, or a group's member, Team[i]",
            )
            return
        have = self.drone_param(arg.name)
        if have is None:
            if arg.name in self.scope and not is_group_type(self.scope[arg.name].type):
                self.error(arg.loc, f"'{arg.name}' is a number, not a drone", "", len(arg.name))
                return
            if self.group_type(arg.name) is not None:
                self.error(
                    arg.loc,
                    f"'{arg.name}' is a group; {call.name}'s parameter '{param.name}' is one "
                    f"drone ({param.type})",
                    f"pass one member, {arg.name}[i], or loop: for _, d := range {arg.name}",
                    len(arg.name),
                )
                return
            if arg.name == GROUND_STATION:
                self.error(arg.loc, f"the ground station '{GROUND_STATION}' does not fly")
                return
            have = self.types.get(arg.name)
        if have is not None:
            self._satisfies(call, arg, arg.name, have, param)

    def group_argument(self, call: BlockCall, arg: Expr, param: Param) -> None:
        """A group argument names a group whose members' type satisfies the parameter's."""
        if not isinstance(arg, Name | Slice) or (
            isinstance(arg, Name) and self.group_type(arg.name) is None
        ):
            self.error(
                arg.loc,
                f"{call.name}'s parameter '{param.name}' is a group ({param.type})",
                "pass a group by its name, e.g. Team, or a part of it, Team[0:10]",
            )
            return
        have = self.group_ref(arg)
        if have is not None:
            self._satisfies(call, arg, _shown(arg), have, param)


def _calls(stmt: Statement) -> list[BlockCall | BlockRef]:
    """The block calls of a statement: a call, or a control structure's blocks."""
    if isinstance(stmt, BlockCall):
        return [stmt]
    if isinstance(stmt, Control):
        return [r for r in (stmt.body, stmt.orelse, stmt.exit) if r is not None]
    return []


def drone_arguments(mission: Mission) -> list[tuple[Name, str]]:
    """Each name passed to a drone parameter by a call, with its block (to find drones).

    Names in scope there (parameters, loop variables) and groups are left out.
    """
    out: list[tuple[Name, str]] = []
    for block in mission.blocks.values():
        params = {p.name for p in block.params}
        for stmt, loops in scoped_statements(block.statements):
            for call in _calls(stmt):
                if not call.args:
                    continue
                callee = mission.blocks.get(call.name)
                if callee is None or len(callee.params) != len(call.args):
                    continue
                for arg, param in zip(call.args, callee.params, strict=True):
                    if (
                        param.type not in NUMBER_TYPES
                        and not is_group_type(param.type)
                        and isinstance(arg, Name)
                        and arg.name not in params
                        and arg.name not in loops
                        and arg.name not in mission.groups
                    ):
                        out.append((arg, block.name))
    return out
