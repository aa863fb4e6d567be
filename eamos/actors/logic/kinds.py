"""Which logic class runs which node kind, and the wiring of a whole program.

:func:`node_logic` builds the logic of one node; :func:`program_wiring` reads a
drone program's arcs into each native node's routes and precondition groups,
the same way for the actor runtime and the virtual-time driver.
"""

from __future__ import annotations

from dataclasses import dataclass

from ...program.format import DroneProgram, ProgramNode
from .actions import ActionLogic
from .base import NodeLogic, PassThrough
from .conditions import DoEndLogic, DoLogic, IfLogic, WaitLogic
from .effects import Route
from .events import AbandonLogic, WheneverEndLogic, WheneverLogic
from .handlers import TryEndLogic
from .loops import LoopLogic

LOOP_KINDS = frozenset({"repeat_while", "repeat_until", "repeat_for"})
DO_KINDS = frozenset({"do_while", "do_until"})
TRY_KINDS = frozenset({"try"})
WHENEVER_KINDS = frozenset({"whenever"})
WAIT_KINDS = frozenset({"wait_while", "wait_until", "pause_while", "pause_until"})
CONDITION_KINDS = frozenset({"if"}) | LOOP_KINDS | DO_KINDS | WAIT_KINDS | WHENEVER_KINDS
# A Try's begin node only starts Body (and tells its end it ran): a pass-through.
PASS_KINDS = frozenset({"init", "fork", "end"}) | TRY_KINDS

_LOGIC: dict[str, type[NodeLogic]] = {
    "action": ActionLogic,
    "if": IfLogic,
    **dict.fromkeys(PASS_KINDS, PassThrough),
    **dict.fromkeys(WAIT_KINDS, WaitLogic),
    **dict.fromkeys(LOOP_KINDS, LoopLogic),
    **dict.fromkeys(DO_KINDS, DoLogic),
    **dict.fromkeys(WHENEVER_KINDS, WheneverLogic),
    "abandon": AbandonLogic,
}


def logic_class(kind: str, begin_kind: str = "") -> type[NodeLogic]:
    """The logic class of a node kind (``begin_kind``: for an ``end``, its begin's kind)."""
    if kind == "end" and begin_kind in DO_KINDS:
        return DoEndLogic
    if kind == "end" and begin_kind in TRY_KINDS:
        return TryEndLogic
    if kind == "end" and begin_kind in WHENEVER_KINDS:
        return WheneverEndLogic
    try:
        return _LOGIC[kind]
    except KeyError:
        raise ValueError(f"unknown node kind {kind!r}") from None


def node_logic(
    spec: ProgramNode,
    routes: tuple[Route, ...],
    entry: frozenset[str],
    loop: frozenset[str] = frozenset(),
    begin_kind: str = "",
) -> NodeLogic:
    """The pure logic of one native node."""
    return logic_class(spec.kind, begin_kind)(spec, routes, entry, loop)


@dataclass(frozen=True)
class NodeWiring:
    """What one native node needs besides its spec: arcs out, arcs in, its begin's kind."""

    spec: ProgramNode
    routes: tuple[Route, ...]
    entry: frozenset[str]
    loop: frozenset[str]
    begin_kind: str

    def logic(self) -> NodeLogic:
        """A fresh logic instance for this node."""
        return node_logic(self.spec, self.routes, self.entry, self.loop, self.begin_kind)


def program_wiring(program: DroneProgram) -> dict[str, NodeWiring]:
    """Per native node of ``program`` (by key, in program order): its wiring."""
    routes: dict[str, list[Route]] = {}
    entry: dict[str, set[str]] = {}
    loop: dict[str, set[str]] = {}
    drone_of = {n.key: n.drone for n in program.nodes}
    kind_of = {n.key: n.kind for n in program.nodes}
    for arc in program.arcs:
        routes.setdefault(arc.src, []).append(
            Route(arc.dst, drone_of[arc.dst], arc.kind, arc.external)
        )
        (loop if arc.kind == "loop" else entry).setdefault(arc.dst, set()).add(arc.src)
    return {
        node.key: NodeWiring(
            node,
            tuple(routes.get(node.key, ())),
            frozenset(entry.get(node.key, ())),
            frozenset(loop.get(node.key, ())),
            kind_of.get(f"n{node.begin}", "") if node.begin is not None else "",
        )
        for node in program.native_nodes()
    }
