"""The reliable-delivery protocol alone: sessions, a fake clock, messages passed in memory.

Exactly once and in order per link under loss of messages and acks,
duplicates, reordering and late joiners; retransmission timing and back-off;
round-trip times (Karn); explicit acks; reliable broadcasts; heartbeats and
lost/back/left peers; latest-value telemetry (rate cap, refresh, staleness,
old samples).  No thread, socket or clock: each test runs in milliseconds.
"""

from __future__ import annotations

import ast
import dataclasses
import itertools
import random
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import msgspec
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from eamos.logs import close_logger, make_logger, read_log
from eamos.net import wire
from eamos.net.effects import Deliver, PeerStatus, Send, TelemetryStale, TriggersAcknowledged, Wake
from eamos.net.link import LinkSettings
from eamos.net.session import NACK_INTERVAL_S, ReliableSession

from .session_helpers import (
    FAST,
    MISSION,
    NEVER,
    Fleet,
    first_transmission_of,
    random_rule,
    sample,
    trig,
)

SLOW_TIMER = dataclasses.replace(FAST, rto_initial_s=20.0, rto_min_s=20.0, rto_max_s=20.0)


def triggers(fleet: Fleet, who: str, sender: str | None = None) -> list[int]:
    got = fleet.of(who, wire.Trigger)
    return [m.iteration[0] for m in got if sender is None or m.sender == sender]


def session(name: str = "A", peers: tuple[str, ...] = ("B",), **kw: object) -> ReliableSession:
    kw.setdefault("incarnation", 0)  # 0: messages compare equal to unstamped ones
    s = ReliableSession(name, MISSION, FAST, rng=random.Random(1), **kw)  # type: ignore[arg-type]
    s.add_peers(peers)
    return s


def sends(actions: Sequence[object]) -> list[Any]:
    return [a.message for a in actions if isinstance(a, Send)]


def delivered(actions: Sequence[object]) -> list[Any]:
    return [a.item for a in actions if isinstance(a, Deliver)]


def seq(n: int, sender: str = "B", dest: str = "A", cls: type = wire.Trigger) -> wire.Message:
    if cls is wire.Report:
        return wire.Report(MISSION, sender, {"ok": True}, dest=dest, seq=n)
    return msgspec.structs.replace(trig(sender, dest, n), seq=n)


# -- delivery -------------------------------------------------------------------------


def test_exactly_once_in_order_with_messages_and_acks_lost() -> None:
    fleet = Fleet(["A", "B"])
    a, b = fleet.sessions["A"], fleet.sessions["B"]
    rng = random.Random(3)
    lose_triggers = random_rule(rng, 0.3, (wire.Trigger,), sender="A")
    lose_acks = random_rule(rng, 0.3, (wire.Ack, wire.Heartbeat), sender="B")  # acks ride on both
    fleet.lose = lambda s, to, m: lose_triggers(s, to, m) or lose_acks(s, to, m)
    fleet.duplicate = random_rule(rng, 0.1, (wire.Trigger,), sender="A")
    count = 300
    for n in range(count):
        fleet.send("A", trig("A", "B", n))
    assert fleet.until(lambda: len(fleet.of("B", wire.Trigger)) >= count)
    assert fleet.until(a.flushed)
    assert triggers(fleet, "B") == list(range(count))  # each once, in order
    assert [m.seq for m in fleet.of("B", wire.Trigger)] == list(range(1, count + 1))
    dropped = fleet.dropped_from["A"]
    assert dropped > 0 and a.counters.retransmissions >= dropped
    assert b.counters.duplicates_dropped > 0  # retransmissions of messages whose ack was lost
    assert a.unacked() == 0


def test_late_joiner_gets_everything_sent_before_it_existed_at_once() -> None:
    fleet = Fleet(["A", "B"])
    a = fleet.sessions["A"]
    fleet.down.add("B")  # not subscribed yet: the XPUB socket drops what A sends
    for n in range(50):
        fleet.send("A", trig("A", "B", n))
    fleet.advance(0.3)
    assert not a.flushed()
    fleet.advance(3.0)  # the timer keeps trying, in vain
    assert not a.flushed() and a.counters.retransmissions > 0
    joined = fleet.now
    fleet.subscribe("A", wire.topic_to("B"), by="B")
    # Resent as the subscription is seen, not at the next timeout.
    assert fleet.now == joined and triggers(fleet, "B") == list(range(50))
    assert fleet.until(a.flushed)


