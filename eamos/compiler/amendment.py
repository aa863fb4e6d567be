"""Amending a mission that runs: each node's identity by content, and what an amendment changes.

A node's key (``n12``, ``n4@Drone1``) is its number in the execution graph, and
numbers follow the text: one statement inserted into Drone2's part renumbers every
node after it, Drone1's too.  What a node *is* does not depend on that number:

:class:`Place`
    The drone that runs the node (``""`` for a fork, which every drone of its
    block copies), the block it is written in, its kind, its action, and its
    ordinal among the nodes that share all four, in execution-graph order.
    Editing Drone2's part changes no place of Drone1's.

:func:`rekey` renumbers an amended mission's nodes so that every node whose place
the running mission has keeps the running node's number (and key); new nodes are
numbered after the running mission's last.  Unchanged drones then have programs
equal to the ones they run, node for node, and their peers' triggers still name
the same nodes.  :func:`compare` says, per drone, which nodes an amendment adds,
removes and changes and which arcs it adds and removes; :func:`node_progress`
reads, from a run's snapshot, which nodes have already begun (they keep their
meaning: :mod:`eamos.check.amendment` refuses a change to one).

All pure: programs and graphs in, frozen records out.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections import defaultdict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import networkx as nx

from ..program.format import DroneProgram, ProgramArc, ProgramNode
from .phases import CompiledMission

#: Node attributes that name other nodes by execution-graph number.
_NUMBER_REFS = ("begin", "end", "catch")
_NUMBER_LISTS = ("loops", "scopes")


@dataclass(frozen=True, order=True)
class Place:
    """What a node is, independent of its number (see the module docstring)."""

    drone: str
    block: str
    kind: str
    action: str
    ordinal: int


@dataclass(frozen=True)
class NodeRef:
    """A node as an operator reads it: its key, drone, label and line."""

    key: str
    drone: str
    label: str
    line: int

    def describe(self) -> str:
        """``n12 FlyByY(3) (line 31)``."""
        where = f" (line {self.line})" if self.line else ""
        return f"{self.key} {self.label}{where}"


@dataclass(frozen=True)
class DroneChange:
    """What an amendment changes in one drone's program (after :func:`rekey`)."""

    drone: str
    added: tuple[NodeRef, ...] = ()
    removed: tuple[NodeRef, ...] = ()
    changed: tuple[NodeRef, ...] = ()
    arcs_added: tuple[tuple[str, str, str], ...] = ()
    arcs_removed: tuple[tuple[str, str, str], ...] = ()
    #: The nodes the change touches (added, removed, changed, or the head of an arc
    #: added or removed), keys only: what must not have begun.
    touched: tuple[str, ...] = ()
    #: The tails of arcs added or removed (what comes after them changes), keys only:
    #: what must not have ended (a running node may be redirected).
    redirected: tuple[str, ...] = ()
    #: The first of its own nodes the drone would run differently (None: none of its own).
    switch: NodeRef | None = None

    @property
    def changes(self) -> bool:
        """True when the drone's program differs in anything it executes."""
        return bool(self.touched or self.redirected)

    def to_json(self) -> dict[str, Any]:
        """The change as plain data (``eamos amend --json``)."""

        def refs(nodes: tuple[NodeRef, ...]) -> list[dict[str, Any]]:
            return [dataclasses.asdict(n) for n in nodes]

        return {
            "drone": self.drone,
            "added": refs(self.added),
            "removed": refs(self.removed),
            "changed": refs(self.changed),
            "arcs_added": [list(a) for a in self.arcs_added],
            "arcs_removed": [list(a) for a in self.arcs_removed],
            "touched": list(self.touched),
            "redirected": list(self.redirected),
            "switch": None if self.switch is None else dataclasses.asdict(self.switch),
        }


def _node_key(number: int, drone: str, fork: bool) -> str:
    return f"n{number}@{drone}" if fork else f"n{number}"


def _representatives(programs: Mapping[str, DroneProgram]) -> dict[int, ProgramNode]:
    """One node per execution-graph number: the native one where a program runs it."""
    found: dict[int, ProgramNode] = {}
    for program in programs.values():
        for node in program.nodes:
            if node.meg not in found or (node.native and not found[node.meg].native):
                found[node.meg] = node
    return found


def places(programs: Mapping[str, DroneProgram]) -> dict[int, Place]:
    """Each execution-graph number of ``programs``' nodes, with its :class:`Place`."""
    nodes = _representatives(programs)
    seen: defaultdict[tuple[str, str, str, str], int] = defaultdict(int)
    out: dict[int, Place] = {}
    for number in sorted(nodes):
        node = nodes[number]
        drone = "" if node.kind == "fork" else node.drone
        base = (drone, node.block, node.kind, node.action or "")
        out[number] = Place(*base, seen[base])
        seen[base] += 1
    return out


