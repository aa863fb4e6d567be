"""Progress batches: every state change a drone reports, in order, in few messages.

A drone tells the ground station what each node does (running, ok, waiting,
decided, ...) for people to watch.  Bursts of instant actions would flood the
link if each change were a message, and dropping all but the latest would
hide what happened (an ``Arm`` seen "running" but never "ok").  So the
executive batches: one :class:`~eamos.net.wire.Progress` carries the newest
event in its fields and the ones before it, oldest first, in
``detail["earlier"]`` (each ``[state, node, action, detail]``).  Nothing is
dropped; :func:`progress_events` unpacks a batch back into one message per
event, in order.  Each event's ``detail["at"]`` is the drone's wall-clock
time of the change, so displays can order events of several drones.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from .wire import Progress

#: One event: state, node key, action label, detail (iteration, reason, at, ...).
ProgressEvent = tuple[str, str, str, Mapping[str, Any]]

__all__ = ["ProgressEvent", "progress_batch", "progress_events"]


def progress_batch(mission: str, sender: str, events: Sequence[ProgressEvent]) -> Progress:
    """One message carrying ``events`` (at least one), oldest first."""
    if not events:
        raise ValueError("a progress batch needs at least one event")
    *earlier, (state, node, action, detail) = events
    full = dict(detail)
    if earlier:
        full["earlier"] = [[s, n, a, dict(d)] for s, n, a, d in earlier]
    return Progress(
        mission=mission, sender=sender, state=state, node=node, action=action, detail=full
    )


def progress_events(msg: Progress) -> list[Progress]:
    """The events ``msg`` carries, oldest first, each as its own message (``msg`` last).

    A malformed ``earlier`` entry (not ``[str, str, str, map]``) is left out:
    what a peer sends is checked here, at the edge.
    """
    detail = dict(msg.detail)
    earlier = detail.pop("earlier", [])
    out: list[Progress] = []
    if isinstance(earlier, list | tuple):
        for entry in earlier:
            if (
                isinstance(entry, list | tuple)
                and len(entry) == 4
                and all(isinstance(x, str) for x in entry[:3])
                and isinstance(entry[3], dict)
            ):
                state, node, action, extra = entry
                out.append(
                    Progress(
                        mission=msg.mission,
                        sender=msg.sender,
                        state=state,
                        node=node,
                        action=action,
                        detail=dict(extra),
                        incarnation=msg.incarnation,
                    )
                )
    out.append(
        Progress(
            mission=msg.mission,
            sender=msg.sender,
            state=msg.state,
            node=msg.node,
            action=msg.action,
            detail=detail,
            incarnation=msg.incarnation,
        )
    )
    return out
