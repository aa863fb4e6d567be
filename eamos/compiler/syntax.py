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


Expr = Num | Bool | Prop | Unary | Binary


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


@dataclass(frozen=True)
class BlockCall:
    """``SEQ_Start()``: run another block here."""

    name: str
    loc: SourceLocation


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
)


@dataclass(frozen=True)
class BlockRef:
    """A block named as an argument of a control structure (Body, Then, Else, Exit)."""

    name: str
    loc: SourceLocation


@dataclass(frozen=True)
class Control:
    """A control structure of the paper's Table 3."""

    kind: ControlKind
    loc: SourceLocation
    cond: Expr | None = None
    count: int | None = None  # RepeatFor
    body: BlockRef | None = None  # Body or Then
    orelse: BlockRef | None = None  # Else
    exit: BlockRef | None = None  # Exit
    drone: str | None = None  # D1.PauseWhile(...)


Statement = ActionCall | BlockCall | Control


@dataclass(frozen=True)
class Block:
    """One ``func``: SEQ_ blocks run in order, PAR_ blocks in parallel."""

    name: str
    mode: Literal["SEQ", "PAR"]
    statements: tuple[Statement, ...]
    loc: SourceLocation


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
