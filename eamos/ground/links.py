"""Trigger counts per link (drone A -> drone B) and per arc, derived from node states (pure).

The drones count the triggers their Out-Bridge sends and their In-Bridge
receives, but say so only in their final report.  The monitor (live) and the
mission snapshot (``snapshot.json``, per arc) count them from what the ground
station already hears -- each node's state changes
(``Progress``), ``Resolved`` -- and the compiled programs' arcs, using the
rules the node logic (:mod:`eamos.actors.logic`) follows:

* a node that *resolved* for an activation (an action ``ok``/``failed``/
  ``cancelled``, a node ``skipped`` or ``blocked``, an If ``decided``, a Wait
  that handed on) triggered each of its outgoing arcs once for it: its
  external ones are *sent* (a loop's begin node triggers its Exit arcs when it
  resolves; its Body arcs once per iteration, known from the iterations seen);
* a node that *fired* for an activation (it ran, or resolved) received a
  trigger on every entry arc for it: its external ones are *received*, and its
  predecessors resolved -- up the graph, across drones;
* a loop's begin node seen at iteration ``k`` (a node of its Body ran with
  counter ``k``) received the back arcs (``loop``) of iterations ``0 .. k-1``;
  when it resolved, those of every iteration seen;
* ``Resolved`` from a participant: every top-level node it executes resolved.

Each trigger (arc, iteration) is counted once.  For a run that ends normally
the totals equal the reports' ``triggers_sent``/``triggers_received`` (paper
Table 7); they run a little behind while the mission runs (a trigger counts
as received when its node is seen to fire).  After an abort, triggers the
drones held back can be counted as sent.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from eamos.program.format import DroneProgram

#: Node kinds whose begin node counts iterations (their Body arcs carry the counter).
LOOP_KINDS = frozenset({"repeat_while", "repeat_until", "repeat_for"})
#: Progress states (:data:`eamos.net.wire.Progress.state`) of a node that fired.
FIRED_STATES = frozenset({"running", "waiting"})
#: Progress states of a node that resolved (and so triggered its outgoing arcs).
RESOLVED_STATES = frozenset(
    {"ok", "failed", "caught", "cancelled", "skipped", "blocked", "decided"}
)

Iteration = tuple[int, ...]


@dataclass(frozen=True)
class LinkArc:
    """One MDG arc: ``src`` -> ``dst`` (node keys), its kind, whether it crosses drones."""

    src: str
    dst: str
    kind: str
    external: bool


@dataclass(frozen=True)
class LinkGraph:
    """The whole mission's MDG as the link counts need it (every participant's arcs, once).

    ``owner``: node key -> the participant executing it; ``loops``: node key ->
    the keys of the loop begin nodes around it (outermost first); ``kinds``:
    node key -> kind; ``arcs``: every arc once.
    """

    owner: Mapping[str, str]
    kinds: Mapping[str, str]
    loops: Mapping[str, tuple[str, ...]]
    arcs: tuple[LinkArc, ...]

    @classmethod
    def from_programs(cls, programs: Iterable[DroneProgram]) -> LinkGraph:
        """The graph of a mission from its participants' programs."""
        owner: dict[str, str] = {}
        kinds: dict[str, str] = {}
        megs: dict[str, int] = {}
        arcs: dict[tuple[str, str, str], LinkArc] = {}
        progs = list(programs)
        for program in progs:
            for node in program.nodes:
                if node.native:
                    owner[node.key], kinds[node.key], megs[node.key] = (
                        node.drone,
                        node.kind,
                        node.meg,
                    )
            for arc in program.arcs:
                arcs.setdefault(
                    (arc.src, arc.dst, arc.kind), LinkArc(arc.src, arc.dst, arc.kind, arc.external)
                )
        begin_of = {megs[k]: k for k in megs if kinds[k] in LOOP_KINDS}
        loops = {
            node.key: tuple(begin_of.get(m, f"n{m}") for m in node.loops)
            for program in progs
            for node in program.nodes
            if node.native
        }
        return cls(owner, kinds, loops, tuple(arcs.values()))

    def links(self) -> dict[tuple[str, str], int]:
        """External arcs per link (source participant, destination participant)."""
        out: dict[tuple[str, str], int] = {}
        for arc in self.arcs:
            if arc.external and arc.src in self.owner and arc.dst in self.owner:
                link = (self.owner[arc.src], self.owner[arc.dst])
                out[link] = out.get(link, 0) + 1
        return dict(sorted(out.items()))


