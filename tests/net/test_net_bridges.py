"""Out-/In-Bridges over real loopback TCP sockets."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Any

import msgpack
import pytest
import zmq

import eamos.net.out_bridge as out_bridge_module
from eamos.logs import close_logger, make_logger, read_log
from eamos.net import (
    TOPIC_ALL,
    Abort,
    Complete,
    InBridge,
    Message,
    OutBridge,
    Progress,
    Ready,
    Report,
    Resolved,
    Start,
    TelemetrySample,
    Trigger,
    encode,
    topic_telemetry,
    topic_to,
)

from .net_helpers import MISSION, WAIT_S, Bridges, Collector

pytestmark = pytest.mark.timeout(120)


def trig(sender: str, dest: str, n: int, mission: str = MISSION, src: str = "a") -> Trigger:
    return Trigger(mission, sender, dest, src, "b", (n,), "done")


def tel(sender: str, t: float) -> TelemetrySample:
    return TelemetrySample(MISSION, sender, t, t, 0.0, 10.0, 47.0, 8.0, 500.0, 90.0, True, False)


def test_endpoint_resolves_ephemeral_port(bridges: Bridges) -> None:
    for bind in ("tcp://127.0.0.1:0", "tcp://*:0"):
        out = bridges.out(bind)
        host, port = out.endpoint.rsplit(":", 1)
        assert host.startswith("tcp://")
        assert int(port) > 0


def test_wait_subscribed_then_nothing_lost(bridges: Bridges) -> None:
    out = bridges.out()
    # Nobody is connected yet: the wait must time out (a bounded wait, not a sleep).
    assert not out.wait_subscribed([topic_to("D2")], 0.3)

    inbox = Collector()
    inb = bridges.inb({"D1": out.endpoint}, [topic_to("D2")], inbox)
    assert out.wait_subscribed([topic_to("D2")], WAIT_S)
    assert topic_to("D2") in out.subscriptions
    # Still not subscribed to a topic nobody asked for.
    assert not out.wait_subscribed([topic_to("D2"), topic_to("D3")], 0.1)

    count = 1000
    for n in range(count):
        assert out.send(trig("D1", "D2", n))
    assert inbox.wait_count(count), f"got {len(inbox.messages)} of {count}"
    assert [m.iteration[0] for m in inbox.messages] == list(range(count))  # type: ignore[union-attr]
    assert inb.received == count
    assert inb.dropped == 0
    assert out.sent_counts == {"Trigger": count}
    assert out.sent_bytes == sum(len(f) for n in range(count) for f in encode(trig("D1", "D2", n)))


def test_concurrent_senders_keep_per_sender_order(bridges: Bridges) -> None:
    """Four threads share one OutBridge and a second participant sends too."""
    out1, out3 = bridges.out(), bridges.out()
    inbox = Collector()
    bridges.inb({"D1": out1.endpoint, "D3": out3.endpoint}, [topic_to("D2")], inbox)
    for out in (out1, out3):
        assert out.wait_subscribed([topic_to("D2")], WAIT_S)

    per_thread = 250
    go = threading.Barrier(5)

    def sender(out: OutBridge, name: str, src: str) -> None:
        go.wait(WAIT_S)
        for n in range(per_thread):
            out.send(trig(name, "D2", n, src=src))

    threads = [threading.Thread(target=sender, args=(out1, "D1", f"t{i}")) for i in range(4)]
    threads.append(threading.Thread(target=sender, args=(out3, "D3", "t0")))
    for t in threads:
        t.start()
    for t in threads:
        t.join(WAIT_S)
    total = per_thread * len(threads)
    assert inbox.wait_count(total), f"got {len(inbox.messages)} of {total}"
    streams: dict[tuple[str, str], list[int]] = {}
    for m in inbox.messages:
        assert isinstance(m, Trigger)
        streams.setdefault((m.sender, m.src_node), []).append(m.iteration[0])
    assert len(streams) == 5
    assert all(seq == list(range(per_thread)) for seq in streams.values())


def test_senders_write_the_socket_themselves_and_subscriptions_are_still_seen(
    bridges: Bridges, monkeypatch: pytest.MonkeyPatch
) -> None:
    """No hand-over to the bridge thread, yet a subscriber joining mid-stream is noticed.

    The bridge thread reads subscriptions while other threads send on the same
    socket (under its lock); a send can consume the socket's edge-triggered
    wake-up signal, which the sender then passes on.
    """
    out = bridges.out()
    sending_threads: set[str] = set()
    real = out_bridge_module.send_message

    def spy(sock: Any, frames: Any) -> None:
        if sock is out._xpub:
            sending_threads.add(threading.current_thread().name)
        real(sock, frames)

    monkeypatch.setattr(out_bridge_module, "send_message", spy)
    stop = threading.Event()

    def flood() -> None:
        n = 0
        while not stop.is_set():
            out.send(trig("D1", "D9", n))
            n += 1

    flooder = threading.Thread(target=flood, name="flooder")
    flooder.start()
    try:
        for n in range(3):  # three subscribers join, one after another, while it sends
            inbox = Collector()
            bridges.inb({"D1": out.endpoint}, [topic_to(f"D{n + 2}")], inbox)
            assert out.wait_subscribed([topic_to(f"D{n + 2}")], WAIT_S), n
            assert out.send(trig("D1", f"D{n + 2}", n))
            assert inbox.wait_count(1)
    finally:
        stop.set()
        flooder.join(WAIT_S)
    assert sending_threads == {"flooder", threading.current_thread().name}


@dataclass
class Participant:
    name: str
    out: OutBridge
    inbox: Collector
    inb: InBridge | None = None


def test_two_drones_and_ground_station(bridges: Bridges) -> None:
    names = ["D1", "D2", "GCS"]
    parts = {n: Participant(n, bridges.out(), Collector()) for n in names}
    subscribe = {
        "D1": [topic_to("D1"), TOPIC_ALL, topic_telemetry("D2")],
        "D2": [topic_to("D2"), TOPIC_ALL, topic_telemetry("D1")],
        "GCS": [topic_to("GCS"), topic_telemetry("D1"), topic_telemetry("D2")],
    }
    for p in parts.values():
        peers = {o: parts[o].out.endpoint for o in names if o != p.name}
        p.inb = bridges.inb(peers, subscribe[p.name], p.inbox)
    d1, d2, gcs = parts["D1"], parts["D2"], parts["GCS"]

    # Drones report ready only once everyone they send to has subscribed.
    assert d1.out.wait_subscribed([topic_to("D2"), topic_to("GCS")], WAIT_S)
    assert d2.out.wait_subscribed([topic_to("D1"), topic_to("GCS")], WAIT_S)
    d1.out.send(Ready(MISSION, "D1", "sum1"))
    d2.out.send(Ready(MISSION, "D2", "sum2"))
    assert gcs.inbox.wait_type(Ready, 2)
    assert {m.sender for m in gcs.inbox.messages} == {"D1", "D2"}

    assert gcs.out.wait_subscribed([TOPIC_ALL], WAIT_S)
    gcs.out.send(Start(MISSION, "GCS"))
    assert d1.inbox.wait_type(Start) and d2.inbox.wait_type(Start)

    # Triggers both ways, telemetry to the other drone and the ground station.
    d1.out.send(trig("D1", "D2", 0))
    d2.out.send(trig("D2", "D1", 0))
    d1.out.send(tel("D1", 1.0))
    assert d2.inbox.wait_type(Trigger) and d1.inbox.wait_type(Trigger)
    assert d2.inbox.wait_type(TelemetrySample) and gcs.inbox.wait_type(TelemetrySample)

    for d in (d1, d2):
        d.out.send(Progress(MISSION, d.name, "done", "n1", "goto", {"t": 1.0}))
        d.out.send(Resolved(MISSION, d.name))
        d.out.send(Report(MISSION, d.name, {"nodes": 3}))
    assert gcs.inbox.wait_type(Report, 2)
    gcs.out.send(Complete(MISSION, "GCS"))
    gcs.out.send(Abort(MISSION, "GCS", "test over"))
    assert d1.inbox.wait_type(Abort) and d2.inbox.wait_type(Abort)

    kinds = [type(m).__name__ for m in gcs.inbox.messages]
    assert kinds.count("Progress") == 2 and kinds.count("Resolved") == 2
    assert [type(m) for m in d1.inbox.messages if m.sender == "GCS"] == [Start, Complete, Abort]
    # A drone does not see telemetry it did not subscribe to, nor messages to others.
    assert not any(m.sender == "D1" for m in d1.inbox.messages)
    assert all(p.inb is not None and p.inb.dropped == 0 for p in parts.values())


def test_other_mission_dropped(bridges: Bridges, tmp_path: Any) -> None:
    log = make_logger(tmp_path / "net.log", drone="D2")
    out = bridges.out()
    inbox = Collector()
    inb = bridges.inb({"D1": out.endpoint}, [topic_to("D2")], inbox, log=log)
    assert out.wait_subscribed([topic_to("D2")], WAIT_S)
    out.send(trig("D1", "D2", 0, mission="another-mission"))
    out.send(trig("D1", "D2", 1))
    # Per-sender order: once the good one is here, the bad one was handled.
    assert inbox.wait_count(1)
    assert [m.mission for m in inbox.messages] == [MISSION]
    assert inb.dropped == 1
    inb.close()
    close_logger(log)
    (entry,) = [e for e in read_log(tmp_path / "net.log") if e["event"] == "net.in.drop"]
    assert entry["reason"] == "other_mission"
    assert entry["drone"] == "D2"


def test_malformed_from_raw_socket_dropped(ctx: zmq.Context[Any], bridges: Bridges) -> None:
    # A raw XPUB (a PUB that also shows subscriptions, so we know when to send).
    raw = ctx.socket(zmq.XPUB)
    raw.setsockopt(zmq.LINGER, 0)
    raw.bind("tcp://127.0.0.1:0")
    try:
        endpoint = raw.getsockopt(zmq.LAST_ENDPOINT).decode()
        inbox = Collector()
        inb = bridges.inb({"evil": endpoint}, [topic_to("D2")], inbox)
        assert raw.poll(int(WAIT_S * 1000), zmq.POLLIN)
        assert raw.recv() == b"\x01" + topic_to("D2")

        good = encode(trig("D1", "D2", 7))
        raw.send_multipart([b"to/D2", b"\xc1not msgpack"])
        raw.send_multipart([b"to/D2", msgpack.packb({"v": 99, "t": "trg"})])
        raw.send_multipart([*good, b"extra frame"])
        raw.send_multipart([b"to/D2", encode(trig("D1", "D3", 0))[1]])  # topic mismatch
        raw.send_multipart([b"to/D2"])
        # Prefix match only (to/D2 is a prefix of to/D20): ignored, not dropped.
        raw.send_multipart(encode(trig("D1", "D20", 0)))
        raw.send_multipart(good)
        assert inbox.wait_count(1)
        assert inbox.messages == [trig("D1", "D2", 7)]
        assert inb.dropped == 5
        assert inb.dropped_by_reason == {"malformed": 4, "version": 1}
        assert inb.ignored == 1
    finally:
        raw.close()


def test_older_program_and_flood_never_stall_the_bridge(
    ctx: zmq.Context[Any], bridges: Bridges, tmp_path: Any
) -> None:
    """A peer running an older program (wire version 1) floods; the bridge drops and goes on."""
    log = make_logger(tmp_path / "net.log", drone="D2")
    raw = ctx.socket(zmq.XPUB)
    raw.setsockopt(zmq.LINGER, 0)
    raw.setsockopt(zmq.SNDHWM, 0)  # the flood is not cut short at the sender
    raw.bind("tcp://127.0.0.1:0")
    try:
        inbox = Collector()
        inb = bridges.inb(
            {"D1": raw.getsockopt(zmq.LAST_ENDPOINT).decode()}, [topic_to("D2")], inbox, log=log
        )
        assert raw.poll(int(WAIT_S * 1000), zmq.POLLIN)
        raw.recv()
        old = msgpack.unpackb(encode(trig("D1", "D2", 0))[1])
        old["v"] = 1
        del old["q"]
        for _ in range(5000):
            raw.send_multipart([b"to/D2", msgpack.packb(old)])
        raw.send_multipart(encode(trig("D1", "D2", 9)))
        assert inbox.wait_count(1)
        assert inb.dropped_by_reason == {"version": 5000}
    finally:
        raw.close()
        inb.close()
        close_logger(log)
    drops = [e for e in read_log(tmp_path / "net.log") if e["event"] == "net.in.drop"]
    assert drops[0]["reason"] == "version" and "version 1" in drops[0]["detail"]
    assert 100 <= len(drops) < 200  # logged one by one at first, then rarely: no log flood


def test_callback_exception_does_not_kill_thread(bridges: Bridges, tmp_path: Any) -> None:
    log = make_logger(tmp_path / "net.log")
    inbox = Collector()

    def flaky(msg: Message) -> None:
        if isinstance(msg, Trigger) and msg.iteration[0] % 2 == 0:
            raise RuntimeError(f"boom {msg.iteration[0]}")
        inbox(msg)

    out = bridges.out()
    inb = bridges.inb({"D1": out.endpoint}, [topic_to("D2")], flaky, log=log)
    assert out.wait_subscribed([topic_to("D2")], WAIT_S)
    for n in range(10):
        out.send(trig("D1", "D2", n))
    assert inbox.wait_count(5)
    assert [m.iteration[0] for m in inbox.messages] == [1, 3, 5, 7, 9]  # type: ignore[union-attr]
    assert inb.callback_errors == 5
    inb.close()
    close_logger(log)
    errors = [e for e in read_log(tmp_path / "net.log") if e["event"] == "net.in.callback_error"]
    assert len(errors) == 5
    assert "boom" in errors[0]["exception"]


def test_add_subscription_from_another_thread(bridges: Bridges) -> None:
    out = bridges.out()
    inbox = Collector()
    inb = bridges.inb({"D1": out.endpoint}, [TOPIC_ALL], inbox)
    assert out.wait_subscribed([TOPIC_ALL], WAIT_S)
    assert not out.wait_subscribed([topic_telemetry("D1")], 0.1)

    adder = threading.Thread(target=inb.add_subscription, args=(topic_telemetry("D1"),))
    adder.start()
    adder.join(WAIT_S)
    assert out.wait_subscribed([topic_telemetry("D1")], WAIT_S)
    out.send(tel("D1", 2.0))
    assert inbox.wait_type(TelemetrySample)


def test_add_subscription_before_start(bridges: Bridges) -> None:
    out = bridges.out()
    inbox = Collector()
    inb = bridges.inb({"D1": out.endpoint}, [], inbox, start=False)
    assert inb.add_subscription(topic_to("D2"))
    assert out.wait_subscribed([topic_to("D2")], WAIT_S)
    out.send(trig("D1", "D2", 0))  # queued in the SUB socket until the thread starts
    inb.start()
    assert inbox.wait_count(1)


def test_close_never_hangs_with_peers_gone(ctx: zmq.Context[Any]) -> None:
    out = OutBridge(ctx, "tcp://127.0.0.1:0", None)
    out.start()
    # An In-Bridge whose peers do not exist (nothing listens on the second port).
    ghost = OutBridge(ctx, "tcp://127.0.0.1:0", None)
    dead_endpoint = ghost.endpoint
    ghost.close()
    inbox = Collector()
    inb = InBridge(
        ctx, {"D1": out.endpoint, "ghost": dead_endpoint}, [topic_to("D2")], inbox, MISSION, None
    )
    inb.start()
    assert out.wait_subscribed([topic_to("D2")], WAIT_S)
    for n in range(200):
        out.send(trig("D1", "D2", n))
    inb.close()  # the subscriber goes away with messages possibly in flight
    for n in range(200):
        out.send(trig("D1", "D2", n))

    began = time.monotonic()
    out.close()
    out.close()  # idempotent
    inb.close()
    assert time.monotonic() - began < 2.0
    assert not out.send(trig("D1", "D2", 0))
    assert not inb.add_subscription(b"all")
    with pytest.raises(RuntimeError):
        out.start()

    # Terminating the context must not hang either (it waits at most the linger).
    term = threading.Thread(target=ctx.term, daemon=True)
    term.start()
    term.join(WAIT_S)
    assert not term.is_alive()


def test_close_before_start_and_context_manager(ctx: zmq.Context[Any]) -> None:
    out = OutBridge(ctx, "tcp://127.0.0.1:0", None)
    inb = InBridge(ctx, {"D1": out.endpoint}, [TOPIC_ALL], Collector(), MISSION, None)
    out.close()
    inb.close()
    assert out.closed and inb.closed
    inbox = Collector()
    with (
        OutBridge(ctx, "tcp://127.0.0.1:0", None) as out2,
        InBridge(ctx, {"GCS": out2.endpoint}, [TOPIC_ALL], inbox, MISSION, None),
    ):
        assert out2.wait_subscribed([TOPIC_ALL], WAIT_S)
        out2.send(Start(MISSION, "GCS"))
        assert inbox.wait_count(1)
    assert out2.closed
    assert not out2.wait_subscribed([TOPIC_ALL], 0.1)


def test_close_from_inside_callback(bridges: Bridges) -> None:
    out = bridges.out()
    closed = threading.Event()
    holder: list[InBridge] = []

    seen: list[Message] = []

    def on_message(msg: Message) -> None:
        seen.append(msg)
        holder[0].close()  # must not deadlock by joining its own thread
        closed.set()

    holder.append(bridges.inb({"D1": out.endpoint}, [TOPIC_ALL], on_message))
    assert out.wait_subscribed([TOPIC_ALL], WAIT_S)
    for n in range(50):
        out.send(Abort(MISSION, "D1", f"x{n}"))
    assert closed.wait(WAIT_S)
    assert holder[0].closed
    # Bounded wait for the thread to finish; after close() nothing more is delivered.
    assert holder[0].wait_ended(WAIT_S)
    assert len(seen) == 1


def test_bad_endpoint_raises_without_leaking(ctx: zmq.Context[Any]) -> None:
    with pytest.raises(zmq.ZMQError):
        InBridge(ctx, {"D1": "tcp://nonsense"}, [TOPIC_ALL], Collector(), MISSION, None)
    with pytest.raises(zmq.ZMQError):
        OutBridge(ctx, "tcp://256.0.0.1:0", None)
    term = threading.Thread(target=ctx.term, daemon=True)
    term.start()
    term.join(WAIT_S)
    assert not term.is_alive()  # no socket left open


def test_a_long_turn_of_the_receive_loop_is_reported_as_a_stall(
    ctx: zmq.Context[Any], bridges: Bridges
) -> None:
    # A consumer that takes long over one message (a burst on a busy machine): the
    # bridge tells how long the turn took, so the link does not count it as the
    # peers' silence.  Quick messages are no stall.
    stalls: list[float] = []
    slow = threading.Event()  # never set: the consumer's wait is its slowness
    inbox = Collector()

    def consumer(msg: Message) -> None:
        if isinstance(msg, Trigger) and msg.iteration[0] == 99:
            slow.wait(0.3)
        inbox(msg)

    out = bridges.out()
    inb = InBridge(
        ctx, {"D1": out.endpoint}, [topic_to("D2")], consumer, MISSION, on_stall=stalls.append
    )
    bridges.made.append(inb)
    inb.start()
    assert out.wait_subscribed([topic_to("D2")], WAIT_S)
    for n in range(5):
        out.send(trig("D1", "D2", n))
    assert inbox.wait_count(5)
    assert stalls == []
    out.send(trig("D1", "D2", 99))
    assert inbox.wait_count(6)
    deadline = time.monotonic() + WAIT_S
    while not stalls and time.monotonic() < deadline:
        slow.wait(0.01)
    assert len(stalls) == 1 and 0.3 <= stalls[0] < WAIT_S


def test_closing_bridges_stops_their_monitors_before_their_sockets(
    ctx: zmq.Context[Any], tmp_path: Any
) -> None:
    # libzmq sends monitor events with a blocking send on the context's I/O thread: a
    # socket closed before its monitor was stopped, whose reader then closed, blocked
    # that thread at its next event, and every other participant of the context with
    # it (drones sharing a context went deaf and mute at a mission's end).
    log = make_logger(tmp_path / "net.log", drone="D1")
    first = OutBridge(ctx, "tcp://127.0.0.1:0", log)
    first.start()
    listener = InBridge(ctx, {"D1": first.endpoint}, [TOPIC_ALL], Collector(), MISSION, log)
    listener.start()
    assert first.wait_subscribed([TOPIC_ALL], WAIT_S)
    first.close()
    listener.close()
    # The context still carries a participant's messages.
    second = OutBridge(ctx, "tcp://127.0.0.1:0", log)
    second.start()
    inbox = Collector()
    inb = InBridge(ctx, {"D2": second.endpoint}, [TOPIC_ALL], inbox, MISSION, log)
    inb.start()
    assert second.wait_subscribed([TOPIC_ALL], WAIT_S)
    second.send(Start(MISSION, "D2"))
    assert inbox.wait_count(1)
    inb.close()
    second.close()
    close_logger(log)
    events = [e["event"] for e in read_log(tmp_path / "net.log")]
    assert "net.monitor.closed_late" not in events
    assert "net.monitor.disable_failed" not in events
