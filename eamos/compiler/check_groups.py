"""Checks of groups, loops and group conditions, before anything is expanded.

The part of the checker (:mod:`.check`) for fleets::

    var Team [20]Quadcopter
    func PAR_Up() { for i, d := range Team { d.Takeoff(2 + i) } }
    ... WaitUntil(All(Team.Z() > 2), SEQ_Go) ...

A group's declaration names a known type; its members' names (``Team_3``) are
no other drone's.  A loop ranges over a group (its member variable then has
the group's type) or counts with numbers; its variables shadow nothing.  A
group condition reads exactly one group, as if it were a drone.  What depends
on values (an index out of range, a loop that never ends) is found when the
loop is expanded (:mod:`.instantiate`), located at the same place.
"""

from __future__ import annotations

import re

from ..program.uniform import GROUND_STATION, DroneType
from .check_calls import CallChecks
from .errors import SourceLocation, did_you_mean
from .syntax import (
    NUMBER_TYPES,
    WHOLE,
    Control,
    Expr,
    ForLoop,
    Name,
    Param,
    Prop,
    Quantifier,
    Slice,
    expr_text,
    member_name,
    props_in,
)

_MEMBER_NAME = re.compile(r"(.+)_(0|[1-9][0-9]*)")


class GroupChecks(CallChecks):
    """Group declarations, ``for`` loops and group conditions; mixed into the checker."""

    # The group a group condition is reading, while its condition is checked.
    quantified: str | None = None
    # The index variables of the loops over groups around a statement (``i`` of ``i, d``).
    range_indices: frozenset[str] = frozenset()

    def warn(self, loc: SourceLocation, message: str, hint: str = "") -> None:
        raise NotImplementedError  # pragma: no cover - the checker defines it

    def statement(self, stmt: object) -> None:
        raise NotImplementedError  # pragma: no cover - the checker defines it

    def unimplemented(self, drone: str, type_name: str, loc: SourceLocation) -> None:
        raise NotImplementedError  # pragma: no cover - the checker defines it

    def expr_type(self, expr: Expr) -> str | None:
        raise NotImplementedError  # pragma: no cover - the checker defines it

    # -- declarations ------------------------------------------------------------

    def group_declarations(self) -> None:
        """Each group's type is known, and no drone has one of its members' names."""
        for group in self.mission.groups.values():
            if group.type not in self.vocab.types:
                self.error(
                    group.type_loc or group.loc,
                    f"unknown drone type '{group.type}'",
                    did_you_mean(group.type, self.vocab.types),
                    len(group.type),
                )
            if group.name == GROUND_STATION:
                self.error(
                    group.loc,
                    f"'{GROUND_STATION}' is the ground station's name",
                    "name the group differently",
                )
            self.unimplemented(f"{group.name}'s members", group.type, group.type_loc or group.loc)
        for decl in self.mission.drones.values():
            member = self.member_named(decl.name)
            if member is not None:
                self.error(
                    decl.loc,
                    f"drone '{decl.name}' has the name of {member}, a member of a group",
                    f"{member} is called {decl.name} in fleet files and logs: rename the drone",
                    len(decl.name),
                )

    def member_named(self, name: str) -> str | None:
        """``Team[3]`` if ``name`` is the drone name of a declared group's member."""
        match = _MEMBER_NAME.fullmatch(name)
        if match is None:
            return None
        group = self.mission.groups.get(match.group(1))
        index = int(match.group(2))
        if group is None or index >= group.size or member_name(group.name, index) != name:
            return None
        return f"{group.name}[{index}]"

    def group_as_drone(self, name: str, loc: SourceLocation, what: str) -> bool:
        """Report (and return True) a group or a member's file name used as one drone."""
        if self.group_type(name) is not None and self.quantified != name:
            hint = (
                f"read one member, {name}[i].Z(), or all of them: All({name}.Z() > 2)"
                if what == "read"
                else f"{what} one member, {name}[i], or each: for _, d := range {name} {{ ... }}"
            )
            self.error(loc, f"'{name}' is a group of drones, not one drone", hint, len(name))
            return True
        member = self.member_named(name) if name not in self.mission.drones else None
        if member is not None and name not in self.scope:
            self.error(
                loc,
                f"'{name}' is the file name of {member}: in the mission, write {member}",
                "a group's members are named Team_3 only outside the mission text",
                len(name),
            )
            return True
        return False

    # -- loops -------------------------------------------------------------------

    def for_loop(self, loop: ForLoop) -> None:
        """A loop's header and variables, then its body with the variables in scope."""
        element = self.loop_header(loop)
        if element is False:
            return
        saved = dict(self.scope)
        if loop.index is not None and isinstance(element, DroneType):
            self.range_indices = self.range_indices | {loop.index}
        for name, loc, kind in (
            (loop.index, loop.index_loc, WHOLE),
            (loop.member, loop.member_loc, element.name if isinstance(element, DroneType) else ""),
        ):
            if name is None or loc is None or not kind:
                continue
            self.loop_variable(name, loc)
            self.scope[name] = Param(name, kind, loc)
        if not loop.body and not loop.incomplete:
            self.error(loop.loc, "this for loop is empty", "give it a statement, or remove it", 3)
        for stmt in loop.body:
            if isinstance(stmt, Control) and stmt.kind == "Whenever":
                self.error(
                    stmt.loc,
                    "Whenever in a for loop: it guards the statements after it in a SEQ_ block",
                    "call a SEQ_ block with parameters from the loop, and put the Whenever in it",
                    len("Whenever"),
                )
                continue
            self.statement(stmt)
        self.scope = saved
        if loop.index is not None:
            self.range_indices = self.range_indices - {loop.index}

    def loop_header(self, loop: ForLoop) -> DroneType | bool | None:
        """The members' type of a loop over a group, None for a counting loop, False on error."""
        over = loop.over
        if isinstance(over, Name) and self.group_type(over.name) is None:
            param = self.scope.get(over.name)
            if param is None or param.type not in NUMBER_TYPES:
                self.not_a_group(over.name, over.loc)
                return False
            # ``for i := range n``: a count read from a number in scope.
            if loop.member is not None and loop.member_loc is not None:
                self.error(
                    loop.member_loc,
                    "a range over a number gives one variable, the counter",
                    f"write for i := range {over.name}",
                )
                return False
            return None if self.numbers_only(over, "ranges over a count") else False
        if isinstance(over, Name | Slice):
            element = self.group_ref(over)
            return False if element is None else element
        parts = [e for e in (loop.start, loop.limit, loop.step) if e is not None]
        ok = all([self.numbers_only(e, "a loop's start, limit and step") for e in parts])
        return None if ok else False

    def loop_variable(self, name: str, loc: SourceLocation) -> None:
        """A loop variable may not hide a parameter, another loop's variable or a drone."""
        clash = ""
        if name in self.scope:
            clash = f"'{name}' is already a parameter or a loop variable here"
        elif name in self.mission.drones or name in self.types:
            clash = f"'{name}' is the name of a drone of the mission"
        elif name in self.mission.groups:
            clash = f"'{name}' is the name of a group of the mission"
        elif name == GROUND_STATION:
            clash = f"'{GROUND_STATION}' is the ground station's name"
        if clash:
            self.error(loc, clash, "give the loop variable another name", len(name))

    # -- group conditions ----------------------------------------------------------

    def quantifier_type(self, expr: Quantifier) -> str | None:
        """``All(...)``/``Any(...)``: 'bool'; ``Count(...)``: 'number' (None: reported)."""
        if self.quantified is not None:
            self.error(
                expr.loc,
                f"{expr.kind}(...) inside another group condition",
                "test the groups in two conditions joined by && or ||",
                len(expr.kind),
            )
            return None
        read: dict[str, Prop] = {}
        for prop in props_in(expr.cond):
            if isinstance(prop.pick, Slice) or (
                prop.pick is None and self.group_type(prop.drone) is not None
            ):
                read.setdefault(_group_text(prop), prop)
        if len(read) != 1:
            self.error(
                expr.loc,
                f"{expr.kind}(...) reads one group, as if it were a drone"
                + (f"; this one reads {', '.join(read)}" if read else ""),
                f"e.g. {expr.kind}(Team.Z() > 2): Team.Z() stands for each member's Z()",
                len(expr.kind),
            )
            return None
        prop = next(iter(read.values()))
        if isinstance(prop.pick, Slice) and self.group_ref(prop.pick) is None:
            return None
        self.quantified = prop.drone
        try:
            inner = self.expr_type(expr.cond)
        finally:
            self.quantified = None
        if inner is None:
            return None
        if inner != "bool":
            self.error(
                expr.cond.loc,
                f"{expr.kind}(...) takes a condition (true/false), not a number",
                f"compare it, e.g. {expr.kind}({_group_text(prop)}.Z() > 2)",
            )
            return None
        return "number" if expr.kind == "Count" else "bool"

    def group_read(self, prop: Prop) -> tuple[bool, DroneType | None]:
        """Whether a property read names a member, a group or part of one (``True``) or
        a drone (``False``: the checker's own case), and then the members' type (None:
        a mistake, reported)."""
        if isinstance(prop.pick, Slice):
            if self.quantified == prop.drone:
                return True, self.group_type(prop.drone)
            self.error(
                prop.loc,
                f"'{_group_text(prop)}' is several drones",
                f"read one member, {prop.drone}[i].{prop.name}(), or all of them: "
                f"All({_group_text(prop)}.{prop.name}() > 2)",
            )
            return True, None
        if prop.pick is not None:
            return True, self.member_ref(prop.pick)
        if self.quantified == prop.drone:
            return True, self.group_type(prop.drone)
        if self.group_as_drone(prop.drone, prop.loc, "read"):
            return True, None
        return False, None


def _group_text(prop: Prop) -> str:
    """How a group condition's group is written: ``Team`` or ``Team[0:10]``."""
    return expr_text(prop.pick) if isinstance(prop.pick, Slice) else prop.drone
