"""The start gate of a drone's node (issue 28, item 13), pure: no threads, no sockets.

A node takes only the Start of its own deployment, and acts on nothing
before it; from the ground station, only what a session whose Start it took
sends counts.
"""

from __future__ import annotations

from eamos.actors.inbound import MAX_HELD, StartGate
from eamos.logs import make_logger
from eamos.net import wire

M = "mission-1"


def trigger(sender: str, incarnation: int, src: str = "n1") -> wire.Trigger:
    return wire.Trigger(M, sender, "Drone1", src, "n2", (), "done", seq=1, incarnation=incarnation)


def start(deployment: str, incarnation: int) -> wire.Start:
    return wire.Start(M, "GCS", deployment, seq=1, incarnation=incarnation)


def gate(deployment: str = "B", told: list[str] | None = None) -> StartGate:
    said = told if told is not None else []
    return StartGate("Drone1", deployment, make_logger(None), tell=lambda d, t: said.append(t))


def test_nothing_acts_before_the_start_of_its_own_deployment() -> None:
    g = gate()
    peer = trigger("Drone2", 7)
    assert g.hold(peer) and not g.started
    assert g.start(start("B", 5)) == [peer] and g.started
    assert not g.hold(trigger("Drone2", 7, "n3"))  # started: at once
    assert not g.hold(trigger("GCS", 5))
    assert g.start(start("B", 5)) == []  # the same Start again (resent): nothing new


def test_another_deployments_ground_station_is_refused_and_said_once() -> None:
    told: list[str] = []
    g = gate(told=told)
    old = trigger("GCS", 3)
    assert g.start(start("A", 3)) is None
    assert g.start(start("A", 3)) is None  # retransmitted: refused again, said once
    assert len(told) == 1 and "refused a Start of deployment A" in told[0]
    assert g.hold(old) and not g.takes_complete(wire.Complete(M, "GCS", incarnation=3))
    # This deployment's ground station (a new session) starts it; the old one's trigger
    # stays held, its Complete refused; the new one's count.
    assert g.start(start("B", 9)) == []
    assert g.hold(trigger("GCS", 3, "n4"))
    assert not g.hold(trigger("GCS", 9))
    assert not g.takes_complete(wire.Complete(M, "GCS", incarnation=3))
    assert g.takes_complete(wire.Complete(M, "GCS", incarnation=9))


def test_a_restarted_ground_station_of_the_deployment_is_taken_with_its_start() -> None:
    g = gate()
    assert g.start(start("B", 5)) == []
    early = trigger("GCS", 8)  # the restarted one's trigger overtook its Start
    assert g.hold(early)
    assert g.start(start("B", 8)) == [early]


def test_without_a_deployment_any_start_is_taken() -> None:
    g = gate(deployment="")
    assert g.hold(trigger("Drone2", 1))
    assert len(g.start(start("anything", 4)) or []) == 1


def test_a_flood_before_the_start_is_bounded() -> None:
    g = gate()
    for i in range(MAX_HELD + 10):
        assert g.hold(trigger("Drone2", 1, f"n{i}"))
    assert g.dropped == 10
    assert len(g.start(start("B", 2)) or []) == MAX_HELD


def test_running_is_said_once() -> None:
    calls: list[int] = []
    g = StartGate("Drone1", "B", make_logger(None), on_running=lambda: calls.append(1))
    g.running()
    g.running()
    assert calls == [1]
