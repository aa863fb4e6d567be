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
from typing import TYPE_CHECKING

from ..net import wire
from ..net.out_bridge import OutBridge
from ..program.format import DroneProgram
from .failure import tell_operator
from .wiring import destinations

if TYPE_CHECKING:
    from ..logs import EventLog

#: While waiting for its peers to listen, a node says whom it waits for this often.
READY_NOTE_S = 5.0

__all__ = ["READY_NOTE_S", "announce_ready", "not_listening", "wait_listening"]


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


def announce_ready(
    out: OutBridge,
    program: DroneProgram,
    to_ground: Callable[[wire.Message], None],
    log: EventLog,
    timeout_s: float,
    stop: threading.Event | None = None,
) -> bool:
    """Wait until every participant ``program``'s drone sends to listens, then tell the
    ground station it is ready (``to_ground``); False if they never all did.

    ``stop`` (set by a signal handler) ends the wait early: a node asked to stop
    while its peers are missing must not linger for the whole timeout.
    """
    drone = program.drone

    def waiting(missing: list[str], waited_s: float) -> None:
        log.info("mission.waiting_for_peers", peers=missing, waited_s=round(waited_s, 1))
        tell_operator(drone, f"waiting for {', '.join(missing)} to listen ({waited_s:.0f} s)")

    missing = wait_listening(out, destinations(program), timeout_s, stop, waiting)
    if missing:
        log.error("mission.not_ready", waiting_for=missing)
        return False
    to_ground(
        wire.Ready(mission=program.mission_id, sender=drone, program_checksum=program.checksum)
    )
    log.info("mission.ready")
    return True
