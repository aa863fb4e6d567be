"""Heartbeats carry news, not the fleet: their size follows the traffic (issue 15).

A heartbeat naming every peer reached every watcher once a period: the ground
station's, read by every drone, grew with the fleet, so the fleet's liveness
cost grew with its square.  Now a link is named only while it has something to
say: its acknowledgements for a few heartbeats after they changed, its highest
seq while messages on it are unacknowledged.
"""

from __future__ import annotations

from eamos.net import wire
from eamos.net.session import HEARTBEAT_ACK_REPEATS

from .session_helpers import FAST, Fleet, trig

DRONES = [f"D{i}" for i in range(1, 21)]


def heartbeats(fleet: Fleet, who: str, after: float = 0.0) -> list[wire.Heartbeat]:
    return [m for t, m in fleet.sent_by(who, wire.Heartbeat) if t >= after]


def test_a_quiet_fleet_sends_empty_heartbeats_and_loses_nothing() -> None:
    fleet = Fleet(["GCS", *DRONES])
    gcs = fleet.sessions["GCS"]
    for n, drone in enumerate(DRONES):
        fleet.send(drone, trig(drone, "GCS", n))
        fleet.send("GCS", trig("GCS", drone, n))
    assert fleet.until(lambda: all(s.flushed() for s in fleet.sessions.values()))
    assert len(fleet.of("GCS", wire.Trigger)) == len(DRONES)
    assert all(len(fleet.of(d, wire.Trigger)) == 1 for d in DRONES)
    # Acknowledged by heartbeats alone, without a retransmission.
    assert sum(s.counters.retransmissions for s in fleet.sessions.values()) == 0
    assert gcs.counters.acks_sent == 0
    # Each drone's acknowledgement rode on exactly HEARTBEAT_ACK_REPEATS of the
    # ground station's heartbeats, then no more.
    quiet = fleet.now
    fleet.run(quiet + (HEARTBEAT_ACK_REPEATS + 2) * FAST.heartbeat_s)
    beats = heartbeats(fleet, "GCS")
    for drone in DRONES:
        assert sum(drone in hb.acks for hb in beats) == HEARTBEAT_ACK_REPEATS
    late = heartbeats(fleet, "GCS", after=quiet + HEARTBEAT_ACK_REPEATS * FAST.heartbeat_s)
    assert late and all(not (hb.acks or hb.backs or hb.known or hb.sent) for hb in late)


def test_sent_is_named_while_unacknowledged_so_a_lost_tail_is_still_asked_for() -> None:
    fleet = Fleet(["A", "B"])
    a = fleet.sessions["A"]
    fleet.lose = lambda sender, to, msg: isinstance(msg, wire.Trigger) and msg.seq == 2
    for n in range(2):
        fleet.send("A", trig("A", "B", n))
    fleet.advance(FAST.heartbeat_s / 2)
    fleet.lose = lambda sender, to, msg: False
    # The next heartbeat names seq 2 (unacknowledged); B nacks it before any timeout.
    assert fleet.until(a.flushed, FAST.rto_min_s)
    assert [m.iteration for m in fleet.of("B", wire.Trigger)] == [(0,), (1,)]
    fleet.run(fleet.now + (HEARTBEAT_ACK_REPEATS + 2) * FAST.heartbeat_s)
    assert all(not hb.sent for hb in heartbeats(fleet, "A", after=fleet.now - FAST.heartbeat_s))