def renumbering(
    running: Mapping[str, DroneProgram], amended: Mapping[str, DroneProgram]
) -> dict[int, int]:
    """For each node number of ``amended``, the number it gets: the running node's of the
    same place, or a new one after the running mission's largest."""
    old = {place: number for number, place in places(running).items()}
    new = places(amended)
    fresh = max((n.meg for p in running.values() for n in p.nodes), default=-1) + 1
    out: dict[int, int] = {}
    for number in sorted(new):
        if new[number] in old:
            out[number] = old[new[number]]
        else:
            out[number] = fresh
            fresh += 1
    return out


def _renumbered_attrs(attrs: Mapping[str, Any], numbers: Mapping[int, int]) -> dict[str, Any]:
    """Node attributes with every execution-graph number in them renumbered."""
    out = dict(attrs)
    for name in _NUMBER_REFS:
        if out.get(name) is not None:
            out[name] = numbers[out[name]]
    for name in _NUMBER_LISTS:
        if out.get(name):
            out[name] = type(out[name])(numbers[n] for n in out[name])
    if "meg" in out:
        out["meg"] = numbers[out["meg"]]
    return out


def _renumbered_program(
    program: DroneProgram, numbers: Mapping[int, int], mission_id: str, mission: str
) -> DroneProgram:
    keys = {n.key: _node_key(numbers[n.meg], n.drone, "@" in n.key) for n in program.nodes}
    nodes = [
        dataclasses.replace(
            n,
            key=keys[n.key],
            **_renumbered_attrs(
                {f: getattr(n, f) for f in ("meg", *_NUMBER_REFS, *_NUMBER_LISTS)}, numbers
            ),
        )
        for n in program.nodes
    ]
    nodes.sort(key=lambda n: (n.meg, n.key))
    order = {n.key: n.meg for n in nodes}
    arcs = sorted(
        (ProgramArc(keys[a.src], keys[a.dst], a.kind, a.external) for a in program.arcs),
        key=lambda a: (order[a.src], order[a.dst], a.src, a.dst),
    )
    return dataclasses.replace(
        program, mission=mission, mission_id=mission_id, nodes=tuple(nodes), arcs=tuple(arcs)
    )


def _renumbered_graph(graph: nx.DiGraph, numbers: Mapping[int, int], keyed: bool) -> nx.DiGraph:
    """A copy of the execution graph (``keyed`` False: its nodes are numbers) or of a
    dependency graph (True: its nodes are keys, ``meg`` their number), renumbered."""

    def name(node: Any) -> Any:
        if not keyed:
            return numbers[node]
        number, _, drone = str(node)[1:].partition("@")
        return _node_key(numbers[int(number)], drone, bool(drone))

    out = nx.DiGraph(**graph.graph)
    for node, attrs in graph.nodes(data=True):
        out.add_node(name(node), **_renumbered_attrs(attrs, numbers))
    for a, b, attrs in graph.edges(data=True):
        out.add_edge(name(a), name(b), **attrs)
    return out


def rekey(running: Mapping[str, DroneProgram], amended: CompiledMission) -> CompiledMission:
    """``amended`` renumbered against the ``running`` programs (see the module docstring),
    carrying the running mission's id and name: the mission its drones run, amended (a
    text without a ``package`` line is named after its file, which an amended copy is not).

    The execution graph, the dependency graphs and the programs are renumbered; the
    mission tree keeps the numbers of the amended text (it is the text's tree).
    """
    first = next(iter(running.values()), None)
    mission_id = first.mission_id if first is not None else amended.mission_id
    name = first.mission if first is not None else amended.mission.name
    numbers = renumbering(running, amended.programs)
    return dataclasses.replace(
        amended,
        mission_id=mission_id,
        meg=_renumbered_graph(amended.meg, numbers, keyed=False),
        mdgs={d: _renumbered_graph(g, numbers, keyed=True) for d, g in amended.mdgs.items()},
        programs={
            d: _renumbered_program(p, numbers, mission_id, name)
            for d, p in amended.programs.items()
        },
    )


def execution_body(program: DroneProgram) -> dict[str, Any]:
    """What the drone executes: the program minus its descriptive fields.

    Left out: the mission id and file name, source positions, and the labels,
    actions, arguments and conditions of proxy nodes (nodes of other drones, which
    this drone never runs).  Kept: the compiler and the libraries the drone's part
    came from (a changed library redeploys the drones that use it).  Equal bodies
    mean the drone behaves the same: a roll-out keeps its program, an amendment does
    not touch it.
    """
    body = program.body()
    for name in ("mission_id", "source_file"):
        body.pop(name, None)
    body["nodes"] = [_jsonable(n.executed()) for n in program.nodes]
    return body


