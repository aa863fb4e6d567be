"""When a drone ends its part on its own (issue 17's faults; issue 13's end policy).

Two ways a drone can be left with nobody to end its mission:

* **stranded**: it has not resolved, it is idle (no action running), and a
  participant it receives triggers from (or the ground station) has been
  silent for longer than ``peer_wait_limit_s`` while it waited.  It then applies
  its end policy (``on_stranded``: ``land`` by default, or ``hold``), tells the
  drones waiting for it that their triggers from it failed, and reports
  ``Resolved``: the run ends at once instead of at the mission timeout.
* **no Complete**: it has resolved, but the ground station has been silent for
  longer than ``peer_wait_limit_s``: the ``Complete`` will never come, so it
  ends as if it had (its report is kept in its own folder).
* **held without a ground station**: the operator paused or held it, and the
  ground station, the only one that can resume it, has been silent for longer
  than ``peer_wait_limit_s``: stranded as above (it would otherwise hover for
  good, its action suspended).

Pure: :func:`end_on_own` takes the time, what the executive says
(:class:`Activity`) and when each peer went silent (:func:`silent_since`, from
the link's peer events); the drone's loop (:mod:`.drone`) applies the answer.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from ..config import END_POLICIES, NodeConfig
from ..program.format import DroneProgram
from ..program.uniform import GROUND_STATION

__all__ = [
    "DEFAULT_PEER_WAIT_LIMIT_S",
    "END_POLICIES",
    "Activity",
    "EndOnOwn",
    "activity_matters",
    "end_on_own",
    "silent_since",
    "trigger_sources",
]

#: How long a drone waits, idle, for a silent peer before it applies its end policy
#: (and, once resolved, for a silent ground station's Complete): the node config's
#: ``peer_wait_limit_s`` default.  What it does then is ``on_stranded``, one of
#: :data:`END_POLICIES` (``return`` is not implemented yet: it lands).
DEFAULT_PEER_WAIT_LIMIT_S: float = NodeConfig.peer_wait_limit_s

#: Link states that mean "not heard from any more" (``left``: it said goodbye).
_SILENT_STATES = ("lost", "left")


@dataclass(frozen=True)
class Activity:
    """What the executive says about the drone's progress, at one moment."""

    resolved: bool  # every top-level node finished
    idle_since: float | None  # monotonic time no action has run since; None: one runs now
    held: bool = False  # paused or held by the operator (only the ground station resumes it)


@dataclass(frozen=True)
class EndOnOwn:
    """The drone ends its part on its own: ``stranded`` or ``no_complete``, and why."""

    kind: str
    reason: str
    peer: str | None = None  # stranded by this lost peer (None: another reason)


def caught_lost_peer(program: DroneProgram, peer: str) -> frozenset[str]:
    """The nodes hosted by ``peer`` that a Try's Body on this drone waits on (keys).

    When a peer whose link is lost feeds a node inside a Try's Body, the loss is
    a failure that Try catches (:meth:`~eamos.actors.logic.NodeLogic.peer_lost`)
    instead of stranding the drone; empty: no Try here waits on ``peer``.
    """
    hosted = frozenset(n.key for n in program.nodes if n.drone == peer)
    native = {n.key: n for n in program.native_nodes()}
    for arc in program.arcs:
        node = native.get(arc.dst)
        if arc.external and arc.src in hosted and node is not None and node.catch is not None:
            return hosted
    return frozenset()


def trigger_sources(program: DroneProgram) -> frozenset[str]:
    """The participants this drone may wait for: those it receives triggers from.

    The ground station is one when it hosts nodes this drone waits for (its
    initial node, a pause); its silence alone does not strand a flying drone.
    """
    native = {n.key for n in program.native_nodes()}
    drone_of = {n.key: n.drone for n in program.nodes}
    sources = {drone_of[a.src] for a in program.arcs if a.external and a.dst in native}
    sources.discard(program.drone)
    return frozenset(sources)


def silent_since(
    events: Iterable[Mapping[str, Any]], now_wall: float, now: float
) -> dict[str, float]:
    """Per peer whose latest link event says it is silent: the monotonic time it went silent.

    ``events`` are the link's ``peer_events`` (``peer``, ``state``, ``silent_s``
    and ``t``, a wall-clock stamp); ``now_wall`` and ``now`` are the same
    instant on the wall clock and the monotonic clock.
    """
    latest: dict[str, Mapping[str, Any]] = {}
    for event in events:
        latest[str(event.get("peer", ""))] = event
    out: dict[str, float] = {}
    for peer, event in latest.items():
        if event.get("state") in _SILENT_STATES:
            went_silent_wall = float(event.get("t", now_wall)) - float(event.get("silent_s", 0.0))
            out[peer] = now - max(0.0, now_wall - went_silent_wall)
    return out


def activity_matters(silent: Mapping[str, float], resolved: bool, checked: bool) -> bool:
    """Whether the executive's :class:`Activity` can change what the drone does now.

    With no peer silent, :func:`end_on_own` ends nothing, whatever the activity; what
    is left is the one check of a part that resolved (``resolved``, not yet
    ``checked``).  Otherwise the drone's thread need not ask the executive: twice a
    second per drone, each a round trip through a worker thread.
    """
    return bool(silent) or (resolved and not checked)


def end_on_own(
    now: float,
    activity: Activity,
    silent: Mapping[str, float],
    sources: Collection[str],
    limit_s: float,
) -> EndOnOwn | None:
    """Whether the drone must end its part now (None: keep going).

    ``silent`` maps a silent peer to the monotonic time it went silent;
    ``sources`` are the peers the drone may be waiting for.
    """
    since = silent.get(GROUND_STATION)
    if activity.held and since is not None and now - since > limit_s:
        # First, resolved or not: a peer that ended the same way a moment earlier
        # may have failed this part's last nodes, but what strands it is the hold.
        return EndOnOwn(
            "stranded",
            f"stranded: held by the operator, and the ground station, which alone can resume "
            f"it, has been silent for {now - since:.0f} s (peer_wait_limit_s = {limit_s:g})",
        )
    if activity.resolved:
        if since is not None and now - since > limit_s:
            return EndOnOwn(
                "no_complete",
                f"no Complete: the ground station has been silent for {now - since:.0f} s "
                f"(peer_wait_limit_s = {limit_s:g}); ending on its own",
            )
        return None
    if activity.idle_since is None:
        return None
    for peer in sorted(sources):
        since = silent.get(peer)
        if since is None:
            continue
        waited = now - max(since, activity.idle_since)
        if waited > limit_s:
            return EndOnOwn(
                "stranded",
                f"stranded: waited {waited:.0f} s for {peer}, whose link is lost "
                f"(peer_wait_limit_s = {limit_s:g})",
                peer,
            )
    return None