def test_tail_loss_recovered_by_heartbeat_nack() -> None:
    """The last message is lost and the sender's timer is long: the heartbeat tells."""
    fleet = Fleet(["A", "B"], SLOW_TIMER)
    b = fleet.sessions["B"]
    fleet.lose = first_transmission_of({3})
    for n in range(3):
        fleet.send("A", trig("A", "B", n))
    # Far sooner than the 20 s retransmission timeout.
    assert fleet.until(lambda: len(fleet.of("B", wire.Trigger)) >= 3, limit_s=10)
    assert fleet.now < 1.0
    assert triggers(fleet, "B") == [0, 1, 2]
    assert b.counters.nacks_sent >= 1 and fleet.dropped == 1


def test_gap_is_nacked_and_filled_in_order() -> None:
    fleet = Fleet(["A", "B"], SLOW_TIMER)
    b = fleet.sessions["B"]
    # Seqs 2..4 vanish (as across a reconnect); 5 arrives and reveals the gap.
    fleet.lose = first_transmission_of({2, 3, 4})
    for n in range(6):
        fleet.send("A", trig("A", "B", n))
    assert fleet.until(lambda: len(fleet.of("B", wire.Trigger)) >= 6, limit_s=10)
    assert fleet.now < 1.0
    assert triggers(fleet, "B") == list(range(6))
    assert b.counters.reordered >= 1 and b.counters.nacks_sent >= 1


def test_broadcasts_reach_every_peer_once() -> None:
    drones = ("D1", "D2", "D3")
    fleet = Fleet(["GCS", *drones], seed=7)
    gcs = fleet.sessions["GCS"]
    fleet.lose = random_rule(
        random.Random(7), 0.5, (wire.Start, wire.Abort, wire.Complete), sender="GCS"
    )
    fleet.send("GCS", wire.Start(MISSION, "GCS"))
    for i in range(20):
        fleet.send("GCS", wire.Abort(MISSION, "GCS", f"r{i}"))
    fleet.send("GCS", wire.Complete(MISSION, "GCS"))
    assert fleet.until(lambda: all(fleet.of(d, wire.Complete) for d in drones))
    assert fleet.until(gcs.flushed)
    for d in drones:
        kinds = (wire.Start, wire.Abort, wire.Complete)
        got = [type(m).__name__ for m in fleet.got[d] if isinstance(m, kinds)]
        assert got == ["Start"] + ["Abort"] * 20 + ["Complete"]
        assert [m.reason for m in fleet.of(d, wire.Abort)] == [f"r{i}" for i in range(20)]
    assert gcs.unacked() == 0


def test_duplicate_is_dropped_and_acknowledged_at_once() -> None:
    b = session("B", ("A",))
    assert delivered(b.on_receive(seq(1, "A", "B"), 0.0)) == [seq(1, "A", "B")]
    assert b.on_batch_end(0.0) == []  # steady traffic: the next heartbeat acknowledges
    assert delivered(b.on_receive(seq(1, "A", "B"), 0.5)) == []
    assert b.counters.duplicates_dropped == 1
    # The sender is retransmitting, so it lacks the ack: an explicit one goes now.
    assert sends(b.on_batch_end(0.5)) == [wire.Ack(MISSION, "B", "A", 1, 0)]


def test_out_of_order_waits_for_the_gap_and_nacks_are_rate_limited() -> None:
    b = session("B", ("A",))
    assert delivered(b.on_receive(seq(3, "A", "B"), 0.0)) == []
    assert b.counters.reordered == 1
    assert sends(b.on_batch_end(0.0)) == [wire.Ack(MISSION, "B", "A", 0, 0, nack=True)]
    assert delivered(b.on_receive(seq(2, "A", "B"), NACK_INTERVAL_S / 2)) == []
    # Too soon for another nack: a plain ack.
    assert sends(b.on_batch_end(NACK_INTERVAL_S / 2)) == [wire.Ack(MISSION, "B", "A", 0, 0)]
    assert b.counters.nacks_sent == 1
    got = delivered(b.on_receive(seq(1, "A", "B"), 2 * NACK_INTERVAL_S))
    assert [m.seq for m in got] == [1, 2, 3]
    assert b.on_batch_end(2 * NACK_INTERVAL_S) == []


