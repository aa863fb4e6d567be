"""Ready only when heard: wait until every participant a drone sends to listens to it.

A drone reports ready to the ground station only once each participant it
will send to has subscribed to it (so no trigger is lost at the start).  While
it waits, it says every :data:`READY_NOTE_S` seconds whom it waits for, so a
node that seems to hang tells why.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence

from ..net import wire
from ..net.out_bridge import OutBridge

#: While waiting for its peers to listen, a node says whom it waits for this often.
READY_NOTE_S = 5.0

__all__ = ["READY_NOTE_S", "not_listening", "wait_listening"]


def not_listening(out: OutBridge, names: Sequence[str]) -> list[str]:
    """Those of ``names`` not subscribed to ``out`` yet."""
    subs = out.subscriptions
    return [n for n in names if not any(wire.topic_to(n).startswith(p) for p in subs)]


def wait_listening(
    out: OutBridge,
    names: Sequence[str],
    timeout_s: float,
    stop: threading.Event | None,
    note: Callable[[list[str], float], None],
) -> list[str]:
    """Wait until all of ``names`` listen: [] then, else those still missing (timeout, stop).

    ``note(missing, waited_s)`` is called every :data:`READY_NOTE_S` while it waits.
    """
    topics = [wire.topic_to(n) for n in names]
    start = time.monotonic()
    deadline = start + timeout_s
    told = start
    while not out.wait_subscribed(topics, min(0.5, max(0.0, deadline - time.monotonic()))):
        now = time.monotonic()
        if (stop is not None and stop.is_set()) or now >= deadline:
            return not_listening(out, names)
        if now - told >= READY_NOTE_S:
            told = now
            note(not_listening(out, names), now - start)
    return []
