"""No message deafens a receiver: every receive loop survives whatever one message raises.

A real In-Bridge on CURVE sockets (keys from ``eamos keys``) is fed, by a key holder's
Out-Bridge, random and adversarial frames: after each, its receive thread still runs
and the next 20 triggers arrive, in order.  Faults the wire format no longer lets in
(the decoder's ``RecursionError`` of issue 28, a consumer's ``SystemExit``) are
injected where they would arise, to show the loop itself holds whatever the cause.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgpack
import pytest
import zmq
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from eamos.logs import close_logger, make_logger, read_log
from eamos.net import InBridge, OutBridge, wire
from eamos.net import in_bridge as in_bridge_module
from eamos.net.keys import FleetAuthenticator, FleetKeys, create_fleet_keys

from .link_helpers import MISSION, WAIT_S, Inbox, Lossy, eventually, fail_one_tick, network, trig

pytestmark = pytest.mark.timeout(600)

TOPICS = [wire.topic_to("B"), wire.TOPIC_ALL]


@dataclass
class Pair:
    """A's Out-Bridge (a key holder) and B's In-Bridge listening to it, both on CURVE."""

    out: OutBridge
    inb: InBridge
    inbox: Inbox
    log_path: Path
    sent: int = 0  # triggers sent so far: the next one's iteration

    def next_20_triggers_arrive(self) -> bool:
        """Send 20 triggers; True when all arrived after what was sent before, in order."""
        first = self.sent
        self.sent += 20
        for n in range(first, first + 20):
            assert self.out.send(trig("A", "B", n))

        def arrived(items: list[Any]) -> bool:
            # Only this helper's triggers (node "a"): a drawn valid trigger arrives too.
            got = [
                m.iteration[0] for m in items if isinstance(m, wire.Trigger) and m.src_node == "a"
            ]
            return got[-20:] == list(range(first, first + 20))

        return self.inbox.wait(arrived, WAIT_S)


@contextmanager
def curve_pair(tmp_path: Path, on_message: Callable[[Any], None] | None = None) -> Iterator[Pair]:
    keys_dir = create_fleet_keys(tmp_path / "keys", ["A", "B"], force=True)
    ctx_a: zmq.Context[Any] = zmq.Context()
    ctx_b: zmq.Context[Any] = zmq.Context()
    log_path = tmp_path / "b.log"
    log = make_logger(log_path, drone="B")
    keys_a = FleetKeys.load(keys_dir / "A", "A")
    keys_b = FleetKeys.load(keys_dir / "B", "B")
    auth = FleetAuthenticator(ctx_a, keys_a)
    out = OutBridge(ctx_a, "tcp://127.0.0.1:0", curve=keys_a)
    out.start()
    inbox = Inbox()
    inb = InBridge(
        ctx_b,
        {"A": out.endpoint},
        TOPICS,
        on_message or inbox,
        MISSION,
        log,
        curve=keys_b,
        check_sender=True,
    )
    inb.start()
    try:
        assert out.wait_subscribed(TOPICS, WAIT_S)
        yield Pair(out, inb, inbox, log_path)
    finally:
        inb.close()
        out.close()
        auth.stop()
        close_logger(log)
        ctx_a.destroy(linger=0)
        ctx_b.destroy(linger=0)


# -- random and adversarial frames (the property) ------------------------------------------

_SCALARS = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**63), max_value=2**64 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=40),
    st.binary(max_size=40),
)
_PLAIN = st.recursive(
    _SCALARS,
    lambda inner: (
        st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=8), inner, max_size=5)
    ),
    max_leaves=30,
)
#: Every message type's code, a few wrong ones, and the keys a payload may hold.
_CODES = st.sampled_from(
    ["trg", "rdy", "sta", "abt", "cpl", "rep", "rpp", "hb", "ack", "tm", "prg", "?", ""]
)
_KEYS = st.sampled_from(["v", "t", "m", "s", "d", "q", "a", "r", "sn", "dn", "it", "st", "ck", "x"])


def _nested(depth: int) -> bytes:
    """A payload nesting one-element arrays ``depth`` deep inside a trigger-like map."""
    return b"\x82\xa1v\x04\xa1t" + b"\x91" * depth + b"\x01"


ADVERSARIAL: list[bytes] = [
    _nested(1000),
    _nested(100_000),
    b"\x81\xa1v" + b"\x81\xa1x" * 5000 + b"\x01",  # maps nested 5 000 deep
    b"\xdc\xff\xff",  # an array claiming 65 535 items, none there
    b"\xdf\xff\xff\xff\xff",  # a map claiming 4 billion pairs
    b"\xdb\xff\xff\xff\xff",  # a string claiming 4 GiB
    b"\xc1",  # a byte msgpack never uses
    b"\xd4\x01\x00",  # an extension type
    b"\x81\x01\x02",  # an int key
    b"\x81\x91\x01\x02",  # an array as key (unhashable)
    b"",
    msgpack.packb({"v": wire.WIRE_VERSION, "t": "trg", "m": MISSION, "s": "B", "d": "B"}),
    msgpack.packb({"v": True, "t": "trg"}),
    msgpack.packb({"v": wire.WIRE_VERSION, "t": "trg", "m": "other-mission"}),
]


@st.composite
def frames(draw: st.DrawFn) -> list[bytes]:
    """One multipart message a key holder might send: random, msgpack-shaped, or known-bad."""
    topic = draw(
        st.sampled_from([*TOPICS, b"to/B/x", b"to/", b"\xff\xfe", b""]) | st.binary(max_size=80)
    )
    kind = draw(st.sampled_from(["bytes", "plain", "shaped", "valid", "adversarial"]))
    if kind == "bytes":
        payload = draw(st.binary(max_size=2000))
    elif kind == "plain":
        payload = msgpack.packb(draw(_PLAIN), use_bin_type=True)
    elif kind == "shaped":
        body = draw(st.dictionaries(_KEYS, _PLAIN, max_size=10))
        body.setdefault("v", wire.WIRE_VERSION)
        body.setdefault("t", draw(_CODES))
        body.setdefault("m", draw(st.sampled_from([MISSION, "x"])))
        body.setdefault("s", draw(st.sampled_from(["A", "B", "GCS", ""])))
        payload = msgpack.packb(body, use_bin_type=True)
    elif kind == "valid":
        # Real messages with field values at their edges, on a right or wrong topic.
        msg = wire.Trigger(
            draw(st.sampled_from([MISSION, "other"])),
            draw(st.sampled_from(["A", "B", "Z"])),
            "B",
            "h" + draw(st.text(max_size=20)),
            "h" + draw(st.text(max_size=20)),
            tuple(draw(st.lists(st.integers(0, 2**31), max_size=4))),
            draw(st.sampled_from(["done", "failed"])),
        )
        topic, payload = wire.encode(msg)
        topic = draw(st.sampled_from([topic, wire.TOPIC_ALL]))
    else:
        payload = draw(st.sampled_from(ADVERSARIAL))
    count = draw(st.sampled_from([2, 2, 2, 1, 3]))
    return [topic, payload, b"extra"][:count] if count != 1 else [topic]


def test_random_and_adversarial_frames_never_stop_the_receive_thread(tmp_path: Path) -> None:
    with curve_pair(tmp_path) as pair:
        assert pair.next_20_triggers_arrive()

        @settings(
            max_examples=120,
            deadline=None,
            database=None,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
        )
        @given(frames())
        def after_any_frame(sent: list[bytes]) -> None:
            assert pair.out.send_frames(sent)
            assert pair.next_20_triggers_arrive(), f"triggers lost after {sent[:2]!r}"
            assert pair.inb.alive

        after_any_frame()
        for payload in ADVERSARIAL:  # each known-bad payload at least once, whatever was drawn
            assert pair.out.send_frames([wire.topic_to("B"), payload])
            assert pair.next_20_triggers_arrive()
        assert pair.inb.alive
        assert pair.inb.message_errors == 0  # each was a counted drop, nothing unexpected
        assert pair.inb.dropped > 0


# -- any exception of one message: injected where it would arise ---------------------------

POISON = b"\x82\xa1v\x04\xa1t\xa1!"  # a marker payload the injected faults react to


@pytest.mark.parametrize(
    "error",
    [RecursionError, MemoryError, KeyError, UnicodeDecodeError, SystemExit, KeyboardInterrupt],
)
def test_any_exception_of_the_decoder_is_logged_once_counted_and_the_thread_goes_on(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, error: type[BaseException]
) -> None:
    real = in_bridge_module.decode

    def decode(frames: list[bytes]) -> wire.Message:
        if frames[1:] == [POISON]:
            if error is UnicodeDecodeError:
                raise UnicodeDecodeError("utf-8", b"\xff", 0, 1, "a decoder's bug")
            raise error("a decoder's bug")
        return real(frames)

    monkeypatch.setattr(in_bridge_module, "decode", decode)
    with curve_pair(tmp_path) as pair:
        assert pair.next_20_triggers_arrive()
        for _ in range(3):
            assert pair.out.send_frames([wire.topic_to("B"), POISON])
            assert pair.next_20_triggers_arrive()
        assert pair.inb.alive
        assert pair.inb.message_errors == 3
    errors = [e for e in read_log(pair.log_path) if e["event"] == "net.in.message_error"]
    assert len(errors) == 3  # once per message
    assert errors[0]["peer"] == "A" and error.__name__ in errors[0]["error"]
    assert errors[0]["topic"] == "to/B" and "Traceback" in errors[0]["exception"]


@pytest.mark.parametrize("error", [SystemExit, KeyboardInterrupt, RecursionError, ValueError])
def test_a_consumer_raising_anything_on_one_message_does_not_deafen_the_bridge(
    tmp_path: Path, error: type[BaseException]
) -> None:
    inbox = Inbox()
    failed = threading.Event()

    def consumer(msg: Any) -> None:
        if isinstance(msg, wire.Trigger) and msg.iteration == (5,) and not failed.is_set():
            failed.set()
            raise error("a consumer's bug")
        inbox(msg)

    with curve_pair(tmp_path, consumer) as pair:
        pair.inbox = inbox
        for n in range(10):
            assert pair.out.send(trig("A", "B", n))
        assert inbox.wait_type(wire.Trigger, 9)
        assert pair.inb.alive and pair.inb.callback_errors == 1
        pair.sent = 100
        assert pair.next_20_triggers_arrive()
    events = [e for e in read_log(pair.log_path) if e["event"] == "net.in.callback_error"]
    assert len(events) == 1 and error.__name__ in events[0]["error"]


def test_the_link_timer_survives_a_failing_tick_and_still_retransmits(tmp_path: Path) -> None:
    """A tick that raises once: the timer logs it, waits a heartbeat, and goes on (a lost
    trigger is retransmitted, which only the timer does)."""
    log_path = tmp_path / "a.log"
    log = make_logger(log_path, drone="A")
    try:
        with network(tmp_path) as net:
            inbox = Inbox()
            b = net.link("B", ["A"], inbox)
            a = net.link("A", ["B"], log=log)
            assert a.wait_subscribed([wire.topic_to("B")], WAIT_S)
            fail_one_tick(a)
            assert eventually(lambda: a.timer_errors == 1)
            lossy = Lossy(a)
            lost = {1}

            def drop_once(m: object) -> bool:  # the first Trigger of iteration 1, once
                if isinstance(m, wire.Trigger) and m.iteration == (1,) and lost:
                    lost.clear()
                    return True
                return False

            lossy.drop = drop_once
            for n in range(3):
                a.send(trig("A", "B", n))
            assert inbox.wait_type(wire.Trigger, 3)  # the lost one came again
            assert [m.iteration for m in inbox.of(wire.Trigger)] == [(0,), (1,), (2,)]
            assert lossy.dropped == 1 and a.retransmissions >= 1
            assert a.stats()["timer_errors"] == 1
            assert b.inb is not None and b.inb.alive
    finally:
        close_logger(log)
    errors = [e for e in read_log(log_path) if e["event"] == "net.link.timer_error"]
    assert len(errors) == 1 and "a tick's bug" in errors[0]["error"]