def test_a_final_report_is_acknowledged_at_once() -> None:
    gcs = session("GCS", ("D1",))
    report = seq(1, "D1", "GCS", wire.Report)
    assert delivered(gcs.on_receive(report, 0.0)) == [report]
    assert sends(gcs.on_batch_end(0.0)) == [wire.Ack(MISSION, "GCS", "D1", 1, 0)]


def test_unknown_destination_and_closed_session() -> None:
    a = session("A", ("B",))
    unknown = trig("A", "Z", 0)
    assert a.on_send(unknown, 0.0) == [Send(unknown)]  # not a peer: sent once, unsequenced
    assert a.unacked() == 0
    (goodbye,) = sends(a.close())
    assert isinstance(goodbye, wire.Heartbeat) and goodbye.leaving
    assert a.on_send(trig("A", "B", 0), 0.1) == []
    assert a.on_batch_end(0.1) == [] and a.flushed()
    assert a.close() == []  # idempotent


def test_settings_are_validated() -> None:
    with pytest.raises(ValueError, match="peer_timeout_s"):
        LinkSettings(heartbeat_s=1.0, peer_timeout_s=0.5)
    with pytest.raises(ValueError, match="telemetry_stale_s"):
        LinkSettings(heartbeat_s=1.0, telemetry_stale_s=0.5, peer_timeout_s=3.0)
    with pytest.raises(ValueError, match="rto_min_s"):
        LinkSettings(heartbeat_s=1.0, rto_min_s=0.5)
    with pytest.raises(ValueError, match="heartbeat_s"):
        LinkSettings(heartbeat_s=0)


# -- retransmission timing --------------------------------------------------------------


def test_the_first_timeout_is_three_heartbeats_within_the_bounds() -> None:
    # Before a round trip is measured: the ack rides the receiver's next heartbeat.
    assert LinkSettings().rto_initial_s == pytest.approx(3.0)
    assert LinkSettings(heartbeat_s=0.5, peer_timeout_s=3.0).rto_initial_s == pytest.approx(1.5)
    assert LinkSettings(heartbeat_s=1.0, rto_max_s=2.5).rto_initial_s == pytest.approx(2.5)
    assert LinkSettings(heartbeat_s=1.0, rto_min_s=4.0, rto_max_s=9.0).rto_initial_s == 4.0
    assert LinkSettings(rto_initial_s=1.2).rto_initial_s == 1.2  # said explicitly: kept


def test_retransmission_timeout_doubles_with_jitter_up_to_the_maximum() -> None:
    fleet = Fleet(["A", "B"])
    a = fleet.sessions["A"]
    fleet.lose = lambda s, to, m: s == "A"  # B hears nothing from A: no nack, only the timer
    fleet.send("A", trig("A", "B", 0))
    fleet.run(8.0)
    times = [t for t, m in fleet.sent_by("A", wire.Trigger)]
    assert times[0] == 0.0 and len(times) >= 6
    gaps = [b - a for a, b in itertools.pairwise(times)]
    assert gaps[0] == pytest.approx(FAST.rto_initial_s)  # the first timeout: the initial RTO
    backoff = FAST.rto_initial_s
    for gap in gaps[1:]:
        backoff = min(2 * backoff, FAST.rto_max_s)
        assert 0.8 * backoff - 1e-9 <= gap <= 1.2 * backoff + 1e-9
    assert backoff == FAST.rto_max_s
    assert {m.seq for _, m in fleet.sent_by("A", wire.Trigger)} == {1}
    assert a.counters.retransmissions == len(times) - 1
    fleet.lose = NEVER
    assert fleet.until(a.flushed)
    assert triggers(fleet, "B") == [0]


def test_round_trip_measured_once_per_message_karn_and_clamped() -> None:
    a = session("A", ("B",))
    actions = a.on_send(trig("A", "B", 0), 0.0)
    assert Wake(FAST.rto_initial_s) in actions  # the timer is armed with the initial RTO
    a.on_receive(wire.Ack(MISSION, "B", "A", 1, 0), 0.05)
    assert a.peer_stats()["B"]["rtt_ms"] == 50.0
    # RTO = 50 ms + 4 * 25 ms, clamped to rto_min_s.
    actions = a.on_send(trig("A", "B", 1), 1.0)
    assert Wake(1.0 + FAST.rto_min_s) in actions
    actions, _ = a.on_tick(1.0 + FAST.rto_min_s)
    assert [m.seq for m in sends(actions) if isinstance(m, wire.Trigger)] == [2]
    # Acknowledged after a retransmission: which copy arrived is unknown, no sample.
    a.on_receive(wire.Ack(MISSION, "B", "A", 2, 0), 3.0)
    assert a.peer_stats()["B"]["rtt_ms"] == 50.0
    assert a.unacked() == 0


