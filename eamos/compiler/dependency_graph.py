"""Phase 5: Mission Execution Graph -> one Mission Dependency Graph per drone.

The paper's slicing (Section V-C, Algorithms 1 to 4, Figure 8).  For every
drone ``d`` (the ground station ``GCS`` included) and every MEG node ``n``
hosted by ``d``:

1. *Forward fork processing* (Algorithm 2): for each fork ``s`` following
   ``n``, find the non-fork leaves reachable through forks only; for every
   other drone ``d'`` owning one of them, add the fork proxy ``s@d'`` and
   link ``n -> s@d'``.
2. *Current node processing* (Algorithm 3): add ``n`` and link it with its
   non-fork predecessors and successors.
3. *Backward fork processing* (Algorithm 4): for each fork parent of ``n``,
   replicate the chain of forks above it for ``d`` (internal arcs) and link
   the non-fork predecessors of the topmost fork to it.

A link between nodes of different drones is an *external* arc (dashed); it
appears once in the sender's MDG and once in the receiver's, under the same
node keys, which is what the bridges send.

MDG node keys: ``"n<id>"`` for non-fork nodes (one drone each) and
``"n<id>@<drone>"`` for the replica of fork ``<id>`` on that drone.  Node
attributes: ``meg`` (MEG id), ``drone`` (the drone that executes it),
``native`` (executed in this MDG) or proxy (a node of another drone this MDG
sends to or receives from), plus the MEG node's attributes for natives.
Edge attributes: ``kind`` (the MEG arc kind) and ``external``.
"""

from __future__ import annotations

import re

import networkx as nx

from ..program.uniform import GROUND_STATION
from .errors import CompilerBug, Diagnostic, MissionError, SourceLocation
from .limits import MAX_SYNC_ARCS, amount


class _MegIndex:
    """What every drone's slicing reads from the MEG, computed once for all drones.

    Slicing runs once per drone; looking nodes, arcs and fork leaves up in
    plain dicts here (instead of networkx views, per drone) keeps the whole
    slicing linear in the MEG's size times the drones a node talks to.
    """

    def __init__(self, meg: nx.DiGraph) -> None:
        self.meg = meg
        self.forks = frozenset(n for n, a in meg.nodes(data=True) if a["kind"] == "fork")
        self.host: dict[int, str] = {n: str(a["drone"]) for n, a in meg.nodes(data=True)}
        # Each drone's own nodes, in MEG order (the paper's loop visits only these).
        self.by_drone: dict[str, list[int]] = {}
        for n in meg:
            if n not in self.forks:
                self.by_drone.setdefault(self.host[n], []).append(n)
        self.succ: dict[int, list[int]] = {n: list(meg.successors(n)) for n in meg}
        self.pred: dict[int, list[int]] = {n: list(meg.predecessors(n)) for n in meg}
        self.arc_kind: dict[tuple[int, int], str] = {
            (a, b): d["kind"] for a, b, d in meg.edges(data=True)
        }
        self._leaves: dict[int, frozenset[str]] = {}

    def key(self, node: int, drone: str) -> str:
        return f"n{node}@{drone}" if node in self.forks else f"n{node}"

    def leaf_drones(self, fork: int) -> frozenset[str]:
        """Drones of the non-fork nodes reachable from ``fork`` through forks only."""
        cached = self._leaves.get(fork)
        if cached is None:
            drones: set[str] = set()
            for child in self.succ[fork]:
                if child in self.forks:
                    drones |= self.leaf_drones(child)
                else:
                    drones.add(self.host[child])
            cached = self._leaves[fork] = frozenset(drones)
        return cached


class _Slicer:
    def __init__(self, index: _MegIndex, drone: str) -> None:
        self.ix = index
        self.meg = index.meg
        self.drone = drone
        self.mdg = nx.DiGraph(drone=drone, **index.meg.graph)

    def is_fork(self, node: int) -> bool:
        return node in self.ix.forks

    def ensure(self, node: int, drone: str) -> str:
        key = self.ix.key(node, drone)
        if key not in self.mdg:
            attrs = dict(self.meg.nodes[node])
            attrs["drone"] = drone
            self.mdg.add_node(key, meg=node, native=(drone == self.drone), **attrs)
        return key

    def host(self, node: int) -> str:
        return self.ix.host[node]

    def link(self, src: int, src_drone: str, dst: int, dst_drone: str, kind: str) -> None:
        a = self.ensure(src, src_drone)
        b = self.ensure(dst, dst_drone)
        self.mdg.add_edge(a, b, kind=kind, external=(src_drone != dst_drone))

    def forward(self, n: int) -> None:
        for s in self.ix.succ[n]:
            if not self.is_fork(s):
                continue
            kind = self.ix.arc_kind[n, s]
            for other in sorted(self.ix.leaf_drones(s) - {self.drone}):
                self.link(n, self.drone, s, other, kind)

    def current(self, n: int) -> None:
        self.ensure(n, self.drone)
        for s in self.ix.succ[n]:
            if not self.is_fork(s):
                self.link(n, self.drone, s, self.host(s), self.ix.arc_kind[n, s])
        for p in self.ix.pred[n]:
            if not self.is_fork(p):
                self.link(p, self.host(p), n, self.drone, self.ix.arc_kind[p, n])

    def backward(self, n: int) -> None:
        for p in self.ix.pred[n]:
            if not self.is_fork(p):
                continue
            child = n
            fork = p
            while True:
                already = self.ix.key(fork, self.drone) in self.mdg
                self.link(fork, self.drone, child, self.drone, self.ix.arc_kind[fork, child])
                if already:
                    break  # the chain above was replicated by an earlier node
                parents = self.ix.pred[fork]
                fork_parents = [q for q in parents if self.is_fork(q)]
                if fork_parents:
                    if len(parents) != 1:
                        raise CompilerBug(f"fork {fork} has a fork parent and other parents")
                    child, fork = fork, fork_parents[0]
                    continue
                for q in parents:
                    self.link(q, self.host(q), fork, self.drone, self.ix.arc_kind[q, fork])
                break

    def run(self) -> nx.DiGraph:
        for n in self.ix.by_drone.get(self.drone, ()):
            self.forward(n)
            self.current(n)
            self.backward(n)
        return self.mdg