def _jsonable(doc: dict[str, Any]) -> dict[str, Any]:
    return json.loads(json.dumps(doc, sort_keys=True))


def execution_digest(program: DroneProgram) -> str:
    """``sha256:`` of :func:`execution_body`."""
    canonical = json.dumps(execution_body(program), sort_keys=True, separators=(",", ":"))
    return "sha256:" + hashlib.sha256(canonical.encode()).hexdigest()


def _ref(node: ProgramNode) -> NodeRef:
    return NodeRef(node.key, node.drone, node.label or node.kind, node.line)


def _first_in_order(program: DroneProgram, keys: Iterable[str]) -> NodeRef | None:
    """The first of ``keys`` (native nodes of ``program``) in the order it runs them."""
    wanted = set(keys)
    graph = nx.DiGraph()
    graph.add_nodes_from(n.key for n in program.nodes)
    graph.add_edges_from((a.src, a.dst) for a in program.arcs if a.kind != "loop")
    by_key = {n.key: n for n in program.nodes}
    order = nx.lexicographical_topological_sort(graph, key=lambda k: (by_key[k].meg, k))
    for key in order:
        if key in wanted and by_key[key].native:
            return _ref(by_key[key])
    return None


def drone_change(
    drone: str, running: DroneProgram | None, amended: DroneProgram | None
) -> DroneChange:
    """What changes in ``drone``'s program from ``running`` to ``amended`` (rekeyed)."""
    old = {n.key: n for n in running.nodes} if running else {}
    new = {n.key: n for n in amended.nodes} if amended else {}
    added = [new[k] for k in new if k not in old]
    removed = [old[k] for k in old if k not in new]
    changed = [new[k] for k in new if k in old and new[k].executed() != old[k].executed()]
    arcs_old = {(a.src, a.dst, a.kind) for a in running.arcs} if running else set()
    arcs_new = {(a.src, a.dst, a.kind) for a in amended.arcs} if amended else set()
    arcs_added = sorted(arcs_new - arcs_old)
    arcs_removed = sorted(arcs_old - arcs_new)
    touched = {n.key for n in (*added, *removed, *changed)}
    touched |= {arc[1] for arc in (*arcs_added, *arcs_removed)}
    redirected = {arc[0] for arc in (*arcs_added, *arcs_removed)} - touched
    if (
        running
        and amended
        and not touched
        and not redirected
        and execution_body(running) != execution_body(amended)
    ):
        touched = {n.key for n in amended.nodes}  # its place in the fleet changed: all of it
    switch = _first_in_order(amended, touched) if amended else None
    if switch is None and running is not None:
        switch = _first_in_order(running, touched)
    return DroneChange(
        drone,
        tuple(_ref(n) for n in added if n.native),
        tuple(_ref(n) for n in removed if n.native),
        tuple(_ref(n) for n in changed if n.native),
        tuple(arcs_added),
        tuple(arcs_removed),
        tuple(sorted(touched)),
        tuple(sorted(redirected)),
        switch,
    )


def compare(
    running: Mapping[str, DroneProgram], amended: Mapping[str, DroneProgram]
) -> dict[str, DroneChange]:
    """Per drone of either mission, what changes (``amended`` renumbered by :func:`rekey`)."""
    drones = list(dict.fromkeys([*running, *amended]))
    return {d: drone_change(d, running.get(d), amended.get(d)) for d in drones}


def node_progress(
    programs: Mapping[str, DroneProgram], reported: Mapping[str, str]
) -> dict[str, str]:
    """How far each node that has begun got: ``running`` or ``waiting`` as ``reported``
    (the last state a drone reported for it), ``ended`` for any other reported state and
    for every node before a node that has begun (its triggers went out), loops' back
    arcs aside.  A node absent has not begun."""
    graph = nx.DiGraph()
    for program in programs.values():
        graph.add_nodes_from(n.key for n in program.nodes)
        graph.add_edges_from((a.src, a.dst) for a in program.arcs if a.kind != "loop")
    progress = {
        k: (state if state in ("running", "waiting") else "ended")
        for k, state in reported.items()
        if k in graph
    }
    for key in list(progress):
        for before in nx.ancestors(graph, key):
            progress[before] = "ended"
    return progress


__all__ = [
    "DroneChange",
    "NodeRef",
    "Place",
    "compare",
    "drone_change",
    "execution_body",
    "execution_digest",
    "node_progress",
    "places",
    "rekey",
    "renumbering",
]