def test_a_nack_resends_what_is_not_in_flight_any_more() -> None:
    a = session("A", ("B",))
    for n in range(3):
        a.on_send(trig("A", "B", n), 0.0)
    nack = wire.Ack(MISSION, "B", "A", 1, 0, nack=True)
    # Just sent (within the in-flight window, rto_min_s before an RTT is known): not again.
    assert sends(a.on_receive(nack, 0.01)) == []
    again = sends(a.on_receive(nack, 1.0))
    assert [m.seq for m in again] == [2, 3]


# -- peers ------------------------------------------------------------------------------


def test_peer_lost_back_then_left(tmp_path: Path) -> None:
    log = make_logger(tmp_path / "a.log", drone="A")
    try:
        fleet = Fleet(["A", "B"], logs={"A": log})
        a = fleet.sessions["A"]
        fleet.advance(0.3)
        assert a.peer_stats()["B"]["state"] == "up"
        fleet.lose = lambda s, to, m: s == "B"  # B goes silent
        assert fleet.until(lambda: any(i.state == "lost" for i in fleet.statuses("A")))
        fleet.send("A", trig("A", "B", 0))  # for A, B is just silent
        fleet.lose = NEVER
        assert fleet.until(lambda: any(i.state == "back" for i in fleet.statuses("A")))
        assert fleet.until(a.flushed)
        fleet.close("B")
        assert fleet.until(lambda: any(i.state == "left" for i in fleet.statuses("A")))
        states = [i.state for i in fleet.statuses("A")]
        assert states == ["lost", "back", "left"]
        serials = [i.serial for i in fleet.statuses("A")]
        assert serials == sorted(serials)
        lost = fleet.statuses("A")[0]
        assert lost.sender == "B" and lost.silent_s >= FAST.peer_timeout_s
        # A peer that said goodbye is never reported lost afterwards.
        fleet.advance(5.0)
        assert len(fleet.statuses("A")) == 3
    finally:
        close_logger(log)
    events = [e["event"] for e in read_log(tmp_path / "a.log")]
    assert events.count("mission.peer.lost") == 1 and events.count("mission.peer.back") == 1
    assert "mission.peer.left" in events


def test_a_peer_heard_again_gets_what_it_missed_at_once() -> None:
    fleet = Fleet(["A", "B"])
    fleet.advance(0.3)
    fleet.lose = lambda s, to, m: True  # a partition
    fleet.send("A", trig("A", "B", 0))
    assert fleet.until(lambda: any(i.state == "lost" for i in fleet.statuses("A")))
    fleet.run(fleet.sent_by("A", wire.Trigger)[-1][0] + 0.05)  # just after a timeout
    healed = fleet.now
    fleet.lose = NEVER
    assert fleet.until(lambda: triggers(fleet, "B") == [0], step=0.001)
    # Within B's next heartbeat, long before A's timer (backed off to about 1 s).
    assert fleet.now - healed <= FAST.heartbeat_s + 0.002
    assert fleet.statuses("A")[-1].state == "back"


def test_a_peer_that_left_holds_nothing_back() -> None:
    fleet = Fleet(["GCS", "D1", "D2"])
    gcs = fleet.sessions["GCS"]
    fleet.advance(0.3)
    fleet.lose = lambda s, to, m: to == "D2"  # D2 hears nothing any more
    fleet.send("GCS", wire.Start(MISSION, "GCS"))
    fleet.send("GCS", trig("GCS", "D2", 0))
    assert not gcs.flushed() and not gcs.flushed(["D2"])
    fleet.close("D2")  # its goodbye gets out
    assert [s.state for s in fleet.statuses("GCS")] == ["left"]
    # D1 acknowledges the Start on its next heartbeat; D2 is not waited for.
    assert fleet.until(gcs.flushed, limit_s=2 * FAST.heartbeat_s)
    assert gcs.unacked() == 1  # the trigger to D2, until its timer gives it up
    fleet.advance(FAST.rto_max_s * 2)
    assert gcs.counters.abandoned == 1 and gcs.unacked() == 0


