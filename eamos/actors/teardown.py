"""Stopping a drone runtime: its actors, then its bridges, in the order that loses nothing.

The goodbye heartbeat and the receive side go first (no callback into actors
being stopped), then the actors (nodes, executive, board, uniform API), the
adapter a dead uniform-API actor left open (so its landing could finish), the
dispatchers, and the send side last: what the actors sent while stopping still
goes out.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import pykka

from ..hal.api import Adapter
from ..net.link import Link
from .dispatch import Dispatcher
from .uniform_api import UniformAPI

if TYPE_CHECKING:
    from ..logs import EventLog

__all__ = ["close_orphan", "tear_down"]

#: How long one actor may take to stop.
STOP_TIMEOUT_S = 30


def tear_down(
    link: Link | None,
    actors: Iterable[pykka.ActorRef[Any] | None],
    hal: pykka.ActorRef[UniformAPI] | None,
    adapter: Adapter,
    dispatchers: Iterable[Dispatcher | None],
    log: EventLog,
) -> None:
    """Stop ``actors`` and then ``hal`` (those built), close the bridges of ``link``."""
    if link is not None:
        # Goodbye heartbeat, then the receive side closes (no callbacks into
        # actors being stopped); the send side closes below, after the actors.
        link.close_receiving()
    for ref in [*actors, hal]:
        if ref is not None:
            try:
                ref.stop(block=True, timeout=STOP_TIMEOUT_S)
            except (pykka.ActorDeadError, pykka.Timeout):
                pass
    if hal is not None and not hal.is_alive():
        close_orphan(adapter, log)
    for dispatcher in dispatchers:
        if dispatcher is not None:
            dispatcher.shutdown()
    if link is not None:
        link.close()


def close_orphan(adapter: Adapter, log: EventLog) -> None:
    """Close the adapter a dead uniform-API actor left open (so its landing could finish)."""
    try:
        adapter.close()
    except Exception as exc:
        log.error("mission.adapter.close_error", error=repr(exc))