@dataclass(frozen=True)
class LinkCount:
    """One link's counts: its external arcs in the MDG, triggers sent and received so far."""

    src: str
    dst: str
    arcs: int
    sent: int
    received: int

    def to_json(self) -> dict[str, object]:
        return {
            "src": self.src,
            "dst": self.dst,
            "arcs": self.arcs,
            "sent": self.sent,
            "received": self.received,
        }


class LinkCounts:
    """Counts triggers per link from node events (see the module docstring); no clock."""

    def __init__(self, graph: LinkGraph) -> None:
        self.graph = graph
        self.arcs = graph.links()
        self._entry: dict[str, list[LinkArc]] = {}  # node -> its entry arcs (not "loop")
        self._back: dict[str, list[LinkArc]] = {}  # loop begin -> its "loop" arcs
        self._out: dict[str, list[LinkArc]] = {}  # node -> its external outgoing arcs
        for arc in graph.arcs:
            if arc.src not in graph.owner or arc.dst not in graph.owner:
                continue
            (self._back if arc.kind == "loop" else self._entry).setdefault(arc.dst, []).append(arc)
            if arc.external:
                self._out.setdefault(arc.src, []).append(arc)
        self._fired: set[tuple[str, Iteration]] = set()
        self._resolved: set[tuple[str, Iteration]] = set()
        self._counter: dict[tuple[str, Iteration], int] = {}  # (begin, act) -> highest counter
        self._back_done: dict[tuple[str, Iteration], int] = {}  # (begin, act) -> counters done
        self.sent: dict[tuple[str, str], set[tuple[str, str, Iteration]]] = {}
        self.received: dict[tuple[str, str], set[tuple[str, str, Iteration]]] = {}
        self._changed: set[tuple[str, str]] = set()
        self._todo: list[tuple[bool, str, Iteration]] = []  # (resolved?, node, activation)

    # -- inputs -------------------------------------------------------------------------

    def progress(self, node: str, state: str, iteration: Iteration) -> list[LinkCount]:
        """A node's state change (a Progress event); the links whose counts changed."""
        if node in self.graph.owner:
            if state in RESOLVED_STATES:
                self._resolve(node, iteration)
            elif state in FIRED_STATES:
                self._fire(node, iteration)
        return self._take()

    def started(self) -> list[LinkCount]:
        """The start trigger: every node without entry arcs (the initial node) resolved."""
        for node, kind in self.graph.kinds.items():
            if kind == "init" and not self._entry.get(node):
                self._resolve(node, ())
        return self._take()

    def resolved(self, participant: str) -> list[LinkCount]:
        """``participant`` said Resolved: every top-level node it executes resolved."""
        for node, owner in self.graph.owner.items():
            if owner == participant and not self.graph.loops.get(node):
                self._resolve(node, ())
        return self._take()

    # -- outputs --------------------------------------------------------------------------

    def counts(self) -> list[LinkCount]:
        """Every link with external arcs, in order."""
        return [self._count(link) for link in self.arcs]

    def per_arc(self) -> list[dict[str, Any]]:
        """Every arc between drones: its nodes and drones, and the triggers sent and
        received on it so far (each iteration once), in the graph's order."""
        sent: dict[tuple[str, str], int] = {}
        received: dict[tuple[str, str], int] = {}
        for found, into in ((self.sent, sent), (self.received, received)):
            for keys in found.values():
                for src, dst, _ in keys:
                    into[(src, dst)] = into.get((src, dst), 0) + 1
        out: list[dict[str, Any]] = []
        for arc in self.graph.arcs:
            if arc.external and arc.src in self.graph.owner and arc.dst in self.graph.owner:
                key = (arc.src, arc.dst)
                out.append(
                    {
                        "from": self.graph.owner[arc.src],
                        "to": self.graph.owner[arc.dst],
                        "src": arc.src,
                        "dst": arc.dst,
                        "kind": arc.kind,
                        "sent": sent.get(key, 0),
                        "received": received.get(key, 0),
                    }
                )
        return out

    def totals(self) -> dict[str, tuple[int, int]]:
        """Per participant: (triggers sent, triggers received) so far."""
        out: dict[str, tuple[int, int]] = {}
        for c in self.counts():
            s, r = out.get(c.src, (0, 0))
            out[c.src] = (s + c.sent, r)
            s, r = out.get(c.dst, (0, 0))
            out[c.dst] = (s, r + c.received)
        return out

    def _count(self, link: tuple[str, str]) -> LinkCount:
        return LinkCount(
            link[0],
            link[1],
            self.arcs.get(link, 0),
            len(self.sent.get(link, ())),
            len(self.received.get(link, ())),
        )

    def _take(self) -> list[LinkCount]:
        self._drain()
        changed, self._changed = self._changed, set()
        return [self._count(link) for link in sorted(changed)]

    # -- the rules ----------------------------------------------------------------------

    def _link(self, arc: LinkArc) -> tuple[str, str]:
        return self.graph.owner[arc.src], self.graph.owner[arc.dst]

    def _send(self, arc: LinkArc, iteration: Iteration) -> None:
        link = self._link(arc)
        got = self.sent.setdefault(link, set())
        if (arc.src, arc.dst, iteration) not in got:
            got.add((arc.src, arc.dst, iteration))
            self._changed.add(link)

    def _receive(self, arc: LinkArc, iteration: Iteration) -> None:
        self._send(arc, iteration)  # what arrived was sent
        link = self._link(arc)
        got = self.received.setdefault(link, set())
        if (arc.src, arc.dst, iteration) not in got:
            got.add((arc.src, arc.dst, iteration))
            self._changed.add(link)

    def _is_loop(self, node: str) -> bool:
        return self.graph.kinds.get(node) in LOOP_KINDS

    def _resolve(self, node: str, act: Iteration) -> None:
        """Learnt: ``node`` resolved for ``act`` (worked off by :meth:`_drain`)."""
        self._todo.append((True, node, act))

    def _fire(self, node: str, act: Iteration) -> None:
        """Learnt: ``node`` fired for ``act`` (worked off by :meth:`_drain`)."""
        self._todo.append((False, node, act))

    def _drain(self) -> None:
        # A work list, not recursion: one Resolved can walk a long mission's whole chain.
        while self._todo:
            resolved, node, act = self._todo.pop()
            if resolved:
                self._resolved_now(node, act)
            else:
                self._fired_now(node, act)

    def _resolved_now(self, node: str, act: Iteration) -> None:
        """``node`` resolved for ``act``: it fired, and triggered its outgoing arcs."""
        if (node, act) in self._resolved:
            return
        self._resolved.add((node, act))
        self._fire(node, act)
        loop = self._is_loop(node)
        for arc in self._out.get(node, ()):
            if not (loop and arc.kind == "body"):  # Body arcs: per iteration (_iteration)
                self._send(arc, act)
        if loop and (node, act) in self._counter:
            self._back_arcs(node, act, self._counter[(node, act)] + 1)

    def _fired_now(self, node: str, act: Iteration) -> None:
        """``node`` fired for ``act``: every entry arc delivered its trigger for it."""
        if (node, act) in self._fired:
            return
        self._fired.add((node, act))
        loops = self.graph.loops.get(node, ())
        if loops and len(act) == len(loops):
            self._iteration(loops[-1], act[:-1], act[-1])
        for arc in self._entry.get(node, ()):
            pred = arc.src
            depth = len(self.graph.loops.get(pred, ()))
            pred_act = act[:depth]
            body = self._is_loop(pred) and arc.kind == "body"
            trigger = act if body else pred_act
            if arc.external:
                self._receive(arc, trigger)
            if body:
                self._fire(pred, pred_act)  # a begin node sending Body has not resolved
            else:
                self._resolve(pred, pred_act)

    def _iteration(self, begin: str, act: Iteration, counter: int) -> None:
        """Loop ``begin`` ran iteration ``counter`` of its activation ``act``."""
        key = (begin, act)
        self._fire(begin, act)
        if counter > self._counter.get(key, -1):
            self._counter[key] = counter
        for arc in self._out.get(begin, ()):
            if arc.kind == "body":
                self._send(arc, (*act, counter))
        self._back_arcs(begin, act, counter)
        if (begin, act) in self._resolved:
            self._back_arcs(begin, act, self._counter[key] + 1)

    def _back_arcs(self, begin: str, act: Iteration, upto: int) -> None:
        """Iterations ``0 .. upto-1`` of ``begin`` ended: their back arcs delivered."""
        key = (begin, act)
        done = self._back_done.get(key, 0)
        if upto <= done:
            return
        self._back_done[key] = upto
        for counter in range(done, upto):
            iteration = (*act, counter)
            for arc in self._back.get(begin, ()):
                if arc.external:
                    self._receive(arc, iteration)
                self._resolve(arc.src, iteration)
