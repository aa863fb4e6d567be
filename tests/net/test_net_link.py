"""The reliability layer over real loopback sockets, with loss injected at the sender.

Exactly once and in order per link under random loss of messages and acks,
duplicates, late joiners; reliable broadcasts; heartbeats, lost/back/left
peers; latest-value telemetry (rate cap, refresh, staleness, old samples).
"""

from __future__ import annotations

import dataclasses
import threading
from pathlib import Path

import pytest

from eamos.logs import close_logger, make_logger, read_log
from eamos.net import wire
from eamos.net.link import LinkSettings, PeerStatus, TelemetryStale

from .link_helpers import (
    FAST,
    MISSION,
    WAIT_S,
    Inbox,
    Lossy,
    eventually,
    first_transmission_of,
    network,
    sample,
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


def test_tail_loss_recovered_by_heartbeat_nack(tmp_path: Path) -> None:
    """The last message is lost and the sender's timer is long: the heartbeat tells."""
    slow = dataclasses.replace(FAST, rto_initial_s=20.0, rto_min_s=20.0, rto_max_s=20.0)
    with network(tmp_path) as net:
        inbox = Inbox()
        b = net.link("B", ["A"], inbox, settings=slow)
        a = net.link("A", ["B"], settings=slow)
        assert a.wait_subscribed([wire.topic_to("B")], WAIT_S)
        lossy = Lossy(a)
        lossy.drop = first_transmission_of({3})
        for n in range(3):
            a.send(trig("A", "B", n))
        # Far sooner than the 20 s retransmission timeout.
        assert inbox.wait(lambda items: len(items) >= 3, timeout=10)
        assert triggers(inbox) == [0, 1, 2]
        assert b.nacks_sent >= 1 and lossy.dropped == 1


def test_gap_is_nacked_and_filled_in_order(tmp_path: Path) -> None:
    slow = dataclasses.replace(FAST, rto_initial_s=20.0, rto_min_s=20.0, rto_max_s=20.0)
    with network(tmp_path) as net:
        inbox = Inbox()
        b = net.link("B", ["A"], inbox, settings=slow)
        a = net.link("A", ["B"], settings=slow)
        assert a.wait_subscribed([wire.topic_to("B")], WAIT_S)
        lossy = Lossy(a)
        # Seqs 2..4 vanish (as across a reconnect); 5 arrives and reveals the gap.
        lossy.drop = first_transmission_of({2, 3, 4})
        for n in range(6):
            a.send(trig("A", "B", n))
        assert inbox.wait(lambda items: len(items) >= 6, timeout=10)
        assert triggers(inbox) == list(range(6))
        assert b.reordered >= 1 and b.nacks_sent >= 1


def test_broadcasts_reach_every_peer_once(tmp_path: Path) -> None:
    with network(tmp_path) as net:
        inboxes = {n: Inbox() for n in ("D1", "D2", "D3")}
        for n, inbox in inboxes.items():
            net.link(n, ["GCS", *(o for o in inboxes if o != n)], inbox)
        gcs = net.link("GCS", list(inboxes))
        assert gcs.wait_subscribed([wire.TOPIC_ALL], WAIT_S)
        lossy = Lossy(gcs, seed=7)
        lossy.drop = lossy.random(0.5, (wire.Start, wire.Abort, wire.Complete))
        gcs.send(wire.Start(MISSION, "GCS"))
        for i in range(20):
            gcs.send(wire.Abort(MISSION, "GCS", f"r{i}"))
        gcs.send(wire.Complete(MISSION, "GCS"))
        for inbox in inboxes.values():
            assert inbox.wait_type(wire.Complete)
        assert gcs.flush(WAIT_S)
        for inbox in inboxes.values():
            kinds = (wire.Start, wire.Abort, wire.Complete)
            got = [type(m).__name__ for m in inbox.items if isinstance(m, kinds)]
            assert got == ["Start"] + ["Abort"] * 20 + ["Complete"]
            assert [m.reason for m in inbox.of(wire.Abort)] == [f"r{i}" for i in range(20)]
        assert gcs.stats()["unacked"] == 0


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
    finally:
        close_logger(log)
    events = [e["event"] for e in read_log(tmp_path / "a.log")]
    assert events.count("mission.peer.lost") == 1 and events.count("mission.peer.back") == 1
    assert "mission.peer.left" in events


def test_telemetry_capped_coalesced_and_refreshed(tmp_path: Path) -> None:
    with network(tmp_path) as net:
        inbox = Inbox()
        net.link("B", ["A"], inbox, topics=(wire.topic_telemetry("A"),))
        a = net.link("A", ["B"])
        assert a.wait_subscribed([wire.topic_telemetry("A")], WAIT_S)
        for n in range(200):  # far faster than 20 Hz
            a.send(sample("A", 100.0 + n, x=float(n)))
        # The latest always arrives (the end of a burst is never lost) ...
        assert inbox.wait(lambda items: any(s.x_m == 199.0 for s in inbox.of(wire.TelemetrySample)))
        got = inbox.of(wire.TelemetrySample)
        assert len(got) < 50
        # ... and is repeated while nothing new comes (a drone at rest stays fresh).
        seen = len(got)
        assert inbox.wait(lambda items: len(inbox.of(wire.TelemetrySample)) >= seen + 3)
        assert not inbox.of(TelemetryStale)
        assert all(s.x_m == 199.0 for s in inbox.of(wire.TelemetrySample)[seen:])


def test_telemetry_goes_stale_then_fresh_and_old_samples_are_dropped(tmp_path: Path) -> None:
    settings = dataclasses.replace(FAST, telemetry_max_hz=1e9)
    log = make_logger(tmp_path / "b.log", drone="B")
    try:
        with network(tmp_path) as net:
            inbox = Inbox()
            b = net.link(
                "B", ["A"], inbox, topics=(wire.topic_telemetry("A"),), settings=settings, log=log
            )
            a = net.link("A", ["B"], settings=settings)
            assert a.wait_subscribed([wire.topic_telemetry("A")], WAIT_S)
            a.send(sample("A", 10.0, x=1.0))
            assert inbox.wait_type(wire.TelemetrySample)
            a.send(sample("A", 5.0, x=2.0))  # older than what B has: no news
            a.send(sample("A", 11.0, x=3.0))
            assert inbox.wait(
                lambda items: any(s.x_m == 3.0 for s in inbox.of(wire.TelemetrySample))
            )
            assert all(s.x_m != 2.0 for s in inbox.of(wire.TelemetrySample))
            assert b.old_telemetry >= 1
            lossy = Lossy(a)
            lossy.drop = lambda m: isinstance(m, wire.TelemetrySample)
            assert inbox.wait_type(TelemetryStale)
            stale = inbox.of(TelemetryStale)[0]
            assert stale.sender == "A" and stale.age_s >= settings.telemetry_stale_s
            assert a.stats()["peers"]["B"]["state"] == "up"  # the drone is alive, its data is old
            lossy.drop = lambda m: False
            a.send(sample("A", 12.0, x=4.0))
            assert inbox.wait(
                lambda items: any(s.x_m == 4.0 for s in inbox.of(wire.TelemetrySample))
            )
    finally:
        close_logger(log)
    events = [e["event"] for e in read_log(tmp_path / "b.log")]
    assert "mission.telemetry.stale" in events and "mission.telemetry.fresh" in events


def test_unknown_destination_and_closed_link(tmp_path: Path) -> None:
    with network(tmp_path) as net:
        a = net.link("A", ["B"])
        assert a.send(trig("A", "Z", 0))  # not a peer: sent once, unsequenced, logged
        assert a.stats()["unacked"] == 0
        a.close()
        assert not a.send(trig("A", "B", 0))
        a.close()  # idempotent


def test_settings_are_validated() -> None:
    with pytest.raises(ValueError, match="peer_timeout_s"):
        LinkSettings(heartbeat_s=1.0, peer_timeout_s=0.5)
    with pytest.raises(ValueError, match="telemetry_stale_s"):
        LinkSettings(heartbeat_s=1.0, telemetry_stale_s=0.5, peer_timeout_s=3.0)
    with pytest.raises(ValueError, match="rto_min_s"):
        LinkSettings(heartbeat_s=1.0, rto_min_s=0.5)
    with pytest.raises(ValueError, match="heartbeat_s"):
        LinkSettings(heartbeat_s=0)
