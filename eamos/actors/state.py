"""Pure bookkeeping of one mission node: counting preconditions (paper VI-B).

A node fires when every precondition arc has delivered a trigger for the same
*activation*.  An activation is identified by the iteration counters of the
loops enclosing the node (a tuple, one counter per loop, outermost first), so
loops re-arm nodes without ever mixing iterations, and a duplicated trigger
(same source, same activation) is ignored.

Loop begin nodes have two precondition groups: ``entry`` (the arcs from
before the loop, activation = the loop's own iteration) and ``loop`` (the
back arcs from the end of Body, one group per loop iteration: activation =
the loop's iteration plus the body counter).

Statuses carried by triggers: ``done`` (the predecessor ran), ``skipped``
(it was on a branch not taken, or was interrupted), ``failed`` (it, or
something it depended on, failed).  :func:`combine` decides what a node does
with what it received.  No threads here: the actor in :mod:`.node` wraps it,
and tests drive it directly.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Literal

Status = Literal["done", "skipped", "failed"]
Group = Literal["entry", "loop"]
Iteration = tuple[int, ...]


def combine(statuses: Iterable[Status]) -> Status:
    """What a node does after all its preconditions arrived.

    Any failure blocks it (``failed``); otherwise it runs if any predecessor
    ran (``done``), which is how the end of an If joins the taken branch with
    the skipped one; if all were skipped, it is skipped too (dead-path
    elimination keeps every join counting all of its arcs).
    """
    seen = set(statuses)
    if "failed" in seen:
        return "failed"
    if "done" in seen or not seen:
        return "done"
    return "skipped"


@dataclass(frozen=True)
class Fired:
    """A precondition group completed for one activation."""

    group: Group
    activation: Iteration
    statuses: dict[str, Status]

    @property
    def status(self) -> Status:
        return combine(self.statuses.values())


@dataclass
class Preconditions:
    """Counts the triggers one node received, per group and activation."""

    entry: frozenset[str]
    loop: frozenset[str] = frozenset()
    depth: int = 0  # number of loops around the node
    _pending: dict[tuple[Group, Iteration], dict[str, Status]] = field(default_factory=dict)
    _fired: set[tuple[Group, Iteration]] = field(default_factory=set)
    duplicates: int = 0

    def group_of(self, src: str, iteration: Iteration) -> tuple[Group, Iteration] | None:
        """Which group and activation a trigger from ``src`` belongs to (None: not ours)."""
        if src in self.loop and len(iteration) == self.depth + 1:
            return "loop", iteration
        if src in self.entry and len(iteration) >= self.depth:
            # A trigger from inside a deeper loop cannot reach an entry arc, but a
            # trigger from the same depth carries exactly our activation.
            return "entry", iteration[: self.depth]
        return None

    def receive(self, src: str, iteration: Iteration, status: Status) -> Fired | None:
        """Record one trigger; return the completed group if this was its last arc."""
        found = self.group_of(src, iteration)
        if found is None:
            return None
        group, activation = found
        key = (group, activation)
        if key in self._fired:
            self.duplicates += 1
            return None
        pending = self._pending.setdefault(key, {})
        if src in pending:
            self.duplicates += 1
            return None
        pending[src] = status
        expected = self.entry if group == "entry" else self.loop
        if len(pending) < len(expected):
            return None
        del self._pending[key]
        self._fired.add(key)
        return Fired(group, activation, pending)

    def fire_without_arcs(self) -> Fired | None:
        """For a node with no entry arcs (the initial node): its one activation."""
        key: tuple[Group, Iteration] = ("entry", ())
        if self.entry or key in self._fired:
            return None
        self._fired.add(key)
        return Fired("entry", (), {})

    def has_fired(self, group: Group, activation: Iteration) -> bool:
        """Whether this group already fired for ``activation``."""
        return (group, activation) in self._fired

    def waiting(self) -> dict[tuple[Group, Iteration], frozenset[str]]:
        """Per partially triggered activation, the arcs still missing (for status views)."""
        out = {}
        for (group, act), got in self._pending.items():
            expected = self.entry if group == "entry" else self.loop
            out[(group, act)] = frozenset(expected - got.keys())
        return out


def within(iteration: Iteration, scope_iteration: Iteration) -> bool:
    """True if an activation lies inside the scope activation (prefix match)."""
    return iteration[: len(scope_iteration)] == scope_iteration


def holds(kind: str, value: bool) -> bool:
    """Whether a While/Until structure should go on, given its condition's value."""
    return value if kind.endswith("_while") else not value
