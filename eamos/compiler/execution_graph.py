"""Phase 4: Abstract Mission Tree -> Mission Execution Graph (paper V-B2, Figure 7).

"Closing" the AMT: sequential nodes disappear and their children are chained
so that the last nodes of one statement point to the first nodes of the next.
Forks (``par``) stay.  Control structures become a *begin* node (the AMT's
control node, which evaluates the condition) and, where branches must join
again, an ``end`` node on the same drone.

Node ids are the AMT's ids (so Figure 6 and Figure 7 number nodes alike);
``end`` nodes get new ids after the AMT's largest.  Node attributes are the
AMT's (``par`` becomes ``fork``) plus:

``loops``
    Ids of the loops (``repeat_*`` begin nodes) enclosing the node, outermost
    first.  A trigger carries one iteration counter per enclosing loop.
``scopes``
    Ids of the ``do_*``, ``repeat_*`` and ``try`` begin nodes whose body
    contains the node: the structures that may interrupt it.
``suspend_drones``
    On a ``whenever`` begin node: the drones its Handler uses that also run
    statements it guards (their running actions are suspended while the
    Handler runs, then re-issued).  Its ``interrupt_drones`` are the drones of
    the guarded statements (an ``Abandon()`` in the Handler skips them there;
    ``abandon`` nodes carry the same list).
``suspendable``, ``in_handler``
    On action nodes: a Whenever's firing may suspend it (it is guarded by the
    Whenever, on one of its ``suspend_drones``); it is part of a Handler.
``catch``, ``catch_loops``, ``catch_drones``, ``catch_line``
    On nodes inside a Try's Body: the innermost Try's begin node (it catches
    the node's failure), how many of the node's loops enclose that Try, and the
    drones whose part of Body a failure there cancels; ``catch_line``: where
    that Try is written.
``end`` / ``begin``
    On a begin node, the id of its ``end`` node; on an ``end`` node, its begin.
``interrupt_drones``, ``interrupt_mode``
    On ``do_*``, ``try`` and ``repeat_*`` begin nodes: the drones to tell when
    the body is interrupted, and what is interrupted there (``all`` for Do and
    Try: the running action is cancelled and the rest of Body skipped;
    ``waits`` for Repeat: only Wait/Pause conditions in Body are abandoned).

Edge attribute ``kind``: ``seq`` (plain order), ``then``/``else`` (If
branches), ``body`` (into a structure's Body), ``exit`` (into its Exit or
straight to its end), ``loop`` (back arc from Body's last nodes to the loop
begin, drawn dotted; from a Handler's last nodes to its Whenever), ``begin``
(a Do's, Try's or Whenever's begin to its end) and ``handler`` (a Whenever to
its Handler).

Shapes per construct (C = begin, E = end, X = Exit block):

* ``If``: C -then-> Then -> E, C -else-> Else -> E (or C -else-> E).
* ``WaitWhile``/``WaitUntil``: C -body-> Body; Body's last nodes end it.
* ``PauseWhile``/``PauseUntil``: C alone.
* ``Repeat*``: C -body-> Body -loop-> C, C -exit-> X -> E (or C -exit-> E).
* ``Do*``: C -body-> Body -> E, C -begin-> E, E -exit-> X; it ends with E and X.
* ``Try``: as a Do, with OnFailure as X: C -body-> Body -> E, C -begin-> E,
  E -exit-> OnFailure; E runs OnFailure only if Body failed.
* ``Whenever``: C -body-> R -> E (R: the statements after it in its block),
  C -begin-> E, C -handler-> H -loop-> C (H: the Handler, re-armed per firing).
* ``Abandon()``: a plain node in H (``begin``: its Whenever).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import networkx as nx

from .errors import CompilerBug
from .mission_tree import (
    CONTROL_KINDS,
    DO_KINDS,
    LOOP_KINDS,
    TRY_KINDS,
    WAIT_KINDS,
    WHENEVER_KINDS,
)

_CARRIED = (
    "kind",
    "drone",
    "label",
    "block",
    "line",
    "col",
    "action",
    "args",
    "cond",
    "count",
    "begin",  # Abandon(): its Whenever
)


@dataclass(frozen=True)
class _Fragment:
    entries: tuple[int, ...]
    exits: tuple[int, ...]


class _Closer:
    def __init__(self, amt: nx.DiGraph) -> None:
        self.amt = amt
        self.meg = nx.DiGraph(**amt.graph)
        self.next_id = max(amt.nodes) + 1
        self.shared: dict[int, _Fragment] = {}

    def children(self, node: int, role: str | None = None) -> list[int]:
        out = [
            (d.get("order", 0), c)
            for _, c, d in self.amt.out_edges(node, data=True)
            if role is None or d["role"] == role
        ]
        return [c for _, c in sorted(out)]

    def add(
        self, node: int, loops: tuple[int, ...], scopes: tuple[int, ...], **extra: object
    ) -> int:
        attrs = (
            {k: v for k, v in self.amt.nodes[node].items() if k in _CARRIED}
            if node in self.amt
            else {}
        )
        attrs.update(extra)
        if attrs.get("kind") == "par":
            attrs["kind"] = "fork"
            attrs["drone"] = ""
        self.meg.add_node(node, loops=loops, scopes=scopes, **attrs)
        return node

    def connect(self, sources: tuple[int, ...], targets: tuple[int, ...], kind: str) -> None:
        for s in sources:
            for t in targets:
                if self.meg.has_edge(s, t) and self.meg.edges[s, t]["kind"] != kind:
                    raise CompilerBug(
                        f"two arcs {s}->{t} of kinds {self.meg.edges[s, t]['kind']}/{kind}"
                    )
                self.meg.add_edge(s, t, kind=kind)

    def build(self, node: int, loops: tuple[int, ...], scopes: tuple[int, ...]) -> _Fragment:
        kind = self.amt.nodes[node]["kind"]
        if kind == "seq":
            frags = [self.build(c, loops, scopes) for c in self.children(node)]
            for a, b in itertools.pairwise(frags):
                self.connect(a.exits, b.entries, "seq")
            return _Fragment(frags[0].entries, frags[-1].exits)
        if kind == "par":
            fork = self.add(node, loops, scopes)
            # An insertion-ordered set: a PAR block of thousands of branches stays linear.
            exits: dict[int, None] = {}
            for child in self.children(node):
                frag = self.build(child, loops, scopes)
                self.connect((fork,), frag.entries, "seq")
                exits.update(dict.fromkeys(frag.exits))
            return _Fragment((fork,), tuple(exits))
        if kind in ("action", "abandon"):
            self.add(node, loops, scopes)
            return _Fragment((node,), (node,))
        if kind == "init":
            self.add(node, loops, scopes)
            (child,) = self.children(node)
            frag = self.build(child, loops, scopes)
            self.connect((node,), frag.entries, "seq")
            return _Fragment((node,), frag.exits)
        if kind in CONTROL_KINDS:
            return self.control(node, kind, loops, scopes)
        raise CompilerBug(f"unknown AMT node kind {kind!r}")

    def end_node(self, begin: int, loops: tuple[int, ...], scopes: tuple[int, ...]) -> int:
        attrs = self.amt.nodes[begin]
        end = self.next_id
        self.next_id += 1
        self.meg.add_node(
            end,
            kind="end",
            drone=attrs["drone"],
            label="end " + attrs["label"].split(" ")[0],
            block=attrs["block"],
            line=attrs["line"],
            col=attrs["col"],
            loops=loops,
            scopes=scopes,
            begin=begin,
        )
        self.meg.nodes[begin]["end"] = end
        return end

    def exit_block(
        self, node: int, loops: tuple[int, ...], scopes: tuple[int, ...]
    ) -> _Fragment | None:
        exits = self.children(node, "exit")
        if not exits:
            return None
        (exit_root,) = exits
        if exit_root not in self.shared:
            self.shared[exit_root] = self.build(exit_root, loops, scopes)
        return self.shared[exit_root]

    def control(
        self, node: int, kind: str, loops: tuple[int, ...], scopes: tuple[int, ...]
    ) -> _Fragment:
        begin = self.add(node, loops, scopes)
        if kind in WAIT_KINDS:
            bodies = self.children(node, "body")
            if not bodies:  # PauseWhile / PauseUntil
                return _Fragment((begin,), (begin,))
            body = self.build(bodies[0], loops, scopes)
            self.connect((begin,), body.entries, "body")
            return _Fragment((begin,), body.exits)
        end = self.end_node(begin, loops, scopes)
        if kind in WHENEVER_KINDS:
            return self.whenever(node, begin, end, loops, scopes)
        if kind == "if":
            (then_root,) = self.children(node, "then")
            then = self.build(then_root, loops, scopes)
            self.connect((begin,), then.entries, "then")
            self.connect(then.exits, (end,), "seq")
            else_roots = self.children(node, "else")
            if else_roots:
                orelse = self.build(else_roots[0], loops, scopes)
                self.connect((begin,), orelse.entries, "else")
                self.connect(orelse.exits, (end,), "seq")
            else:
                self.connect((begin,), (end,), "else")
            return _Fragment((begin,), (end,))
        (body_root,) = self.children(node, "body")
        if kind in LOOP_KINDS:
            body = self.build(body_root, (*loops, begin), (*scopes, begin))
            self.connect((begin,), body.entries, "body")
            self.connect(body.exits, (begin,), "loop")
            exit_frag = self.exit_block(node, loops, scopes)
            if exit_frag is None:
                self.connect((begin,), (end,), "exit")
            else:
                self.connect((begin,), exit_frag.entries, "exit")
                self.connect(exit_frag.exits, (end,), "seq")
            return _Fragment((begin,), (end,))
        if kind in DO_KINDS or kind in TRY_KINDS:
            body = self.build(body_root, loops, (*scopes, begin))
            self.connect((begin,), body.entries, "body")
            self.connect(body.exits, (end,), "seq")
            self.connect((begin,), (end,), "begin")
            exit_frag = self.exit_block(node, loops, scopes)
            if exit_frag is None:
                return _Fragment((begin,), (end,))
            self.connect((end,), exit_frag.entries, "exit")
            return _Fragment((begin,), (end, *(x for x in exit_frag.exits if x != end)))
        raise CompilerBug(f"unknown control kind {kind!r}")  # pragma: no cover

    def whenever(
        self, node: int, begin: int, end: int, loops: tuple[int, ...], scopes: tuple[int, ...]
    ) -> _Fragment:
        """C -body-> guarded statements -> E, C -begin-> E, C -handler-> Handler -loop-> C.

        The Handler is re-armed like a loop body (C is one of its ``loops``: each
        firing has its own counter); the guarded statements are in C's scope.
        """
        (rest_root,) = self.children(node, "body")
        rest = self.build(rest_root, loops, (*scopes, begin))
        self.connect((begin,), rest.entries, "body")
        self.connect(rest.exits, (end,), "seq")
        self.connect((begin,), (end,), "begin")
        (handler_root,) = self.children(node, "handler")
        handler = self.build(handler_root, (*loops, begin), scopes)
        self.connect((begin,), handler.entries, "handler")
        self.connect(handler.exits, (begin,), "loop")
        return _Fragment((begin,), (end,))


def build_execution_graph(amt: nx.DiGraph) -> nx.DiGraph:
    """Close an Abstract Mission Tree into its Mission Execution Graph."""
    closer = _Closer(amt)
    closer.build(amt.graph.get("root", 0), (), ())
    meg = closer.meg
    # One pass over the nodes (not one per structure: experiment D has a loop per
    # square, stress missions thousands): each node tells the structures whose
    # body holds it that its drone must hear of an interruption.
    scoped: dict[int, set[str]] = {}
    waiting: dict[int, set[str]] = {}
    for attrs in meg.nodes.values():
        if attrs["kind"] == "fork":
            continue
        for scope in attrs["scopes"]:
            scoped.setdefault(scope, set()).add(attrs["drone"])
            if attrs["kind"] in WAIT_KINDS:
                waiting.setdefault(scope, set()).add(attrs["drone"])
    for node, attrs in meg.nodes(data=True):
        kind = attrs["kind"]
        if kind in DO_KINDS or kind in LOOP_KINDS or kind in TRY_KINDS or kind in WHENEVER_KINDS:
            mode = "waits" if kind in LOOP_KINDS else "all"
            drones = scoped.get(node, set()) if mode == "all" else waiting.get(node, set())
            attrs["interrupt_mode"] = mode
            attrs["interrupt_drones"] = tuple(sorted(drones))
    _mark_catchers(meg)
    _mark_handlers(meg)
    return meg


def _mark_handlers(meg: nx.DiGraph) -> None:
    """Whenever: the drones a firing suspends; Abandon(): the drones it stops.

    ``suspend_drones`` on a Whenever are the drones its Handler uses that also
    run guarded statements (their running actions are interrupted while the
    Handler runs); an ``abandon`` node gets its Whenever's ``interrupt_drones``.
    """
    whenevers = {n for n, a in meg.nodes(data=True) if a["kind"] in WHENEVER_KINDS}
    if not whenevers:
        return
    handler_drones: dict[int, set[str]] = {}
    for attrs in meg.nodes.values():
        if attrs["kind"] == "fork":
            continue
        for loop in attrs["loops"]:
            if loop in whenevers:
                handler_drones.setdefault(loop, set()).add(attrs["drone"])
    for node in whenevers:
        attrs = meg.nodes[node]
        attrs["suspend_drones"] = tuple(
            sorted(handler_drones.get(node, set()) & set(attrs["interrupt_drones"]))
        )
    for attrs in meg.nodes.values():
        if attrs["kind"] == "abandon":
            attrs["interrupt_drones"] = meg.nodes[attrs["begin"]]["interrupt_drones"]
            attrs["interrupt_mode"] = "all"
        if attrs["kind"] != "action":
            continue
        if any(loop in whenevers for loop in attrs["loops"]):
            attrs["in_handler"] = True
        if any(
            s in whenevers and attrs["drone"] in meg.nodes[s]["suspend_drones"]
            for s in attrs["scopes"]
        ):
            attrs["suspendable"] = True


def _mark_catchers(meg: nx.DiGraph) -> None:
    """Give every node inside a Try's Body the Try that catches its failure (the innermost).

    ``catch`` is the Try's begin node, ``catch_loops`` how many of the node's
    loops are outside the Try (the Try's activation is that prefix of the
    node's), ``catch_drones`` the drones whose part of Body is cancelled.
    """
    tries = {n for n, a in meg.nodes(data=True) if a["kind"] in TRY_KINDS}
    if not tries:
        return
    for attrs in meg.nodes.values():
        inner = [s for s in attrs["scopes"] if s in tries]
        if not inner:
            continue
        catcher = meg.nodes[inner[-1]]
        attrs["catch"] = inner[-1]
        attrs["catch_loops"] = len(catcher["loops"])
        attrs["catch_drones"] = catcher["interrupt_drones"]
        attrs["catch_line"] = catcher["line"]


def is_fork(meg: nx.DiGraph, node: int) -> bool:
    """True for fork (parallel branching) nodes."""
    return bool(meg.nodes[node]["kind"] == "fork")
