"""The link driver over real loopback sockets, with loss injected at the sender.

The protocol itself (loss, duplicates, order, retransmission timing, peers,
telemetry) is tested on :class:`~eamos.net.session.ReliableSession` alone in
``test_net_session.py``.  Here: what the driver adds -- the threads, the
Out-Bridge's subscriptions (a late joiner), the timer waking at the session's
deadlines (not polling), the injected clock, the goodbye on close -- with
real ZeroMQ sockets.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import pytest

from eamos.logs import close_logger, make_logger, read_log
from eamos.net import wire
from eamos.net.link import PeerStatus

from .link_helpers import (
    FAST,
    WAIT_S,
    Inbox,
    Lossy,
    eventually,
    network,
    trig,
)

pytestmark = pytest.mark.timeout(180)


def triggers(inbox: Inbox) -> list[int]:
    return [m.iteration[0] for m in inbox.of(wire.Trigger)]


def test_exactly_once_in_order_with_messages_and_acks_lost(tmp_path: Path) -> None:
    with network(tmp_path) as net:
        inbox = Inbox()
        b = net.link("B", ["A"], inbox)
        a = net.link("A", ["B"])
        assert a.wait_subscribed([wire.topic_to("B")], WAIT_S)
        loss_a, loss_b = Lossy(a, seed=3), Lossy(b, seed=4)
        loss_a.drop = loss_a.random(0.3, (wire.Trigger,))
        loss_a.duplicate = loss_a.random(0.1, (wire.Trigger,))
        loss_b.drop = loss_b.random(0.3, (wire.Ack, wire.Heartbeat))  # the acks ride on both
        count = 300
        for n in range(count):
            assert a.send(trig("A", "B", n))
        assert inbox.wait(lambda items: len(items) >= count), len(inbox.items)
        assert a.flush(WAIT_S)
        assert triggers(inbox) == list(range(count))  # each once, in order
        assert [m.seq for m in inbox.of(wire.Trigger)] == list(range(1, count + 1))
        assert loss_a.dropped > 0 and a.retransmissions >= loss_a.dropped
        assert b.duplicates_dropped > 0  # retransmissions of messages whose ack was lost
        stats = a.stats()
        assert stats["unacked"] == 0 and stats["retransmissions"] == a.retransmissions


def test_late_joiner_gets_everything_sent_before_it_existed(tmp_path: Path) -> None:
    with network(tmp_path) as net:
        a = net.link("A", ["B"])
        for n in range(50):
            a.send(trig("A", "B", n))  # nobody subscribed: the XPUB socket drops them
        assert not a.flush(0.3)
        inbox = Inbox()
        net.link("B", ["A"], inbox)
        assert inbox.wait(lambda items: len(items) >= 50)
        assert a.flush(WAIT_S)
        assert triggers(inbox) == list(range(50))


def test_peer_lost_back_then_left(tmp_path: Path) -> None:
    log = make_logger(tmp_path / "a.log", drone="A")
    try:
        with network(tmp_path) as net:
            inbox = Inbox()
            a = net.link("A", ["B"], inbox, log=log)
            b = net.link("B", ["A"])
            assert eventually(lambda: a.stats()["peers"]["B"]["state"] == "up")
            silent = threading.Event()
            lossy = Lossy(b)
            lossy.drop = lambda m: silent.is_set()
            silent.set()
            assert inbox.wait(lambda items: any(getattr(i, "state", "") == "lost" for i in items))
            a.send(trig("A", "B", 0))  # sent while B is unreachable... for A, B is just silent
            silent.clear()
            assert inbox.wait(lambda items: any(getattr(i, "state", "") == "back" for i in items))
            assert a.flush(WAIT_S)
            b.close()
            assert inbox.wait(lambda items: any(getattr(i, "state", "") == "left" for i in items))
            states = [i.state for i in inbox.of(PeerStatus)]
            assert states == ["lost", "back", "left"]
            serials = [i.serial for i in inbox.of(PeerStatus)]
            assert serials == sorted(serials)
            lost = inbox.of(PeerStatus)[0]
            assert lost.sender == "B" and lost.silent_s >= FAST.peer_timeout_s
            # A peer that said goodbye is never reported lost afterwards.
            assert not inbox.wait(lambda items: len(inbox.of(PeerStatus)) > 3, timeout=1.0)
            events = a.stats()["peer_events"]
            assert [(e["peer"], e["state"]) for e in events] == [
                ("B", "lost"),
                ("B", "back"),
                ("B", "left"),
            ]
    finally:
        close_logger(log)
    events = [e["event"] for e in read_log(tmp_path / "a.log")]
    assert events.count("mission.peer.lost") == 1 and events.count("mission.peer.back") == 1
    assert "mission.peer.left" in events


def test_unknown_destination_and_closed_link(tmp_path: Path) -> None:
    with network(tmp_path) as net:
        a = net.link("A", ["B"])
        assert a.send(trig("A", "Z", 0))  # not a peer: sent once, unsequenced, logged
        assert a.stats()["unacked"] == 0
        a.close()
        assert not a.send(trig("A", "B", 0))
        a.close()  # idempotent


def test_the_timer_sleeps_until_the_sessions_next_deadline(tmp_path: Path) -> None:
    """An idle link wakes for its heartbeats (10 a second here), not on a polling period."""
    with network(tmp_path) as net:
        a = net.link("A", ["B"], connect=False)
        net.link("B", ["A"])
        ticks: list[float] = []
        on_tick = a.session.on_tick

        def counting(now: float) -> Any:
            ticks.append(now)
            return on_tick(now)

        a.session.on_tick = counting  # type: ignore[method-assign]
        a.connect({"B": net.endpoints["B"]}, (), lambda m: None)
        assert eventually(lambda: a.stats()["peers"]["B"]["state"] == "up")
        start = len(ticks)
        time.sleep(1.0)  # the measurement window itself, not a synchronisation
        woke = len(ticks) - start
        assert 3 <= woke <= 2 / FAST.heartbeat_s, woke
        # A send arms an earlier deadline (the retransmission timer): still delivered.
        assert a.send(trig("A", "B", 0))
        assert a.flush(WAIT_S)


def test_an_injected_clock_drives_the_protocol(tmp_path: Path) -> None:
    """The driver reads time only from its clock.

    A jump of 10 s makes the timer 10 s late: for the protocol this
    participant's own loop stalled, which is counted and not taken for the
    peer's silence (a busy machine must not declare healthy peers lost).  A
    peer that really falls silent is still lost, after ``peer_timeout_s``.
    """
    offset = [0.0]
    with network(tmp_path) as net:
        inbox = Inbox()
        a = net.link("A", ["B"], inbox, clock=lambda: time.monotonic() + offset[0])
        b = net.link("B", ["A"])
        assert eventually(lambda: a.stats()["peers"]["B"]["state"] == "up")
        offset[0] = 10.0
        assert eventually(lambda: a.stats()["late_ticks"] >= 1)
        assert a.stats()["stalled_s"] >= 9.0
        assert not inbox.of(PeerStatus)  # B was never silent: not lost
        Lossy(b).drop = lambda m: True  # now B falls silent for real
        assert inbox.wait_type(PeerStatus)
        lost = inbox.of(PeerStatus)[0]
        assert lost.state == "lost" and FAST.peer_timeout_s <= lost.silent_s < 9.0
