"""Checks of parameterised blocks: parameters, block-call arguments, drone types.

The part of the checker (:mod:`.check`) for blocks with parameters::

    func SEQ_Hop(d Quadcopter, dist_m float64) { d.FlyByX(dist_m) }

A block's parameters are its *scope*: a drone parameter stands for the
caller's drone (whose type must satisfy the parameter's), a ``float64`` for a
number.  Arguments are constant expressions of numbers and the caller's own
number parameters; they are folded when the call is expanded
(:mod:`.instantiate`).
"""

from __future__ import annotations

from ..program.uniform import DRONE_TYPES, GROUND_STATION, DroneType
from .constants import names_in
from .drone_types import NUMBER, Vocabulary
from .errors import Diagnostic, SourceLocation, did_you_mean
from .limits import MAX_PARAMS
from .syntax import Block, BlockCall, BlockRef, Control, Expr, Mission, Name, Param, Statement


def signature(block: Block) -> str:
    """``SEQ_Hop(d Quadcopter, dist_m float64)``, as messages show a block."""
    return f"{block.name}(" + ", ".join(f"{p.name} {p.type}" for p in block.params) + ")"


class CallChecks:
    """Scopes and block calls; mixed into the checker, which provides the state below."""

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
            if param.type != NUMBER and param.type not in self.vocab.types:
                self.error(
                    param.type_loc or param.loc,
                    f"unknown parameter type '{param.type}'",
                    did_you_mean(param.type, [NUMBER, *self.vocab.types]),
                    len(param.type),
                )
            if param.name in self.mission.drones:
                self.error(
                    param.loc,
                    f"parameter '{param.name}' has the name of a drone of the mission",
                    "rename the parameter",
                )
        if block.params and block.name == self.mission.entry:
            self.error(
                block.params[0].loc,
                f"block '{block.name}' takes no parameters",
                "it is where the mission starts; call a block with parameters from it",
            )

    def drone_param(self, name: str) -> DroneType | None:
        """The type of a drone parameter in scope (None if ``name`` is not one)."""
        param = self.scope.get(name)
        if param is None or param.type == NUMBER:
            return None
        return self.vocab.types.get(param.type, DRONE_TYPES["Quadcopter"])

    def numbers_only(self, expr: Expr, what: str) -> bool:
        """Report every name in ``expr`` that is not a number parameter in scope."""
        ok = True
        for name in names_in(expr):
            param = self.scope.get(name.name)
            if param is not None and param.type == NUMBER:
                continue
            ok = False
            if param is not None or name.name in self.types:
                kind = param.type if param is not None else self.types[name.name].name
                message = f"'{name.name}' is a drone ({kind}), not a number"
                hint = f"{what} are numbers"
            else:
                message = f"unknown name '{name.name}'"
                numbers = [p.name for p in self.scope.values() if p.type == NUMBER]
                hint = did_you_mean(name.name, numbers) if numbers else ""
                hint = hint or f"{what} are numbers, or the block's float64 parameters"
            self.error(name.loc, message, hint, len(name.name))
        return ok

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
            if param.type == NUMBER:
                self.numbers_only(arg, f"the arguments of {call.name}")
            else:
                self.drone_argument(call, arg, param)

    def drone_argument(self, call: BlockCall, arg: Expr, param: Param) -> None:
        """A drone argument names a drone whose type satisfies the parameter's."""
        if not isinstance(arg, Name):
            self.error(
                arg.loc,
                f"{call.name}'s parameter '{param.name}' is a drone ({param.type})",
                "pass a drone by its name, e.g. Drone1",
            )
            return
        have = self.drone_param(arg.name)
        if have is None:
            if arg.name in self.scope:
                self.error(arg.loc, f"'{arg.name}' is a number, not a drone", "", len(arg.name))
                return
            if arg.name == GROUND_STATION:
                self.error(arg.loc, f"the ground station '{GROUND_STATION}' does not fly")
                return
            have = self.types.get(arg.name)
        want = self.vocab.types.get(param.type)
        if have is None or want is None:
            return  # an unknown type, reported at its declaration
        missing = self.vocab.missing(have, want)
        if missing:
            shown = ", ".join(missing[:6]) + (" ..." if len(missing) > 6 else "")
            self.error(
                arg.loc,
                f"{arg.name} ({have.name}) is not a {want.name}: it has no {shown}",
                f"{call.name} needs a drone of type {want.name}, or one that embeds it",
                len(arg.name),
            )


def _calls(stmt: Statement) -> list[BlockCall | BlockRef]:
    """The block calls of a statement: a call, or a control structure's blocks."""
    if isinstance(stmt, BlockCall):
        return [stmt]
    if isinstance(stmt, Control):
        return [r for r in (stmt.body, stmt.orelse, stmt.exit) if r is not None]
    return []


def drone_arguments(mission: Mission) -> list[tuple[Name, str]]:
    """Each name passed to a drone parameter by a call, with its block (to find drones)."""
    out: list[tuple[Name, str]] = []
    for block in mission.blocks.values():
        scope = {p.name for p in block.params}
        for call in (c for stmt in block.statements for c in _calls(stmt)):
            if not call.args:
                continue
            callee = mission.blocks.get(call.name)
            if callee is None or len(callee.params) != len(call.args):
                continue
            for arg, param in zip(call.args, callee.params, strict=True):
                if param.type != NUMBER and isinstance(arg, Name) and arg.name not in scope:
                    out.append((arg, block.name))
    return out
