"""What an amendment needs of one node actor: has it begun, and what has it taken so far.

An amendment applied to a flying drone (:mod:`.reprogram`) replaces the node actors it
changes and gives new successors to the nodes it redirects, in two phases.  Between
them each such node is held (:class:`Amendable`, pure bookkeeping, one per
:class:`~.node.MissionNode`):

* a node to be *replaced* (removed, or its action, condition or incoming arcs changed)
  must not have begun: nothing it was given made it do anything but wait.  Held, it
  keeps what it is given (triggers, interrupts, a lost peer) instead of acting on it;
  its replacement is handed every trigger of an arc it keeps, in order, so a
  precondition counted before the switch counts after it too;
* a node *redirected* (what follows it changes) may be running, not ended.  Held, the
  triggers it would send are kept; with its new successors they go to those, and if
  the amendment is cancelled, to the old ones.

Cancelled, a held node acts on what it kept, in order, as if it had never been held.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from .logic import Effect, Emit, Note, Route
from .messages import Interrupt, PeerLost, Trigger

__all__ = ["AmendNode", "Amendable", "Kept", "reroute_emits"]

#: What a node not yet begun keeps for its replacement.
Kept = Trigger | Interrupt | PeerLost


@dataclass(frozen=True)
class AmendNode:
    """The reprogramming's question or order to one node actor (asked, not told).

    ``op``: ``"hold"`` (to be replaced: the answer is False if it has begun),
    ``"hold-out"`` (redirected: False if it has ended), ``"release"`` (the amendment
    is cancelled), ``"retire"`` (replaced: the answer is what it kept; it then acts
    on nothing), ``"reroute"`` (its new ``routes``: what it held goes to them).
    """

    op: str
    routes: tuple[Route, ...] = ()


class Amendable:
    """One node's part in an amendment (module docstring); pure, no threads."""

    def __init__(self) -> None:
        self.begun = False  # it did something besides waiting
        self.emitted = False  # it sent a trigger on (it ended an activation)
        self.kept: list[Kept] = []  # taken while it had not begun (emptied once it does)
        self.held_in = False  # held for replacement: it keeps what it is given
        self.held_from = 0  # kept[held_from:] arrived while held
        self.held_out = False  # redirected: it keeps the triggers it would send
        self.held_emits: list[Emit] = []
        self.retired = False

    def keeps(self, message: object) -> bool:
        """Whether ``message`` is kept instead of acted on (the node is held)."""
        if self.held_in and isinstance(message, (Trigger, Interrupt, PeerLost)):
            self.kept.append(message)
            return True
        return False

    def seen(self, message: object, effects: Sequence[Effect]) -> None:
        """The node acted on ``message`` with ``effects``."""
        if self.begun and self.emitted:
            return  # nothing more to learn (the common case: no cost on the trigger's path)
        if any(type(e) is Emit for e in effects):
            self.emitted = True
        if self.begun:
            return
        if any(type(e) is not Note for e in effects):
            self.begun = True
            self.kept = []  # no replacement will need them
        elif isinstance(message, (Trigger, Interrupt, PeerLost)):
            self.kept.append(message)

    def hold_in(self) -> bool:
        """Hold the node for its replacement; False (not held) if it has begun."""
        if self.begun:
            return False
        self.held_in, self.held_from = True, len(self.kept)
        return True

    def hold_out(self) -> bool:
        """Keep the triggers it would send; False (not held) if it has ended."""
        if self.emitted:
            return False
        self.held_out = True
        return True

    def outgoing(self, effects: Sequence[Effect]) -> list[Effect]:
        """``effects`` without the triggers a redirected node holds (kept for later)."""
        if not self.held_out:
            return list(effects)
        self.held_emits += [e for e in effects if type(e) is Emit]
        return [e for e in effects if type(e) is not Emit]

    def release(self) -> tuple[list[Kept], list[Emit]]:
        """The amendment is cancelled: what arrived while held, and the triggers held."""
        arrived = self.kept[self.held_from :] if self.held_in else []
        del self.kept[self.held_from :]
        emits, self.held_emits = self.held_emits, []
        self.held_in = self.held_out = False
        return arrived, emits

    def retire(self) -> tuple[Kept, ...]:
        """Replaced: everything it kept, in order; from now on it acts on nothing."""
        self.retired = True
        kept, self.kept = tuple(self.kept), []
        return kept

    def reroute(self, routes: tuple[Route, ...]) -> list[Emit]:
        """Its new successors: the triggers it held, sent to them instead."""
        emits, self.held_emits = self.held_emits, []
        self.held_out = False
        return reroute_emits(emits, routes)


def reroute_emits(emits: Sequence[Emit], routes: tuple[Route, ...]) -> list[Emit]:
    """Triggers sent on old routes, as the same node sends them on ``routes``.

    Per activation, each new route gets the status the old routes of its kind got (an
    If's branch ``then`` ran, ``else`` was skipped), or else the status of the
    activation's first trigger (a node sends one status on every route).
    """
    out: list[Emit] = []
    by_act: dict[tuple[int, ...], dict[str, str]] = {}
    for e in emits:
        kinds = by_act.setdefault(e.iteration, {})
        kinds.setdefault(e.route.kind, e.status)
        kinds.setdefault("", e.status)
    for act, kinds in by_act.items():
        for route in routes:
            status = kinds.get(route.kind, kinds[""])
            out.append(Emit(route, act, status))  # type: ignore[arg-type]
    return out
