"""Who a drone talks to, read from its program alone (pure functions, no actors).

The runtime uses these to subscribe the in-bridge, to wait until the drones it
sends to listen (no trigger lost at start), to choose whose heartbeats to
follow, and, when it aborts on an internal failure, to release the drones that
wait for it.
"""

from __future__ import annotations

from ..net import wire
from ..net.settings import LinkSettings
from ..program.conditions import properties
from ..program.format import DroneProgram
from ..program.uniform import GROUND_STATION

__all__ = [
    "connected_peers",
    "destinations",
    "released_arcs",
    "subscriptions",
    "telemetry_read_hz",
    "watched_peers",
]


def telemetry_read_hz(
    program: DroneProgram, link: LinkSettings, battery_floor_pct: float | None
) -> float | None:
    """How often this drone's own telemetry samples are read at most (None: as they come).

    Its samples leave for others at most ``link.telemetry_max_hz`` (the ground
    station's rate, or the peers' when another drone's conditions read it).  Read
    on board as they come: when a condition of its own reads its own properties,
    or a battery floor (``battery_floor_pct``) fails a Try's Body below it.
    """
    if battery_floor_pct is not None:
        return None
    for node in program.native_nodes():
        if any(drone == program.drone for drone, _ in properties(node.cond)):
            return None
    return link.telemetry_max_hz


def destinations(program: DroneProgram) -> list[str]:
    """Every participant this drone sends to (the ground station always)."""
    native = {n.key for n in program.native_nodes()}
    drone_of = {n.key: n.drone for n in program.nodes}
    dests = {drone_of[a.dst] for a in program.arcs if a.external and a.src in native}
    for node in program.native_nodes():
        dests.update(node.interrupt_drones)
    dests.add(GROUND_STATION)
    dests.discard(program.drone)
    return sorted(dests)


def watched_peers(program: DroneProgram, whole_fleet: bool) -> list[str] | None:
    """Peers whose heartbeats this participant follows (None: every peer).

    The ground station watches the whole fleet (``whole_fleet``); a drone, the
    participants it exchanges triggers, interrupts or telemetry with, and the
    ground station.  (Each heartbeat wakes its receiver: all-to-all would grow
    with the square of the fleet.)
    """
    if whole_fleet or program.drone == GROUND_STATION:
        return None
    native = {n.key for n in program.native_nodes()}
    drone_of = {n.key: n.drone for n in program.nodes}
    sources = {drone_of[a.src] for a in program.arcs if a.external and a.dst in native}
    watch = {*destinations(program), *sources, *program.telemetry_from, GROUND_STATION}
    watch.discard(program.drone)
    return sorted(watch)


def connected_peers(programs: dict[str, DroneProgram]) -> dict[str, list[str]]:
    """Per participant, the peers its In-Bridge connects to, from every program of a mission.

    A drone connects to the peers it watches (:func:`watched_peers`: those it
    sends to, those that trigger it, those whose telemetry it reads, the ground
    station) and to every drone that sends to it (an interrupt needs no arc);
    the ground station to the whole fleet.  So a relay of N drones makes about
    3N connections instead of N², each one a CURVE handshake and a heartbeat
    stream.  Its own program alone cannot tell a drone who interrupts it:
    the ground, holding every program, writes these into the node configs.
    """
    names = sorted(programs)
    peers: dict[str, set[str]] = {}
    for name, program in programs.items():
        watched = watched_peers(program, whole_fleet=False)
        peers[name] = set(names if watched is None else watched)
    for name, program in programs.items():
        for dest in destinations(program):
            if dest in peers:
                peers[dest].add(name)
    return {name: sorted(p - {name}) for name, p in peers.items()}


def subscriptions(program: DroneProgram, extra: tuple[bytes, ...] = ()) -> list[bytes]:
    """The in-bridge's topics: broadcasts, this drone's own, the telemetry it reads."""
    topics = [wire.TOPIC_ALL, wire.topic_to(program.drone)]
    topics += [wire.topic_telemetry(d) for d in program.telemetry_from]
    topics += [t for t in extra if t not in topics]
    return topics


def released_arcs(program: DroneProgram) -> list[tuple[str, str, str]]:
    """``(dest drone, src node, dst node)`` of the outgoing external arcs outside loops.

    Their one activation is ``()``: when this drone aborts on an internal
    failure it sends ``failed`` on each one not sent yet, so the nodes waiting
    for it are blocked and finish (dead-path elimination).  Arcs inside loops
    carry iteration counters only the nodes know, so they are not released.
    """
    native = {n.key for n in program.native_nodes()}
    node_of = {n.key: n for n in program.nodes}
    return [
        (node_of[a.dst].drone, a.src, a.dst)
        for a in program.arcs
        if a.external
        and a.src in native
        and a.kind != "loop"
        and not node_of[a.src].loops
        and not node_of[a.dst].loops
    ]
