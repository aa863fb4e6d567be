"""A participant connects to an *announced* peer when the peer subscribes to it.

The ground station, up first, waits for every drone: a connection to a drone
that is not up yet is refused and libzmq retries it only every 100 ms.  So the
ground station connects to a drone when the drone's own connection subscribes to
the ground station's Out-Bridge (the drone then listens): real sockets, CURVE.
"""

from __future__ import annotations

from pathlib import Path

from eamos.net import wire

from .link_helpers import WAIT_S, Inbox, network, trig


def test_the_waiting_side_connects_when_the_peer_subscribes(tmp_path: Path) -> None:
    with network(tmp_path) as net:
        net.keys(["G", "D"])
        inbox = Inbox()
        g = net.link("G", ["D"], secure=True, connect=False)
        g.connect({"D": net.endpoints["D"]}, (), inbox, announced=["D"])
        assert g.inb is not None
        assert g.inb.unannounced == frozenset({"D"})  # nothing tried while D is not up
        d = net.link("D", ["G"], secure=True)
        # D subscribed to G, so G connected to D and subscribed to D's messages for it.
        assert d.wait_subscribed([wire.topic_to("G")], WAIT_S)
        assert g.inb.unannounced == frozenset()
        d.send(trig("D", "G", 7))
        assert inbox.wait_type(wire.Trigger)
        assert [m.iteration for m in inbox.of(wire.Trigger)] == [(7,)]


def test_a_peer_that_subscribed_before_the_in_bridge_existed_is_connected_at_once(
    tmp_path: Path,
) -> None:
    with network(tmp_path) as net:
        inbox = Inbox()
        g = net.link("G", ["D"], connect=False)  # bound, not connected to anyone
        d = net.link("D", ["G"])
        assert g.wait_subscribed([wire.topic_to("D")], WAIT_S)  # D listens already
        g.connect({"D": net.endpoints["D"]}, (), inbox, announced=["D"])
        assert d.wait_subscribed([wire.topic_to("G")], WAIT_S)
        d.send(trig("D", "G", 3))
        assert inbox.wait_type(wire.Trigger)


def test_a_peer_not_announced_is_connected_at_once(tmp_path: Path) -> None:
    with network(tmp_path) as net:
        g = net.link("G", ["D"], connect=False)
        g.connect({"D": net.endpoints["D"]}, (), lambda m: None)
        assert g.inb is not None and g.inb.unannounced == frozenset()