def natural_key(name: str) -> tuple[str | int, ...]:
    """Drone2 before Drone10, Team_9 before Team_10: numbers in names compare as numbers."""
    return tuple(int(p) if p.isdigit() else p for p in re.split(r"(\d+)", name))


def fleet(meg: nx.DiGraph) -> list[str]:
    """Every participant hosting MEG nodes: the ground station first, then drones by name.

    Names in natural order (:func:`natural_key`), so that a group's members
    ``Team_0 .. Team_99`` and numbered drones ``D1 .. D100`` stand in that order
    (the default homes follow it, docs/safety.md).
    """
    drones = {a["drone"] for _, a in meg.nodes(data=True) if a["kind"] != "fork"}
    return [GROUND_STATION, *sorted(drones - {GROUND_STATION}, key=natural_key)]


def slice_dependency_graphs(meg: nx.DiGraph) -> dict[str, nx.DiGraph]:
    """Slice the MEG into one MDG per participant (ground station included).

    Raises :class:`~.errors.MissionError` (before slicing) for a mission whose
    forks would need more than :data:`~.limits.MAX_SYNC_ARCS` arcs.
    """
    index = _MegIndex(meg)
    too_many = _sync_arcs_error(index)
    if too_many is not None:
        raise MissionError([too_many])
    return {drone: _Slicer(index, drone).run() for drone in fleet(meg)}


def _sync_arcs_error(index: _MegIndex) -> Diagnostic | None:
    """An error if the forks would tie too many branches to too many drones.

    A PAR block that starts right after p parallel branches end makes each of
    its d drones hear from each branch: p x d arcs (twice: sender and receiver
    MDGs).  Two PAR blocks of 1 000 drones in a row would need a million, so
    the sum is counted here, in one pass, before anything is sliced.
    """
    total, worst, worst_arcs = 0, -1, 0
    for fork in sorted(index.forks):
        ends = sum(1 for p in index.pred[fork] if p not in index.forks)
        if not ends:
            continue
        arcs = ends * len(index.leaf_drones(fork))
        total += arcs
        if arcs > worst_arcs:
            worst, worst_arcs = fork, arcs
    if total <= MAX_SYNC_ARCS:
        return None
    attrs = index.meg.nodes[worst]
    ends = sum(1 for p in index.pred[worst] if p not in index.forks)
    drones = len(index.leaf_drones(worst))
    block = str(attrs.get("label", ""))
    loc = SourceLocation(int(attrs.get("line", 1)), int(attrs.get("col", 1)))
    return Diagnostic(
        "error",
        loc,
        f"block '{block}' starts {drones} drones right after {ends} parallel branches end: "
        f"each drone waits for each branch ({amount(worst_arcs)} arcs; {amount(total)} in the "
        f"whole mission, more than the limit of {amount(MAX_SYNC_ARCS)})",
        "put one step between the PAR blocks (e.g. Drone1.PauseFor(0)): the branches then "
        "tell one drone, and it tells the next ones",
        loc.col + len(block),
    )


def mdg_stats(mdg: nx.DiGraph) -> dict[str, int]:
    """Paper Table 7's columns for one MDG: nodes, internal arcs, external in/out arcs."""
    drone = mdg.graph["drone"]
    internal = ext_in = ext_out = 0
    for _, b, data in mdg.edges(data=True):
        if not data["external"]:
            internal += 1
        elif mdg.nodes[b]["drone"] == drone:
            ext_in += 1
        else:
            ext_out += 1
    return {
        "nodes": mdg.number_of_nodes(),
        "internal_arcs": internal,
        "external_in": ext_in,
        "external_out": ext_out,
    }
