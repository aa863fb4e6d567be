"""A receiver that fell behind decodes only each drone's newest telemetry sample.

Control messages waiting among the samples are all delivered, in order; the
samples superseded by a newer one of the same drone are skipped undecoded.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import pytest

from eamos.net import wire

from .link_helpers import WAIT_S, Inbox, eventually, network, sample, trig

pytestmark = pytest.mark.timeout(120)


def test_a_backlog_of_samples_is_cut_to_the_newest_and_triggers_all_arrive(
    tmp_path: Path,
) -> None:
    release = threading.Event()
    blocked = threading.Event()
    inbox = Inbox()

    def on_message(msg: Any) -> None:
        if isinstance(msg, wire.Trigger) and not blocked.is_set():
            blocked.set()
            release.wait(WAIT_S)  # the receive thread is busy: a backlog builds up
        inbox(msg)

    with network(tmp_path) as net:
        b = net.link("B", ["A"], on_message, topics=(wire.topic_telemetry("A"),))
        a = net.link("A", ["B"])
        assert a.wait_subscribed([wire.topic_to("B"), wire.topic_telemetry("A")], WAIT_S)
        assert a.send(trig("A", "B", 0))
        assert blocked.wait(WAIT_S)
        out = a.out
        assert out is not None
        for i in range(1, 51):
            out.send(sample("A", float(i), x=float(i)))  # straight to the socket, unpaced
            if i == 25:
                assert a.send(trig("A", "B", 1))
        assert a.send(trig("A", "B", 2))
        assert a.flush(0.0) is False  # the triggers wait for B's acks
        release.set()
        assert inbox.wait_type(wire.Trigger, 3)
        assert eventually(lambda: any(s.time_s == 50.0 for s in inbox.of(wire.TelemetrySample)))
        triggers = [m.iteration for m in inbox.of(wire.Trigger)]
        samples = inbox.of(wire.TelemetrySample)
        assert triggers == [(0,), (1,), (2,)]  # every control message, once, in order
        assert len(samples) < 50 and samples[-1].time_s == 50.0
        assert b.inb is not None and b.inb.superseded >= 1
        assert b.stats()["telemetry_superseded"] == b.inb.superseded


def test_latest_telemetry_keeps_each_drones_newest_sample_and_everything_else() -> None:
    from eamos.net.in_bridge import latest_telemetry

    batch = [
        [b"tm/A", b"1"],
        [b"to/B", b"t1"],
        [b"tm/C", b"1"],
        [b"tm/A", b"2"],
        [b"hb/A", b"h"],
        [b"tm/A", b"3"],
    ]
    kept, skipped = latest_telemetry(batch)
    assert kept == [[b"to/B", b"t1"], [b"tm/C", b"1"], [b"hb/A", b"h"], [b"tm/A", b"3"]]
    assert skipped == 2
    assert latest_telemetry([]) == ([], 0)
    assert latest_telemetry([[b"tm/A", b"1"]]) == ([[b"tm/A", b"1"]], 0)
    assert latest_telemetry([[b"tm/A", b"1"], [b"tm/A", b"2"]]) == ([[b"tm/A", b"2"]], 1)
