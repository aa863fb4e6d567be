"""Incarnations: a participant killed and started again is resynchronised, in virtual time.

The restarted session has the same name and a new, larger incarnation and
remembers nothing.  Its peers must not take its new sequence numbers for
duplicates, must resend it everything (the link's triggers, the ground
station's broadcasts), and it must ignore acknowledgements meant for its
predecessor.  Pure: sessions joined by the in-memory network of ``session_helpers``.
"""

from __future__ import annotations

import random

import msgspec

from eamos.net import wire
from eamos.net.effects import PeerStatus
from eamos.net.incarnation import new_incarnation
from eamos.net.session import ReliableSession

from .session_helpers import FAST, MISSION, Fleet, trig


def iterations(items: list[object], sender: str) -> list[int]:
    return [m.iteration[0] for m in items if isinstance(m, wire.Trigger) and m.sender == sender]


def test_incarnations_grow_and_differ() -> None:
    first = new_incarnation()
    second = new_incarnation()
    assert 0 < first < (1 << 63) and second != first
    assert second >> 8 >= first >> 8  # the clock part never goes back within a process


def test_every_message_carries_the_senders_incarnation() -> None:
    fleet = Fleet(["A", "B"])
    fleet.send("A", trig("A", "B", 0))
    fleet.send("A", wire.TelemetrySample(MISSION, "A", 0.0, 0, 0, 0, 0, 0, 0, 100, False, True))
    fleet.advance(1.0)
    a = fleet.sessions["A"].incarnation
    assert {m.incarnation for _, who, m in fleet.sent if who == "A"} == {a}
    assert fleet.sessions["B"].peer_stats()["A"]["state"] == "up"


def test_a_restarted_receiver_gets_every_trigger_again_in_order() -> None:
    fleet = Fleet(["A", "B"])
    for n in range(3):
        fleet.send("A", trig("A", "B", n))
    fleet.advance(1.0)
    assert iterations(fleet.got["B"], "A") == [0, 1, 2]
    assert fleet.sessions["A"].unacked() == 0  # all acknowledged by B's first process
    fleet.restart("B")
    # Nothing new from A: B's heartbeats alone tell A of the new process.
    assert fleet.until(lambda: iterations(fleet.got["B"], "A") == [0, 1, 2], limit_s=5.0)
    fleet.send("A", trig("A", "B", 3))
    assert fleet.until(lambda: iterations(fleet.got["B"], "A") == [0, 1, 2, 3], limit_s=5.0)
    a = fleet.sessions["A"]
    assert a.counters.restarts == 1
    assert [s.state for s in fleet.statuses("A")] == ["restarted"]
    assert fleet.until(lambda: a.unacked() == 0, limit_s=5.0)


def test_a_restarted_sender_is_not_taken_for_duplicates() -> None:
    fleet = Fleet(["A", "B"])
    for n in range(5):
        fleet.send("B", trig("B", "A", n))
    fleet.advance(1.0)
    fleet.restart("B")
    for n in range(10, 13):  # seq 1, 2, 3 again, from the new process
        fleet.send("B", trig("B", "A", n))
    assert fleet.until(
        lambda: iterations(fleet.got["A"], "B") == [0, 1, 2, 3, 4, 10, 11, 12], limit_s=5.0
    )
    assert fleet.sessions["A"].counters.duplicates_dropped == 0


def test_a_restarted_drone_hears_the_start_and_then_the_abort() -> None:
    """The ground station's broadcasts are replayed to the new process, in order."""
    fleet = Fleet(["GCS", "D1", "D2"])
    fleet.send("GCS", wire.Start(MISSION, "GCS"))
    fleet.advance(1.0)
    fleet.restart("D1")
    fleet.advance(0.5)
    fleet.send("GCS", wire.Abort(MISSION, "GCS", "operator"))
    kinds = (wire.Start, wire.Abort)
    assert fleet.until(
        lambda: [type(m) for m in fleet.got["D1"] if isinstance(m, kinds)] == list(kinds),
        limit_s=5.0,
    )
    # D2, which never restarted, gets each broadcast once (replays are duplicates to it).
    assert [type(m) for m in fleet.got["D2"] if isinstance(m, kinds)] == list(kinds)
    assert fleet.until(lambda: fleet.sessions["GCS"].unacked() == 0, limit_s=5.0)


def test_a_silent_peer_that_restarted_is_back_and_restarted() -> None:
    fleet = Fleet(["A", "B"])
    fleet.send("A", trig("A", "B", 0))
    fleet.advance(0.5)
    fleet.down.add("B")  # killed: silent
    fleet.advance(2.0)
    assert [s.state for s in fleet.statuses("A")] == ["lost"]
    fleet.restart("B")
    assert fleet.until(lambda: iterations(fleet.got["B"], "A") == [0], limit_s=5.0)
    states = [s.state for s in fleet.statuses("A")]
    assert states == ["lost", "restarted", "back"]
    assert all(isinstance(s, PeerStatus) for s in fleet.statuses("A"))


def b_session(incarnation: int) -> ReliableSession:
    b = ReliableSession("B", MISSION, FAST, rng=random.Random(1), incarnation=incarnation)
    b.add_peers(["A"])
    return b


def test_acknowledgements_for_the_predecessor_are_ignored() -> None:
    b = b_session(200)
    for n in range(3):
        b.on_send(trig("B", "A", n), 0.0)
    old = wire.Heartbeat(MISSION, "A", acks={"B": 5}, known={"B": 100}, incarnation=50)
    b.on_receive(old, 0.1)
    b.on_receive(wire.Ack(MISSION, "A", "B", 5, 0, False, 100, incarnation=50), 0.1)
    assert b.unacked() == 3  # those acks were for B's previous process
    mine = wire.Heartbeat(MISSION, "A", acks={"B": 3}, known={"B": 200}, incarnation=50)
    b.on_receive(mine, 0.2)
    assert b.unacked() == 0


def test_messages_of_the_predecessor_are_dropped() -> None:
    b = b_session(7)
    new = msgspec.structs.replace(trig("A", "B", 1), seq=1, incarnation=300)
    old = msgspec.structs.replace(trig("A", "B", 9), seq=2, incarnation=299)
    assert b.on_receive(new, 0.0)
    assert b.on_receive(old, 0.1) == []
    assert b.counters.old_incarnation == 1 and b.counters.restarts == 0