def test_an_unwatched_peer_is_never_lost() -> None:
    fleet = Fleet(["GCS", "D1", "D2"], watch={"D1": ["GCS"]})
    fleet.advance(0.3)
    fleet.down.add("D2")
    fleet.advance(3.0)
    assert [(s.sender, s.state) for s in fleet.statuses("D1")] == []
    assert [(s.sender, s.state) for s in fleet.statuses("GCS")] == [("D2", "lost")]
    assert fleet.sessions["D1"].peer_stats()["D2"]["state"] == "unwatched"


def test_heartbeats_keep_their_period_and_an_idle_session_wakes_only_for_them() -> None:
    fleet = Fleet(["A", "B"])
    fleet.run(1.05)
    times = [t for t, _ in fleet.sent_by("A", wire.Heartbeat)]
    assert len(times) == 11 and times[0] == 0.0
    gaps = [b - a for a, b in itertools.pairwise(times)]
    assert all(g == pytest.approx(FAST.heartbeat_s) for g in gaps)
    assert fleet.ticks["A"] == len(times)  # no wake-up without something due


def test_steady_traffic_is_acknowledged_by_heartbeats_alone() -> None:
    fleet = Fleet(["A", "B"])
    a, b = fleet.sessions["A"], fleet.sessions["B"]
    for n in range(20):
        fleet.send("A", trig("A", "B", n))
        fleet.advance(0.01)
    assert fleet.until(a.flushed)
    assert b.counters.acks_sent == 0 and fleet.sent_by("B", wire.Ack) == []
    assert a.counters.retransmissions == 0


# -- telemetry --------------------------------------------------------------------------


def test_telemetry_capped_coalesced_and_refreshed() -> None:
    fleet = Fleet(["A", "B"])
    for n in range(200):  # far faster than 20 Hz
        fleet.send("A", sample("A", 100.0 + n, x=float(n)))
        fleet.advance(0.0005)
    # The latest always arrives (the end of a burst is never lost) ...
    assert fleet.until(lambda: any(s.x_m == 199.0 for s in fleet.of("B", wire.TelemetrySample)))
    got = fleet.of("B", wire.TelemetrySample)
    assert len(got) < 50
    # ... and is repeated while nothing new comes (a drone at rest stays fresh).
    seen = len(got)
    assert fleet.until(lambda: len(fleet.of("B", wire.TelemetrySample)) >= seen + 3)
    assert not fleet.stale("B")
    assert all(s.x_m == 199.0 for s in fleet.of("B", wire.TelemetrySample)[seen:])
    times = [t for t, _ in fleet.sent_by("A", wire.TelemetrySample)]
    assert all(b - a >= 1 / FAST.telemetry_max_hz - 1e-9 for a, b in itertools.pairwise(times))


def test_telemetry_goes_stale_then_fresh_and_old_samples_are_dropped(tmp_path: Path) -> None:
    settings_ = dataclasses.replace(FAST, telemetry_max_hz=1e9)
    log = make_logger(tmp_path / "b.log", drone="B")
    try:
        fleet = Fleet(["A", "B"], settings_, logs={"B": log})
        a, b = fleet.sessions["A"], fleet.sessions["B"]
        fleet.send("A", sample("A", 10.0, x=1.0))
        assert fleet.of("B", wire.TelemetrySample)
        fleet.advance(0.01)
        fleet.send("A", sample("A", 5.0, x=2.0))  # older than what B has: no news
        fleet.advance(0.01)
        fleet.send("A", sample("A", 11.0, x=3.0))
        assert any(s.x_m == 3.0 for s in fleet.of("B", wire.TelemetrySample))
        assert all(s.x_m != 2.0 for s in fleet.of("B", wire.TelemetrySample))
        assert b.counters.old_telemetry >= 1
        fleet.lose = lambda s, to, m: isinstance(m, wire.TelemetrySample)
        assert fleet.until(lambda: bool(fleet.stale("B")))
        stale = fleet.stale("B")[0]
        assert stale.sender == "A" and stale.age_s >= settings_.telemetry_stale_s
        assert a.peer_stats()["B"]["state"] == "up"  # the drone is alive, its data is old
        fleet.lose = NEVER
        fleet.send("A", sample("A", 12.0, x=4.0))
        assert any(s.x_m == 4.0 for s in fleet.of("B", wire.TelemetrySample))
    finally:
        close_logger(log)
    events = [e["event"] for e in read_log(tmp_path / "b.log")]
    assert "mission.telemetry.stale" in events and "mission.telemetry.fresh" in events


