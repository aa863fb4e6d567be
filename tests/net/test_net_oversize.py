"""One oversized message from a key holder: dropped, and the link carries on.

libzmq cuts a connection that sends a frame over ``ZMQ_MAXMSGSIZE`` and, as
that is a protocol error, never reconnects it.  The In-Bridge therefore takes
frames up to :data:`MAX_FRAME_BYTES` (decode drops what exceeds the wire limit,
``oversize``) and reconnects a peer's socket itself when libzmq drops it.
"""

from __future__ import annotations

from pathlib import Path

import msgpack
import pytest

from eamos.logs import close_logger, make_logger, read_log
from eamos.net import wire
from eamos.net.link import Link
from eamos.net.sockets import MAX_FRAME_BYTES

from .link_helpers import MISSION, WAIT_S, Inbox, eventually, network, trig

pytestmark = pytest.mark.timeout(180)


def send_raw(link: Link, size: int) -> None:
    """Publish a Report-shaped payload of about ``size`` bytes on ``to/B``, bypassing encode."""
    body = {"v": wire.WIRE_VERSION, "t": "rep", "m": MISSION, "s": "A", "d": "B"}
    body |= {"rp": {"junk": "x" * size}, "q": 0}
    assert link.out.send_frames([wire.topic_to("B"), msgpack.packb(body)])


@pytest.mark.parametrize(
    ("size", "reason", "reconnects"),
    [(10 << 20, "oversize", False), (MAX_FRAME_BYTES + (4 << 20), None, True)],
    ids=["10MB-dropped", "over-frame-limit-reconnected"],
)
def test_an_oversized_message_leaves_the_link_up(
    tmp_path: Path, size: int, reason: str | None, reconnects: bool
) -> None:
    log = make_logger(tmp_path / "b.log", drone="B")
    try:
        with network(tmp_path) as net:
            net.keys(["A", "B"])
            inbox = Inbox()
            b = net.link("B", ["A"], inbox, secure=True, log=log)
            a = net.link("A", ["B"], secure=True)
            assert a.wait_subscribed([wire.topic_to("B")], WAIT_S)
            a.send(trig("A", "B", 0))
            assert inbox.wait_type(wire.Trigger, 1)
            send_raw(a, size)
            assert b.inb is not None
            inb = b.inb
            if reason is not None:
                assert eventually(lambda: inb.dropped_by_reason.get(reason) == 1)
            else:
                assert eventually(lambda: inb.reconnects >= 1)
            for n in range(1, 21):
                a.send(trig("A", "B", n))
            assert inbox.wait_type(wire.Trigger, 21)
            assert [m.iteration for m in inbox.of(wire.Trigger)] == [(i,) for i in range(21)]
            assert a.flush(WAIT_S)
            assert (inb.reconnects >= 1) is reconnects
    finally:
        close_logger(log)
    events = read_log(tmp_path / "b.log")
    if reason is not None:
        drops = [e for e in events if e["event"] == "net.in.drop"]
        assert drops and drops[0]["reason"] == "oversize" and drops[0]["peer"] == "A"
    else:
        assert any(e["event"] == "net.in.reconnect" and e["peer"] == "A" for e in events)
