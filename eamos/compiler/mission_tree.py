"""Phase 3: parsed mission -> Abstract Mission Tree (paper Section V-B1, Figure 6).

The AMT is a :class:`networkx.DiGraph` rooted at the initial node (id 0).
Every block call is expanded in place, so a block called twice appears twice.

Node attributes:

``kind``
    ``init`` (the ground station's initial node), ``seq``, ``par`` (a fork),
    ``action``, or a control structure: ``if``, ``wait_while``, ``wait_until``,
    ``repeat_while``, ``repeat_until``, ``repeat_for``, ``pause_while``,
    ``pause_until``, ``do_while``, ``do_until``, ``try``.
``drone``
    The drone that hosts the node (``"GCS"`` for the ground station); ``""``
    for ``seq``/``par`` nodes, which are assigned during slicing.
``label``
    What pictures show, e.g. ``Takeoff(1.5)`` or ``RepeatWhile D3.X() > -30 ...``.
``block``
    The block the node comes from (for ``seq``/``par``: the block itself).
``line``, ``col``
    Source location of the statement.
``action``, ``args``
    For ``action`` nodes: the uniform action and its arguments (floats).
``cond``
    For control nodes: the condition (see :mod:`eamos.program.conditions`).
``count``
    For ``repeat_for``: the number of repetitions.

Edge attributes: ``role`` (``child``, ``then``, ``else``, ``body``, ``exit``,
``handler``; a Try's OnFailure block hangs from an ``exit`` edge; a
Whenever's Handler from a ``handler`` edge and the statements after it in
its block, under a ``seq`` node labelled ``<block> after Whenever``, from a
``body`` edge)
and, for children of ``seq`` nodes, ``order`` (1-based execution order).

Sharing: control structures that are siblings in one PAR block and name the
same Exit block share one instance of it (experiment D's four loops with one
``PAR_Exit``): the Exit subtree has one ``exit`` edge from each of them, so
the AMT is a tree except for such shared Exit subtrees.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import networkx as nx

from ..program.conditions import Condition, to_text
from ..program.uniform import GROUND_STATION
from .check import props_read
from .errors import CompilerBug, MissionError
from .limits import block_limit_errors
from .syntax import (
    ActionCall,
    Binary,
    BlockCall,
    Bool,
    Control,
    Expr,
    Mission,
    Num,
    Prop,
    Unary,
)

CONTROL_KIND = {
    "If": "if",
    "WaitWhile": "wait_while",
    "WaitUntil": "wait_until",
    "RepeatWhile": "repeat_while",
    "RepeatUntil": "repeat_until",
    "RepeatFor": "repeat_for",
    "PauseWhile": "pause_while",
    "PauseUntil": "pause_until",
    "DoWhile": "do_while",
    "DoUntil": "do_until",
    "Try": "try",
    "Whenever": "whenever",
    "Abandon": "abandon",
}
LOOP_KINDS = frozenset({"repeat_while", "repeat_until", "repeat_for"})
DO_KINDS = frozenset({"do_while", "do_until"})
#: Structures shaped like a Do in the graphs (a begin, Body, an end, an Exit block):
#: the Do loops and Try (whose Exit block is OnFailure).
TRY_KINDS = frozenset({"try"})
#: Event handlers: ``Whenever`` (a begin node watching its condition) and ``Abandon()``.
WHENEVER_KINDS = frozenset({"whenever"})
WAIT_KINDS = frozenset({"wait_while", "wait_until", "pause_while", "pause_until"})
CONTROL_KINDS = frozenset(CONTROL_KIND.values())


def condition_of(expr: Expr) -> Condition:
    """The runtime form of a parsed condition."""
    if isinstance(expr, Num):
        return ["num", expr.value]
    if isinstance(expr, Bool):
        return ["bool", expr.value]
    if isinstance(expr, Prop):
        return ["prop", expr.drone, expr.name]
    if isinstance(expr, Unary):
        return ["not" if expr.op == "!" else "neg", condition_of(expr.operand)]
    if isinstance(expr, Binary):
        return [expr.op, condition_of(expr.left), condition_of(expr.right)]
    raise CompilerBug(f"unknown expression {expr!r}")


def _fmt_args(args: tuple[float, ...]) -> str:
    return ", ".join(f"{a:g}" for a in args)


def host_of_condition(expr: Expr | None) -> str | None:
    """The drone a condition reads most (first read wins ties); None if it reads none."""
    reads = [p.drone for p in props_read(expr)]
    if not reads:
        return None
    counts = Counter(reads)
    best = max(counts.values())
    return next(d for d in reads if counts[d] == best)


@dataclass
class _Builder:
    mission: Mission
    tree: nx.DiGraph = field(default_factory=nx.DiGraph)
    last_drone: str = GROUND_STATION
    next_id: int = 0
    # The first drone of each block, computed once: a block called from many controls
    # would otherwise be rescanned for each (quadratic on wide missions).
    first_drones: dict[str, str | None] = field(default_factory=dict)
    # The Whenever nodes whose Handler is being built, innermost last (for Abandon).
    handlers: list[int] = field(default_factory=list)

    def add(self, **attrs: object) -> int:
        node = self.next_id
        self.next_id += 1
        self.tree.add_node(node, **attrs)
        return node

    def block(self, name: str, parent: int, **edge: object) -> int:
        block = self.mission.blocks[name]
        node = self.add(
            kind="par" if block.mode == "PAR" else "seq",
            drone="",
            label=name,
            block=name,
            line=block.loc.line,
            col=block.loc.col,
        )
        self.tree.add_edge(parent, node, **edge)
        shared: dict[str, int] = {}
        self.statements(block.statements, node, name, block.mode, shared)
        return node

    def statements(
        self, stmts: tuple[object, ...], node: int, name: str, mode: str, shared: dict[str, int]
    ) -> None:
        for order, stmt in enumerate(stmts, start=1):
            edge_attrs: dict[str, object] = {"role": "child"}
            if mode == "SEQ":
                edge_attrs["order"] = order
            if isinstance(stmt, Control) and stmt.kind == "Whenever":
                # It guards the statements after it: they hang from it (a ``body`` edge).
                whenever = self.control(stmt, node, name, edge_attrs, None)
                rest = self.add(
                    kind="seq",
                    drone="",
                    label=f"{name} after Whenever",
                    block=name,
                    line=stmt.loc.line,
                    col=stmt.loc.col,
                )
                self.tree.add_edge(whenever, rest, role="body")
                self.statements(stmts[order:], rest, name, "SEQ", shared)
                return
            self.statement(stmt, node, name, edge_attrs, shared if mode == "PAR" else None)

    def statement(
        self,
        stmt: object,
        parent: int,
        block: str,
        edge: dict[str, object],
        shared: dict[str, int] | None,
    ) -> None:
        if isinstance(stmt, BlockCall):
            self.block(stmt.name, parent, **edge)
        elif isinstance(stmt, ActionCall):
            drone = stmt.drone if stmt.drone is not None else self.last_drone
            node = self.add(
                kind="action",
                drone=drone,
                action=stmt.action,
                args=stmt.args,
                label=f"{stmt.action}({_fmt_args(stmt.args)})",
                block=block,
                line=stmt.loc.line,
                col=stmt.loc.col,
            )
            self.tree.add_edge(parent, node, **edge)
            if drone != GROUND_STATION:
                self.last_drone = drone
        elif isinstance(stmt, Control):
            self.control(stmt, parent, block, edge, shared)
        else:  # pragma: no cover
            raise CompilerBug(f"unknown statement {stmt!r}")

    def control(
        self,
        ctl: Control,
        parent: int,
        block: str,
        edge: dict[str, object],
        shared: dict[str, int] | None,
    ) -> int:
        kind = CONTROL_KIND[ctl.kind]
        if kind == "abandon":
            return self.abandon(ctl, parent, block, edge)
        drone = ctl.drone or host_of_condition(ctl.cond)
        if drone is None and ctl.body is not None:
            drone = self._first_drone(ctl.body.name) or self.last_drone
        if drone is None:
            drone = self.last_drone
        attrs: dict[str, object] = {
            "kind": kind,
            "drone": drone,
            "block": block,
            "line": ctl.loc.line,
            "col": ctl.loc.col,
        }
        if ctl.cond is not None:
            attrs["cond"] = condition_of(ctl.cond)
            # A group condition is labelled as written (All(Team.Z() > 2)), not member by member.
            shown = ctl.text or to_text(attrs["cond"])  # type: ignore[arg-type]
            attrs["label"] = f"{ctl.kind} {shown}"
        elif kind == "try":
            attrs["label"] = f"Try {ctl.body.name if ctl.body else ''}"
        elif kind == "whenever":  # pragma: no cover - a Whenever always has a condition
            raise CompilerBug("Whenever without a condition")
        else:
            attrs["count"] = ctl.count
            attrs["label"] = f"{ctl.kind} {ctl.count}"
        node = self.add(**attrs)
        self.tree.add_edge(parent, node, **edge)
        if kind == "whenever" and ctl.body is not None:
            # The Handler; the guarded statements are added by the block (``body``).
            self.handlers.append(node)
            last = self.last_drone
            self.block(ctl.body.name, node, role="handler")
            self.handlers.pop()
            self.last_drone = last
            return node
        if ctl.body is not None:
            self.block(ctl.body.name, node, role="then" if kind == "if" else "body")
        if ctl.orelse is not None:
            self.block(ctl.orelse.name, node, role="else")
        if ctl.exit is not None:
            if kind == "try":
                # OnFailure is never shared: each Try catches its own Body's failures.
                self.block(ctl.exit.name, node, role="exit")
            elif shared is not None and ctl.exit.name in shared:
                self.tree.add_edge(node, shared[ctl.exit.name], role="exit")
            else:
                exit_node = self.block(ctl.exit.name, node, role="exit")
                if shared is not None:
                    shared[ctl.exit.name] = exit_node
        return node

    def abandon(self, ctl: Control, parent: int, block: str, edge: dict[str, object]) -> int:
        """``Abandon()``: on the drone of the statement before it, tied to its Whenever."""
        if not self.handlers:  # the checks refuse it first (check_handlers)
            raise CompilerBug(f"Abandon() outside a Whenever handler at line {ctl.loc.line}")
        node = self.add(
            kind="abandon",
            drone=self.last_drone,
            label="Abandon()",
            block=block,
            line=ctl.loc.line,
            col=ctl.loc.col,
            begin=self.handlers[-1],
        )
        self.tree.add_edge(parent, node, **edge)
        return node

    def _first_drone(self, name: str, seen: frozenset[str] = frozenset()) -> str | None:
        """The drone of the first action in a block, in reading order.

        Recursion is bounded by the checked nesting limit (``limits.MAX_BLOCK_DEPTH``).
        """
        if name in seen or name not in self.mission.blocks:
            return None
        if name not in self.first_drones:
            self.first_drones[name] = self._scan_first_drone(name, seen)
        return self.first_drones[name]

    def _scan_first_drone(self, name: str, seen: frozenset[str]) -> str | None:
        for stmt in self.mission.blocks[name].statements:
            if isinstance(stmt, ActionCall) and stmt.drone is not None:
                return stmt.drone
            refs = (
                [stmt.name]
                if isinstance(stmt, BlockCall)
                else (
                    [r.name for r in (stmt.body, stmt.orelse, stmt.exit) if r is not None]
                    if isinstance(stmt, Control)
                    else []
                )
            )
            for ref in refs:
                found = self._first_drone(ref, seen | {name})
                if found:
                    return found
        return None


def build_mission_tree(mission: Mission) -> nx.DiGraph:
    """Expand a checked mission into its Abstract Mission Tree (root: node 0, ``init``).

    Counts before expanding: a mission over the size or nesting limits (normally
    refused by the checks already) raises :class:`~.errors.MissionError` here too.
    """
    too_big = block_limit_errors(mission)
    if too_big:
        raise MissionError(too_big)
    builder = _Builder(mission)
    root = builder.add(kind="init", drone=GROUND_STATION, label="INIT", block="", line=1, col=1)
    builder.block(mission.entry, root, role="child")
    builder.tree.graph.update(mission=mission.name, entry=mission.entry, root=root)
    return builder.tree