def test_a_new_telemetry_subscriber_gets_the_latest_sample_at_once() -> None:
    a = session("A", ("B",))
    assert a.on_subscription(wire.topic_telemetry("A"), 0.0) == []  # nothing to repeat yet
    latest = sample("A", 1.0, x=7.0)
    assert a.on_send(latest, 0.0) == [Send(latest)]
    assert a.on_subscription(wire.topic_telemetry("A"), 0.01) == [Send(latest)]


# -- the property ------------------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    loss=st.floats(0.0, 0.6),
    dup=st.floats(0.0, 0.3),
    delay=st.floats(0.0, 0.5),
    reorder=st.booleans(),
    counts=st.lists(st.integers(0, 25), min_size=6, max_size=6),
    broadcasts=st.integers(0, 10),
    chaos_s=st.floats(0.0, 4.0),
)
def test_any_loss_duplication_and_reordering_delivers_each_message_once_in_order(
    seed: int,
    loss: float,
    dup: float,
    delay: float,
    reorder: bool,
    counts: list[int],
    broadcasts: int,
    chaos_s: float,
) -> None:
    names = ["GCS", "D1", "D2"]
    links = [(s, d) for s in names for d in names if s != d]
    fleet = Fleet(names, seed=seed)
    rng = random.Random(seed)
    fleet.lose = lambda s, to, m: rng.random() < loss
    fleet.duplicate = lambda s, to, m: rng.random() < dup
    fleet.delay = lambda s, to, m: rng.random() < delay
    fleet.reorder = reorder
    todo = [(s, d, n) for (s, d), count in zip(links, counts, strict=True) for n in range(count)]
    todo += [("GCS", "*", n) for n in range(broadcasts)]
    next_n = dict.fromkeys(links, 0)
    next_b = 0
    rng.shuffle(todo)
    for s, d, _ in todo:  # each link's messages in order, the links interleaved
        if d == "*":
            fleet.send(s, wire.Abort(MISSION, s, f"r{next_b}"))
            next_b += 1
        else:
            fleet.send(s, trig(s, d, next_n[(s, d)]))
            next_n[(s, d)] += 1
        fleet.advance(rng.uniform(0.0, 0.05))
    fleet.run(fleet.now + chaos_s)
    fleet.lose = fleet.duplicate = fleet.delay = NEVER  # the network heals: delivery is eventual
    assert fleet.until(
        lambda: all(s.flushed() for s in fleet.sessions.values()), limit_s=120, step=0.5
    )
    for (s, d), count in zip(links, counts, strict=True):
        assert triggers(fleet, d, sender=s) == list(range(count)), (s, d)
    for d in ("D1", "D2"):
        assert [m.reason for m in fleet.of(d, wire.Abort)] == [f"r{i}" for i in range(broadcasts)]
    # Each sender is told of each of its triggers' acknowledgement exactly once.
    for (s, d), count in zip(links, counts, strict=True):
        told = [k for a in fleet.of(s, TriggersAcknowledged) if a.sender == d for k in a.triggers]
        assert sorted(it[0] for _, _, it in told) == list(range(count)), (s, d)
    assert all(
        isinstance(i, PeerStatus | TelemetryStale | TriggersAcknowledged | wire.Message)
        for g in fleet.got.values()
        for i in g
    )


# -- purity ------------------------------------------------------------------------------

PURE_MODULES = ("session", "sequence", "liveness", "effects", "settings")


@pytest.mark.parametrize("module", PURE_MODULES)
def test_the_protocol_modules_use_no_thread_socket_or_clock(module: str) -> None:
    """The protocol is pure: time comes in as an argument, effects go out as values."""
    path = Path(__file__).resolve().parents[2] / "eamos" / "net" / f"{module}.py"
    imported: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            imported |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            imported.add(node.module.split(".")[0])
    assert not imported & {"threading", "time", "socket", "zmq", "asyncio", "select"}, imported
