"""Phase 2: checks before anything flies.

Validates a parsed :class:`~.syntax.Mission` against the uniform API and the
drone types: undefined blocks, unknown actions and properties (with "did you
mean"), argument counts and values, condition types, recursion between
blocks, empty blocks, blocks never reached.  Returns the warnings; raises one
:class:`~.errors.MissionError` with every error found.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator

from ..program.uniform import (
    ACTIONS,
    CONTROL_STRUCTURES,
    DEFAULT_DRONE_TYPE,
    DRONE_TYPES,
    GROUND_STATION,
    MOTION_ACTIONS,
    PROPERTIES,
    DroneType,
)
from .check_calls import drone_arguments, signature
from .check_groups import GroupChecks
from .check_handlers import handler_errors
from .constants import names_in
from .drone_names import misspelt_drones
from .drone_types import Vocabulary, implemented_actions, plugin_argument_problem, vocabulary
from .errors import Diagnostic, MissionError, SourceLocation, did_you_mean
from .limits import (
    MAX_DISTANCE_M,
    MAX_DURATION_S,
    MAX_ORBIT_RADIUS_M,
    MAX_ORBIT_TURNS,
    MAX_SPEED_M_S,
    block_limit_errors,
    fleet_limit_error,
)
from .syntax import (
    ActionCall,
    Binary,
    Block,
    BlockCall,
    BlockRef,
    Bool,
    Control,
    Expr,
    ForLoop,
    Len,
    Mission,
    Name,
    Num,
    Param,
    Prop,
    Quantifier,
    Unary,
    expansion_needed,
    flat_statements,
    named_drone_calls,
    props_in,
)

_ARITH = {"+", "-", "*", "/", "%"}
_COMPARE = {"<", "<=", ">", ">="}
_EQUALITY = {"==", "!="}
_LOGIC = {"&&", "||"}


def drone_types(mission: Mission, vocab: Vocabulary | None = None) -> dict[str, DroneType]:
    """The type of every drone the mission commands or declares (default type if undeclared).

    A block's drone parameters are not drones; the drones passed to them are.
    """
    known = (vocab or vocabulary(mission)[0]).types
    default = DRONE_TYPES[DEFAULT_DRONE_TYPE]
    types: dict[str, DroneType] = {}
    for decl in mission.drones.values():
        types[decl.name] = known.get(decl.type, default)
    for call in named_drone_calls(mission):
        if call.drone is not None and call.drone not in types and call.drone not in mission.groups:
            types[call.drone] = default
    if expansion_needed(mission):
        for name, _ in drone_arguments(mission):
            types.setdefault(name.name, default)
    return types


def _refs(stmt: object) -> Iterator[BlockRef | BlockCall]:
    if isinstance(stmt, BlockCall):
        yield stmt
    elif isinstance(stmt, Control):
        for ref in (stmt.body, stmt.orelse, stmt.exit):
            if ref is not None:
                yield ref


def _block_refs(block: Block) -> list[BlockRef | BlockCall]:
    """The blocks a block names, those in its loops included."""
    return [r for s in flat_statements(block.statements) for r in _refs(s)]


class _WholeMission:
    """Checks of the block-call graph: recursion and reachability."""

    mission: Mission

    def error(self, loc: SourceLocation, message: str, hint: str = "", width: int = 1) -> None:
        raise NotImplementedError  # pragma: no cover - the checker defines it

    def warn(self, loc: SourceLocation, message: str, hint: str = "") -> None:
        raise NotImplementedError  # pragma: no cover - the checker defines it

    # -- whole-mission checks -----------------------------------------------

    def recursion(self) -> bool:
        """Report every cycle of block calls; True if there is none.

        A depth-first walk with an explicit stack: a chain of thousands of blocks
        must not exhaust Python's.
        """
        blocks = self.mission.blocks
        state: dict[str, int] = {}  # 1 = on the current path, 2 = done
        path: list[str] = []
        acyclic = True
        for root in blocks:
            if root in state:
                continue
            state[root] = 1
            path.append(root)
            stack = [iter(_block_refs(blocks[root]))]
            while stack:
                for ref in stack[-1]:
                    if ref.name not in blocks:
                        continue
                    if state.get(ref.name) == 1:
                        acyclic = False
                        cycle = [*path[path.index(ref.name) :], ref.name]
                        self.error(
                            ref.loc,
                            "recursion between blocks: " + " -> ".join(_shorten(cycle)),
                            "a mission is finite: use RepeatWhile/RepeatFor to repeat a block",
                        )
                    elif ref.name not in state:
                        state[ref.name] = 1
                        path.append(ref.name)
                        stack.append(iter(_block_refs(blocks[ref.name])))
                        break
                else:
                    stack.pop()
                    state[path.pop()] = 2
        return acyclic

    def reachability(self) -> None:
        blocks = self.mission.blocks
        if not self.mission.entry:
            return
        seen = {self.mission.entry}
        todo = [self.mission.entry]
        while todo:
            for ref in _block_refs(blocks[todo.pop()]):
                if ref.name in blocks and ref.name not in seen:
                    seen.add(ref.name)
                    todo.append(ref.name)
        for name, block in blocks.items():
            if name not in seen and not block.loc.file:  # a library's blocks are offered
                self.warn(
                    block.loc,
                    f"block '{name}' is never reached from {self.mission.entry}",
                    "call it from another block, or remove it",
                )


class _Checker(GroupChecks, _WholeMission):
    def __init__(self, mission: Mission) -> None:
        self.mission = mission
        self.vocab, self.diags = vocabulary(mission)
        self.types = drone_types(mission, self.vocab)
        self.scope: dict[str, Param] = {}

    def error(self, loc: SourceLocation, message: str, hint: str = "", width: int = 1) -> None:
        end_col = loc.col + width if width > 1 else None
        self.diags.append(Diagnostic("error", loc, message, hint, end_col))

    def warn(self, loc: SourceLocation, message: str, hint: str = "") -> None:
        self.diags.append(Diagnostic("warning", loc, message, hint))

    def run(self) -> list[Diagnostic]:
        m = self.mission
        for decl in m.drones.values():
            if decl.type not in self.vocab.types:
                self.error(
                    decl.type_loc or decl.loc,
                    f"unknown drone type '{decl.type}'",
                    did_you_mean(decl.type, self.vocab.types),
                    len(decl.type),
                )
            if decl.name == GROUND_STATION:
                self.error(
                    decl.loc,
                    f"'{GROUND_STATION}' is the ground station's name",
                    "name the drone differently",
                )
            self.unimplemented(decl.name, decl.type, decl.type_loc or decl.loc)
        self.group_declarations()
        for name, block in m.blocks.items():
            if not block.statements and name not in self.mission.incomplete_blocks:
                self.error(
                    block.loc,
                    f"block '{name}' is empty",
                    "give it at least one statement, or remove it and its calls",
                )
            self.enter(block)
            for stmt in block.statements:
                self.statement(stmt)
        self.scope = {}
        self.diags.extend(handler_errors(m))
        too_many = fleet_limit_error(m)
        if too_many is not None:
            self.diags.append(too_many)
        if self.recursion():
            # Only a mission without cycles has a finite size to count.
            self.diags.extend(block_limit_errors(m))
        self.reachability()
        if not expansion_needed(m):
            # With parameters or loops, which drone moves is known once they are expanded:
            # the same check then runs on the expanded mission (instance_warnings).
            self.par_motions()
        used = _used_names(m)
        for decl in m.drones.values():
            if decl.name not in used:
                self.warn(decl.loc, f"drone '{decl.name}' is declared but never used")
        for group in m.groups.values():
            if group.name not in used:
                self.warn(group.loc, f"group '{group.name}' is declared but never used")
        return self.diags

    # -- one motion per drone at a time ---------------------------------------

    def motions(self, stmt: object, seen: frozenset[str] = frozenset()) -> dict[str, ActionCall]:
        """The first motion action of each drone a statement (and the blocks it calls) gives.

        Control structures are left out: when their blocks run depends on conditions
        (experiment D's four loops share one Exit block, and only one runs it at a time).
        """
        if isinstance(stmt, ActionCall):
            if stmt.drone is not None and stmt.action in MOTION_ACTIONS:
                return {stmt.drone: stmt}
            return {}
        out: dict[str, ActionCall] = {}
        for ref in _refs(stmt) if isinstance(stmt, BlockCall) else ():
            block = self.mission.blocks.get(ref.name)
            if block is None or ref.name in seen:  # undefined or recursive: reported elsewhere
                continue
            for inner in block.statements:
                for drone, call in self.motions(inner, seen | {ref.name}).items():
                    out.setdefault(drone, call)
        return out

    def par_motions(self) -> None:
        """A drone given two motions at once in a PAR_ block: the second fails ``busy``."""
        for name, block in self.mission.blocks.items():
            if block.mode != "PAR":
                continue
            first: dict[str, ActionCall] = {}
            for stmt in block.statements:
                for drone, call in self.motions(stmt, frozenset({name})).items():
                    if drone in first:
                        other = first[drone]
                        self.warn(
                            call.loc,
                            f"the same drone given two actions at once in a PAR_: {drone}."
                            f"{call.action} runs in {name} together with {drone}.{other.action} "
                            f"(line {other.loc.line}); a drone makes one motion at a time, "
                            "so one of them fails 'busy'",
                            "put them one after the other in a SEQ_ block",
                        )
                    else:
                        first[drone] = call

    # -- statements ---------------------------------------------------------

    def unimplemented(self, drone: str, type_name: str, loc: SourceLocation) -> None:
        """Warn of a drone whose type has actions no adapter runs yet (calling one is an error)."""
        dtype = self.vocab.types.get(type_name)
        missing = (
            sorted(dtype.actions - implemented_actions(self.vocab)) if dtype is not None else []
        )
        if missing:
            self.warn(
                loc,
                f"{drone}'s type {type_name} has actions no adapter implements yet: "
                + ", ".join(missing),
                "the mission compiles, but calling one of them is an error",
            )

    def statement(self, stmt: object) -> None:
        if isinstance(stmt, BlockCall):
            self.block_ref(stmt.name, stmt.loc)
            self.block_call(stmt)
        elif isinstance(stmt, ActionCall):
            self.action(stmt)
        elif isinstance(stmt, Control):
            self.control(stmt)
        elif isinstance(stmt, ForLoop):
            self.for_loop(stmt)

    def block_ref(self, name: str, loc: SourceLocation) -> None:
        if name not in self.mission.blocks:
            hint = did_you_mean(name, self.mission.blocks)
            if not name.startswith(("SEQ_", "PAR_")) and "." not in name:
                # ``Tyr(SEQ_A, SEQ_B)``: a misspelt control structure, not a block.
                control = did_you_mean(name, CONTROL_STRUCTURES)
                if control.startswith("did you mean"):
                    hint = control
            if name in ACTIONS:
                hint = f"{name} is an action: call it on a drone, e.g. Drone1.{name}(...)"
            self.error(loc, f"undefined block '{name}'", hint)

    def action(self, call: ActionCall) -> None:
        spec = self.vocab.actions.get(call.action)
        dtype: DroneType | None = None
        if call.drone is None:
            if call.action != "PauseFor":  # pragma: no cover - the parser only makes bare PauseFor
                self.error(
                    call.loc, f"'{call.action}' needs a drone", f"write Drone1.{call.action}(...)"
                )
                return
        elif call.pick is not None:
            dtype = self.member_ref(call.pick)
            if dtype is None:
                return
        elif self.group_as_drone(call.drone, call.loc, "give"):
            return
        elif call.drone == GROUND_STATION:
            self.error(
                call.loc,
                f"the ground station '{GROUND_STATION}' does not fly",
                "call actions on drones; a bare PauseFor(s) pauses at the ground station",
            )
            return
        elif call.drone in self.scope and self.drone_param(call.drone) is None:
            self.error(
                call.loc,
                f"'{call.drone}' is a number, not a drone",
                f"a range loop's first variable is the index: for _, {call.drone} := range ... "
                "gives the members"
                if call.drone in self.range_indices
                else "actions are called on drones or on drone parameters",
                len(call.drone),
            )
            return
        if spec is None:
            self.error(
                call.action_loc or call.loc,
                f"unknown action '{call.action}'",
                did_you_mean(call.action, self.vocab.actions),
                len(call.action),
            )
            return
        if call.drone is not None:
            dtype = dtype or self.drone_param(call.drone) or self.types[call.drone]
            if call.action not in dtype.actions:
                shown = f"{call.drone}[...]" if call.pick is not None else call.drone
                self.error(
                    call.action_loc or call.loc,
                    f"{shown} ({dtype.name}) has no action '{call.action}'",
                    did_you_mean(call.action, dtype.actions)
                    if call.action not in self.vocab.actions
                    else f"{dtype.name} offers: {', '.join(sorted(dtype.actions))}",
                )
                return
        count = len(call.exprs or call.args)
        if count != len(spec.params):
            want = ", ".join(spec.params) or "no arguments"
            self.error(
                call.loc,
                f"{call.action} takes {len(spec.params)} argument"
                f"{'s' if len(spec.params) != 1 else ''}, got {count}",
                f"{call.action}({want})",
            )
            return
        if call.action not in implemented_actions(self.vocab):
            self.error(
                call.action_loc or call.loc,
                f"no adapter implements action '{call.action}' yet",
                f"{call.action} is declared by a drone type, but no installed action plugin "
                "provides it (see docs/plugins.md)",
                len(call.action),
            )
            return
        if call.exprs:
            for expr in call.exprs:
                self.numbers_only(expr, f"the arguments of {call.action}")
            return
        for value, param, loc in zip(
            call.args, spec.params, call.arg_locs or (call.loc,) * len(call.args), strict=False
        ):
            problem = argument_problem(call.action, param, value) or plugin_argument_problem(
                self.vocab, call.action, param, value
            )
            if problem:
                self.error(loc, problem)

    def control(self, ctl: Control) -> None:
        for ref in (ctl.body, ctl.orelse, ctl.exit):
            if ref is not None:
                self.block_ref(ref.name, ref.loc)
                named = self.mission.blocks.get(ref.name)
                if named is not None and named.params and not ref.args:
                    self.error(
                        ref.loc,
                        f"{ref.name} takes parameters: name it with its arguments",
                        f"e.g. {ctl.kind}(..., {signature(named)})",
                        len(ref.name),
                    )
                elif ref.args:
                    self.block_call(BlockCall(ref.name, ref.loc, ref.args))
        if ctl.count_expr is not None:
            self.numbers_only(ctl.count_expr, "RepeatFor's counts")
        if ctl.pick is not None:
            self.member_ref(ctl.pick)
        elif ctl.drone is not None:
            if (
                ctl.drone == GROUND_STATION
                or self.drone_param(ctl.drone) is not None
                or self.group_as_drone(ctl.drone, ctl.loc, "wait on")
            ):
                pass
            elif ctl.drone not in self.types:
                self.error(
                    ctl.loc, f"unknown drone '{ctl.drone}'", did_you_mean(ctl.drone, self.types)
                )
        if ctl.cond is not None:
            kind = self.expr_type(ctl.cond)
            if kind == "number":
                self.error(
                    ctl.cond.loc,
                    f"the condition of {ctl.kind} is a number, not true/false",
                    "compare it, e.g. D1.Z() > 1.5",
                )

    def expr_type(self, expr: Expr) -> str | None:
        """'number' or 'bool' (None after an error already reported)."""
        if isinstance(expr, Num):
            return "number"
        if isinstance(expr, Bool):
            return "bool"
        if isinstance(expr, Name):
            return "number" if self.numbers_only(expr, "names in conditions") else None
        if isinstance(expr, Quantifier):
            return self.quantifier_type(expr)
        if isinstance(expr, Len):
            return "number" if self.group_ref(expr.group) is not None else None
        if isinstance(expr, Prop):
            grouped, member = self.group_read(expr)
            if grouped and member is None:
                return None
            param_type = member if grouped else self.drone_param(expr.drone)
            if expr.drone not in self.types and expr.drone != GROUND_STATION and param_type is None:
                self.error(
                    expr.loc,
                    f"unknown drone '{expr.drone}'",
                    did_you_mean(expr.drone, self.types)
                    or "declare it: var " + expr.drone + " Quadcopter",
                )
                return None
            dtype = param_type or self.types.get(expr.drone)
            spec = PROPERTIES.get(expr.name)
            if spec is None or dtype is None or expr.name not in dtype.properties:
                offered = dtype.properties if dtype is not None else frozenset()
                self.error(
                    expr.loc,
                    f"{expr.drone} has no property '{expr.name}'",
                    did_you_mean(expr.name, offered or PROPERTIES),
                )
                return None
            return spec.type
        if isinstance(expr, Unary):
            inner = self.expr_type(expr.operand)
            want = "bool" if expr.op == "!" else "number"
            if inner is not None and inner != want:
                self.error(
                    expr.loc, f"'{expr.op}' needs a {'condition' if want == 'bool' else 'number'}"
                )
                return None
            return want
        if isinstance(expr, Binary):
            left, right = self.expr_type(expr.left), self.expr_type(expr.right)
            if left is None or right is None:
                return None
            if expr.op in _LOGIC:
                if left != "bool" or right != "bool":
                    self.error(
                        expr.loc,
                        f"'{expr.op}' joins conditions, not numbers",
                        "compare the numbers first, e.g. D1.X() > 1 && D1.Y() < 2",
                    )
                    return None
                return "bool"
            if expr.op in _EQUALITY:
                if left != right:
                    self.error(expr.loc, f"'{expr.op}' compares a number with a condition")
                    return None
                return "bool"
            if left != "number" or right != "number":
                self.error(expr.loc, f"'{expr.op}' needs numbers on both sides")
                return None
            if expr.op == "%" and (props_read(expr.left) or props_read(expr.right)):
                self.error(
                    expr.loc,
                    "'%' is computed when the mission is compiled: it cannot read a property",
                    "use it on loop counters and numbers, e.g. Team[i].Z() > 2 + i % 3",
                )
                return None
            return "bool" if expr.op in _COMPARE else "number"
        return None  # pragma: no cover


def _used_names(mission: Mission) -> set[str]:
    """The drones and groups the blocks name (a superset: names in scope count too)."""
    used: set[str] = set()
    for block in mission.blocks.values():
        for stmt in flat_statements(block.statements):
            exprs: list[Expr] = []
            if isinstance(stmt, ActionCall):
                used.add(stmt.drone or "")
                exprs.extend(stmt.exprs)
            elif isinstance(stmt, Control):
                used.add(stmt.drone or "")
                used.update(p.drone for p in props_in(stmt.cond))
                exprs.extend(a for r in (stmt.body, stmt.orelse, stmt.exit) if r for a in r.args)
                exprs.extend(e for e in (stmt.cond, stmt.count_expr) if e is not None)
            elif isinstance(stmt, BlockCall):
                exprs.extend(stmt.args)
            elif isinstance(stmt, ForLoop):
                exprs.extend(e for e in (stmt.over, stmt.limit, stmt.start) if e is not None)
            used.update(n.name for e in exprs for n in names_in(e))
    used.discard("")
    return used


def _shorten(cycle: list[str]) -> list[str]:
    return cycle if len(cycle) <= 8 else [*cycle[:4], "...", *cycle[-3:]]


# The range of each argument, by parameter name (see docs/mission-language.md, "Limits").
_RANGES: dict[str, tuple[float, float, str]] = {
    "height_m": (0.0, MAX_DISTANCE_M, "m"),
    "distance_m": (-MAX_DISTANCE_M, MAX_DISTANCE_M, "m"),
    "x_m": (-MAX_DISTANCE_M, MAX_DISTANCE_M, "m"),
    "y_m": (-MAX_DISTANCE_M, MAX_DISTANCE_M, "m"),
    "z_m": (-MAX_DISTANCE_M, MAX_DISTANCE_M, "m"),
    "alt_m": (-MAX_DISTANCE_M, MAX_DISTANCE_M, "m"),
    "duration_s": (0.0, MAX_DURATION_S, "s"),
    "heading_deg": (0.0, 360.0, "deg"),
    "speed_m_s": (0.0, MAX_SPEED_M_S, "m/s"),
    "radius_m": (0.0, MAX_ORBIT_RADIUS_M, "m"),
    "turns": (0.0, MAX_ORBIT_TURNS, ""),
}

# Parameters that must be strictly positive (a zero climb, speed, radius or turn does nothing).
_POSITIVE = frozenset({"height_m", "speed_m_s", "radius_m", "turns"})


def argument_problem(action: str, param: str, value: float) -> str:
    """What is wrong with one argument value ("" if nothing)."""
    if not math.isfinite(value):  # pragma: no cover - the parser refuses these
        return f"{action}'s {param} must be a finite number"
    if (param == "duration_s" and value < 0) or (param in _POSITIVE and value <= 0):
        return f"{action}'s {param} must be positive, got {value:g}"
    if param == "lat_deg" and not -90 <= value <= 90:
        return f"latitude must be within -90..90 degrees, got {value:g}"
    if param == "lon_deg" and not -180 <= value <= 180:
        return f"longitude must be within -180..180 degrees, got {value:g}"
    bounds = _RANGES.get(param)
    if bounds is not None and not bounds[0] <= value <= bounds[1]:
        low, high, unit = bounds
        within = f"{low:g}..{high:g} {unit}".rstrip()
        return f"{action}'s {param} must be within {within}, got {value:g}"
    return ""


def props_read(expr: Expr | None) -> list[Prop]:
    """Every property read in a condition, in source order."""
    return list(props_in(expr))


def collect_diagnostics(mission: Mission) -> list[Diagnostic]:
    """Every error and warning the checks find (without raising)."""
    return [*_Checker(mission).run(), *misspelt_drones(mission)]


def instance_warnings(mission: Mission) -> list[Diagnostic]:
    """The checks that need every call expanded (drones known): two motions at once.

    A statement in a loop is one place for many drones: its warning is given once,
    saying for how many more drones it holds.
    """
    checker = _Checker(mission)
    checker.diags = []
    checker.par_motions()
    first: dict[tuple[str, int, int], int] = {}
    more: dict[int, int] = {}
    for i, d in enumerate(checker.diags):
        at = (d.loc.file, d.loc.line, d.loc.col)
        if at in first:
            more[first[at]] = more.get(first[at], 0) + 1
        else:
            first[at] = i
    return [
        dataclasses.replace(d, hint=f"{d.hint} (the same for {more[i]} more drones here)")
        if i in more
        else d
        for i, d in enumerate(checker.diags)
        if first[(d.loc.file, d.loc.line, d.loc.col)] == i
    ]


def check_mission(mission: Mission) -> list[Diagnostic]:
    """Check a parsed mission; return its warnings or raise MissionError with all errors."""
    diags = _Checker(mission).run()
    if any(d.severity == "error" for d in diags):
        raise MissionError(diags)
    return diags
