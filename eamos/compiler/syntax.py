"""The parsed mission: small frozen dataclasses, the output of :mod:`.parse`.

This is the mission exactly as written (blocks, statements, conditions) with
source locations, before any block is expanded into the mission tree.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from .errors import SourceLocation

# -- conditions ---------------------------------------------------------------


@dataclass(frozen=True)
class Num:
    value: float
    loc: SourceLocation


@dataclass(frozen=True)
class Bool:
    value: bool
    loc: SourceLocation


@dataclass(frozen=True)
class Prop:
    """A drone property read, ``D3.X()``."""

    drone: str
    name: str
    loc: SourceLocation


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
    """A block parameter read by name (``dist_m``, or a drone parameter ``d``)."""

    name: str
    loc: SourceLocation


Expr = Num | Bool | Prop | Unary | Binary | Name


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


Statement = ActionCall | BlockCall | Control


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
    """``var Drone1 DroneType1``."""

    name: str
    type: str
    loc: SourceLocation
    type_loc: SourceLocation | None = None


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
