"""File descriptors: a node raises its own limit so idle connections cannot exhaust it.

Every TCP connection to a participant's Out-Bridge costs a descriptor from the
moment it is accepted, before any handshake: an unauthenticated client can hold
thousands of them.  The defence is in three parts:

* the soft ``RLIMIT_NOFILE`` is raised to the hard limit when a node opens its
  network (:func:`raise_descriptor_limit`; usually 1024 -> 524288 or more);
* a connection that has not completed its CURVE handshake within
  :data:`~eamos.net.sockets.HANDSHAKE_IVL_MS` is closed by ZeroMQ, so idle
  connections are bounded by (connection rate x handshake interval);
* the Out-Bridge counts its accepted connections and, should they approach
  the limit anyway, stops listening for a while (see
  :class:`~eamos.net.out_bridge.OutBridge`), keeping :data:`RESERVE`
  descriptors for the node's own files (logs, report, summary).
"""

from __future__ import annotations

import resource
from typing import TYPE_CHECKING, Final

if TYPE_CHECKING:
    from eamos.logs import EventLog

__all__ = ["MAX_SOFT_LIMIT", "RESERVE", "connection_budget", "raise_descriptor_limit"]

MAX_SOFT_LIMIT: Final = 1 << 20
"""The soft limit is raised at most this far (an unlimited hard limit is not a target)."""

RESERVE: Final = 128
"""Descriptors kept for the node itself: sockets to its peers, log files, the
report and summary, ZeroMQ's internal pipes."""


def raise_descriptor_limit(log: EventLog | None = None) -> int:
    """Raise the soft ``RLIMIT_NOFILE`` to the hard limit (at most :data:`MAX_SOFT_LIMIT`).

    Returns the soft limit now in force.  Idempotent; never lowers it; a
    platform that refuses leaves it as it was (logged).
    """
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    target = MAX_SOFT_LIMIT if hard == resource.RLIM_INFINITY else min(hard, MAX_SOFT_LIMIT)
    if soft != resource.RLIM_INFINITY and soft < target:
        try:
            resource.setrlimit(resource.RLIMIT_NOFILE, (target, hard))
        except (ValueError, OSError) as exc:
            if log is not None:
                log.warning("net.descriptors.limit", soft=soft, hard=hard, error=str(exc))
            return soft
        if log is not None:
            log.info("net.descriptors.raised", soft=soft, to=target, hard=hard)
        return target
    return soft if soft != resource.RLIM_INFINITY else MAX_SOFT_LIMIT


def connection_budget() -> int:
    """How many accepted connections an Out-Bridge may hold: the soft limit minus a reserve.

    At least 16, so a node under a very low limit still lets its peers in.
    """
    soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY:
        soft = MAX_SOFT_LIMIT
    return max(16, soft - RESERVE - soft // 8)
