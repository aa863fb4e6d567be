"""The parsed mission: small frozen dataclasses, the output of :mod:`.parse`.

This is the mission exactly as written (blocks, statements, conditions) with
source locations, before any block is expanded into the mission tree.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Literal

from .errors import SourceLocation

# -- conditions ---------------------------------------------------------------


@dataclass(frozen=True)
class Num:
    value: float
    loc: SourceLocation
    # Written without a point or exponent (``2``): a whole number, which keeps arithmetic
    # with the loop counters whole (``i / 2`` drops the remainder, as in Go).
    whole: bool = False


@dataclass(frozen=True)
class Bool:
    value: bool
    loc: SourceLocation


@dataclass(frozen=True)
class Prop:
    """A drone property read, ``D3.X()``; ``Team[i].Z()`` has ``pick``.

    Inside a group condition, ``Team.Z()`` or ``Team[0:10].Z()`` reads each member in turn.
    """

    drone: str
    name: str
    loc: SourceLocation
    pick: Member | Slice | None = None


@dataclass(frozen=True)
class Unary:
    op: Literal["!", "-"]
    operand: Expr
    loc: SourceLocation


@dataclass(frozen=True)
class Binary:
    op: str  # && || == != < <= > >= + - * /
    left: Expr
    right: Expr
    loc: SourceLocation


@dataclass(frozen=True)
class Name:
    """A name: a block parameter (``dist_m``, a drone parameter ``d``), a loop variable,
    a drone or a group passed to a block."""

    name: str
    loc: SourceLocation


@dataclass(frozen=True)
class Member:
    """One member of a group, ``Team[i + 1]``: a drone once the index is folded."""

    group: str
    index: Expr
    loc: SourceLocation


@dataclass(frozen=True)
class Slice:
    """Part of a group, ``Team[10:20]`` (Go's half-open range; a bound may be left out)."""

    group: str
    low: Expr | None
    high: Expr | None
    loc: SourceLocation


@dataclass(frozen=True)
class Len:
    """``len(Team)``: the number of members of a group (a whole number)."""

    group: Name | Slice
    loc: SourceLocation


QUANTIFIERS: tuple[str, ...] = ("All", "Any", "Count")


@dataclass(frozen=True)
class Quantifier:
    """A condition over a group: ``All(Team.Z() > 2)``, ``Any(...)``, ``Count(...)``.

    ``cond`` reads the group as if it were one drone (``Team.Z()``, ``g[2:5].Z()``);
    ``All`` holds when it holds for every member, ``Any`` for at least one, and
    ``Count`` is the number of members for which it holds.
    """

    kind: Literal["All", "Any", "Count"]
    cond: Expr
    loc: SourceLocation


Expr = Num | Bool | Prop | Unary | Binary | Name | Member | Slice | Len | Quantifier


# -- statements ---------------------------------------------------------------


@dataclass(frozen=True)
class ActionCall:
    """``Drone1.Takeoff(1.5)``; ``drone`` is None for a bare ``PauseFor(5)``."""

    drone: str | None
    action: str
    args: tuple[float, ...]
    loc: SourceLocation
    arg_locs: tuple[SourceLocation, ...] = ()
    action_loc: SourceLocation | None = None  # where the action's name is, for the caret
    # Arguments that read block parameters, folded to ``args`` when the block is expanded.
    exprs: tuple[Expr, ...] = ()
    # ``Team[i].Arm()``: the member (``drone`` is then the group's name).
    pick: Member | None = None


@dataclass(frozen=True)
class BlockCall:
    """``SEQ_Start()`` or ``lib.SEQ_Hop(D1, 5)``: run another block here.

    ``args`` are drone names (:class:`Name`) and constant number expressions.
    """

    name: str
    loc: SourceLocation
    args: tuple[Expr, ...] = ()


ControlKind = Literal[
    "If",
    "WaitWhile",
    "WaitUntil",
    "RepeatWhile",
    "RepeatUntil",
    "RepeatFor",
    "PauseWhile",
    "PauseUntil",
    "DoWhile",
    "DoUntil",
    "Try",
    "Whenever",
    "Abandon",
]

CONTROL_KINDS: tuple[str, ...] = (
    "If",
    "WaitWhile",
    "WaitUntil",
    "RepeatWhile",
    "RepeatUntil",
    "RepeatFor",
    "PauseWhile",
    "PauseUntil",
    "DoWhile",
    "DoUntil",
    "Try",
    "Whenever",
    "Abandon",
)


@dataclass(frozen=True)
class BlockRef:
    """A block named as an argument of a control structure (Body, Then, Else, Exit).

    A block with parameters is named with its arguments: ``SEQ_Leg(d, 5)``.
    """

    name: str
    loc: SourceLocation
    args: tuple[Expr, ...] = ()


@dataclass(frozen=True)
class Control:
    """A control structure of the paper's Table 3."""

    kind: ControlKind
    loc: SourceLocation
    cond: Expr | None = None
    count: int | None = None  # RepeatFor
    # RepeatFor's count when it reads a block parameter (folded when the block is expanded).
    count_expr: Expr | None = None
    body: BlockRef | None = None  # Body, Then, or a Whenever's Handler
    orelse: BlockRef | None = None  # Else
    exit: BlockRef | None = None  # Exit (a Try's OnFailure)
    drone: str | None = None  # D1.PauseWhile(...)
    pick: Member | None = None  # Team[i].PauseWhile(...): the member
    # The condition as written, for labels, when the runtime form is long (group conditions).
    text: str = ""


@dataclass(frozen=True)
class ForLoop:
    """A Go ``for`` inside a block, expanded at compile time into its iterations.

    Over a group, ``for i, d := range Team { ... }`` (``over`` is the group;
    ``index``/``member`` the variables, None for ``_`` or absent); over a count,
    ``for i := 0; i < n; i++ { ... }`` or ``for i := range n { ... }``
    (``start``, ``op`` and ``limit``, ``step``).  The iterations run as the
    statements of the block holding the loop: at once in a ``PAR_`` block, one
    after the other in a ``SEQ_`` block; the statements of one iteration run in order.
    """

    loc: SourceLocation
    body: tuple[Statement, ...]
    index: str | None = None
    index_loc: SourceLocation | None = None
    member: str | None = None
    member_loc: SourceLocation | None = None
    over: Name | Slice | None = None
    start: Expr | None = None
    op: str = "<"
    limit: Expr | None = None
    step: Expr | None = None
    # The body lost statements to errors (an "empty" expansion is then a consequence).
    incomplete: bool = False
    # The line of the loop's closing brace: its variables are in scope up to there.
    end_line: int = 0


Statement = ActionCall | BlockCall | Control | ForLoop


def flat_statements(statements: tuple[Statement, ...]) -> Iterator[Statement]:
    """Every statement, those inside loops included (the loops too), in reading order."""
    for stmt, _ in scoped_statements(statements):
        yield stmt


def scoped_statements(
    statements: tuple[Statement, ...],
) -> Iterator[tuple[Statement, frozenset[str]]]:
    """Every statement as :func:`flat_statements`, with the loop variables in scope there.

    Iterative: loops nest at most :data:`~.limits.MAX_LOOP_DEPTH` deep, but no walk
    of the checks should depend on it.
    """
    stack: list[tuple[Iterator[Statement], frozenset[str]]] = [(iter(statements), frozenset())]
    while stack:
        pending, names = stack[-1]
        for stmt in pending:
            yield stmt, names
            if isinstance(stmt, ForLoop):
                inner = names | {n for n in (stmt.index, stmt.member) if n is not None}
                stack.append((iter(stmt.body), inner))
                break
        else:
            stack.pop()


@dataclass(frozen=True)
class Param:
    """A block or action parameter: ``dist_m float64`` or ``d Quadcopter``."""

    name: str
    type: str
    loc: SourceLocation
    type_loc: SourceLocation | None = None


@dataclass(frozen=True)
class Block:
    """One ``func``: SEQ_ blocks run in order, PAR_ blocks in parallel."""

    name: str
    mode: Literal["SEQ", "PAR"]
    statements: tuple[Statement, ...]
    loc: SourceLocation
    params: tuple[Param, ...] = ()
    # The line of the closing brace (0 for blocks the expansion writes).
    end_line: int = 0


@dataclass(frozen=True)
class MethodDecl:
    """An action a declared drone type adds: ``Gimbal(pitch_deg float64)``."""

    name: str
    params: tuple[Param, ...]
    loc: SourceLocation


@dataclass(frozen=True)
class TypeDecl:
    """``type Inspector interface { Quadcopter; TakePhoto() }``: a drone type."""

    name: str
    embeds: tuple[tuple[str, SourceLocation], ...]
    methods: tuple[MethodDecl, ...]
    loc: SourceLocation


@dataclass(frozen=True)
class Import:
    """``import "inspection"``: a library folder, and the package name it gives."""

    path: str
    loc: SourceLocation


@dataclass(frozen=True)
class LibraryFile:
    """A library file a mission was built from, and the SHA-256 of its bytes."""

    path: str
    package: str
    sha256: str


@dataclass(frozen=True)
class DroneDecl:
    """``var Drone1 DroneType1``; a group's member has ``group`` (and the group's place)."""

    name: str
    type: str
    loc: SourceLocation
    type_loc: SourceLocation | None = None
    group: str = ""


@dataclass(frozen=True)
class GroupDecl:
    """``var Team [20]Quadcopter``: ``size`` drones of one type, ``Team[0]`` ... ``Team[19]``.

    Outside the mission text (fleet files, programs, logs, graphs) member ``i`` is
    the drone :func:`member_name` ``Team_i``.
    """

    name: str
    type: str
    size: int
    loc: SourceLocation
    type_loc: SourceLocation | None = None

    def members(self) -> list[str]:
        """The members' drone names, in index order."""
        return [member_name(self.name, i) for i in range(self.size)]


def member_name(group: str, index: int) -> str:
    """The drone name of ``group[index]``: ``Team_3`` (a name for files, TOML and the wire)."""
    return f"{group}_{index}"


#: The type of a group parameter of type ``T``: ``[]T`` (Go's slice type).
GROUP_PREFIX = "[]"
#: The parameter type of decimal numbers, and of whole numbers (loop counters are ``int``).
NUMBER = "float64"
WHOLE = "int"
NUMBER_TYPES = (NUMBER, WHOLE)


@dataclass(frozen=True)
class Mission:
    """A whole parsed mission file."""

    name: str
    blocks: dict[str, Block] = field(hash=False)
    drones: dict[str, DroneDecl] = field(hash=False)
    entry: str
    source: str = field(repr=False, compare=False)
    # Blocks that lost statements to parse errors: an "empty block" there is a consequence.
    incomplete_blocks: frozenset[str] = frozenset()
    imports: tuple[Import, ...] = ()
    # Declared drone types, by name (``lib.Name`` for a library's types).
    types: dict[str, TypeDecl] = field(default_factory=dict, hash=False)
    # The library files merged in (their blocks are named ``package.Block``).
    libraries: tuple[LibraryFile, ...] = ()
    # Groups of drones, by name (their members are drones once the mission is expanded).
    groups: dict[str, GroupDecl] = field(default_factory=dict, hash=False)


def expansion_needed(mission: Mission) -> bool:
    """True if ``mission`` has blocks with parameters, loops or groups to expand."""
    return bool(mission.groups) or any(
        block.params or any(isinstance(s, ForLoop) for s in block.statements)
        for block in mission.blocks.values()
    )


def sub_expressions(expr: Expr | None) -> Iterator[Expr]:
    """``expr`` and every expression inside it, in source order (group conditions too)."""
    stack: list[Expr | None] = [expr]
    while stack:  # a loop: conditions may nest deep
        node = stack.pop()
        if node is None:
            continue
        yield node
        if isinstance(node, Unary):
            stack.append(node.operand)
        elif isinstance(node, Binary):
            stack.extend((node.right, node.left))
        elif isinstance(node, Quantifier):
            stack.append(node.cond)


def props_in(expr: Expr | None) -> Iterator[Prop]:
    """Every property read in an expression, in source order (group conditions included)."""
    return (node for node in sub_expressions(expr) if isinstance(node, Prop))


# Go's precedence, as eamos.program.conditions prints conditions.
_PRECEDENCE = {
    "||": 1,
    "&&": 2,
    **dict.fromkeys(("==", "!=", "<", "<=", ">", ">="), 3),
    **dict.fromkeys(("+", "-"), 4),
    **dict.fromkeys(("*", "/", "%"), 5),
}


def expr_text(expr: Expr | None) -> str:
    """Go text of an expression as the mission writes it (``All(Team[0:10].Z() > 2)``).

    For labels and messages; parentheses only where precedence needs them.  The
    nesting is bounded by the parser's limit, so the recursion is too.
    """
    if expr is None:
        return ""
    if isinstance(expr, Num):
        return f"{expr.value:g}"
    if isinstance(expr, Bool):
        return "true" if expr.value else "false"
    if isinstance(expr, Name):
        return expr.name
    if isinstance(expr, Member):
        return f"{expr.group}[{expr_text(expr.index)}]"
    if isinstance(expr, Slice):
        return f"{expr.group}[{expr_text(expr.low)}:{expr_text(expr.high)}]"
    if isinstance(expr, Len):
        return f"len({expr_text(expr.group)})"
    if isinstance(expr, Prop):
        drone = expr_text(expr.pick) if expr.pick is not None else expr.drone
        return f"{drone}.{expr.name}()"
    if isinstance(expr, Quantifier):
        return f"{expr.kind}({expr_text(expr.cond)})"
    if isinstance(expr, Unary):
        inner = expr_text(expr.operand)
        return f"{expr.op}({inner})" if isinstance(expr.operand, Binary) else f"{expr.op}{inner}"
    mine = _PRECEDENCE.get(expr.op, 6)
    left, right = expr_text(expr.left), expr_text(expr.right)
    if isinstance(expr.left, Binary) and _PRECEDENCE.get(expr.left.op, 6) < mine:
        left = f"({left})"
    if isinstance(expr.right, Binary) and _PRECEDENCE.get(expr.right.op, 6) <= mine:
        right = f"({right})"
    return f"{left} {expr.op} {right}"


def named_drone_calls(mission: Mission) -> Iterator[ActionCall]:
    """Every action called on a drone by its own name, in reading order: not on a block's
    drone parameter, a loop variable or a group member picked by an index."""
    for block in mission.blocks.values():
        params = {p.name for p in block.params}
        for stmt, loops in scoped_statements(block.statements):
            if (
                isinstance(stmt, ActionCall)
                and stmt.drone is not None
                and stmt.pick is None
                and stmt.drone not in params
                and stmt.drone not in loops
            ):
                yield stmt
