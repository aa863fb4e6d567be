"""Reports of any size: a report too large for one message travels in ReportParts.

The parts are split and joined without sockets first (:mod:`eamos.net.reports`),
then over two real links with CURVE, with a part lost on the wire once.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from eamos.net import wire
from eamos.net.reports import SINGLE_REPORT_BYTES, ReportJoiner, report_messages

from .link_helpers import MISSION, WAIT_S, Inbox, Lossy, network

pytestmark = pytest.mark.timeout(180)


def big_report(actions: int) -> dict[str, Any]:
    """A report map shaped like a drone's, with ``actions`` action entries."""
    return {
        "ok": True,
        "actions": [
            {
                "node": f"SEQ_Step#{i}",
                "action": "PauseFor",
                "args": [0.001],
                "iteration": [i],
                "start": 1000.0 + i,
                "end": 1000.5 + i,
                "result": "ok",
            }
            for i in range(actions)
        ],
        "net": {"peers": {f"D{i}": {"sent": i} for i in range(100)}},
    }


def over_the_wire(msg: wire.Message) -> wire.Message:
    frames = wire.encode(msg)
    assert len(frames[1]) <= wire.MAX_PAYLOAD_BYTES
    return wire.decode(frames)


def test_a_small_report_is_one_report_message() -> None:
    report = big_report(10)
    msgs = report_messages(MISSION, "D1", report)
    assert len(msgs) == 1 and isinstance(msgs[0], wire.Report)
    assert msgs[0].report == report and msgs[0].dest == wire.GROUND_STATION


def test_a_report_of_20000_actions_goes_in_parts_and_is_joined_whole() -> None:
    report = big_report(20_000)
    msgs = report_messages(MISSION, "D1", report)
    assert len(msgs) > 1 and all(isinstance(m, wire.ReportPart) for m in msgs)
    assert [m.part for m in msgs] == list(range(len(msgs)))  # type: ignore[union-attr]
    joiner = ReportJoiner()
    joined = [joiner.add(over_the_wire(m)) for m in msgs]  # type: ignore[arg-type]
    assert joined[:-1] == [None] * (len(msgs) - 1)
    last = joined[-1]
    assert isinstance(last, wire.Report) and last.sender == "D1" and last.mission == MISSION
    assert last.report == report
    assert joiner.pending() == {}


def test_parts_out_of_step_are_dropped_and_a_new_first_part_starts_afresh() -> None:
    msgs = report_messages(MISSION, "D1", big_report(20_000))
    assert len(msgs) >= 3
    joiner = ReportJoiner()
    assert joiner.add(msgs[0]) is None  # type: ignore[arg-type]
    with pytest.raises(wire.WireError, match="part 2"):
        joiner.add(msgs[2])  # type: ignore[arg-type]
    assert joiner.pending() == {}
    # A restarted sender (another incarnation) sends its report from part 0 again.
    fresh = [
        wire.ReportPart(
            mission=m.mission,
            sender=m.sender,
            part=m.part,  # type: ignore[union-attr]
            parts=m.parts,  # type: ignore[union-attr]
            data=m.data,  # type: ignore[union-attr]
            incarnation=7,
        )
        for m in msgs
    ]
    assert joiner.add(fresh[0]) is None and joiner.add(fresh[1]) is None
    assert joiner.pending() == {"D1": (2, len(msgs))}
    results = [joiner.add(m) for m in fresh[2:]]
    assert isinstance(results[-1], wire.Report) and results[-1].incarnation == 7


def test_joined_bytes_that_are_not_a_report_map_are_refused() -> None:
    joiner = ReportJoiner()
    junk = wire.ReportPart(mission=MISSION, sender="D1", part=0, parts=1, data=b"\xc1")
    with pytest.raises(wire.WireError, match="not msgpack"):
        joiner.add(junk)
    a_list = wire.ReportPart(mission=MISSION, sender="D1", part=0, parts=1, data=b"\x91\x01")
    with pytest.raises(wire.WireError, match="map"):
        joiner.add(a_list)


@pytest.mark.parametrize(
    ("fields", "match"),
    [
        ({"part": 2, "parts": 2, "data": b""}, "part: 2 of 2"),
        ({"part": 0, "parts": 0, "data": b""}, "parts"),
        ({"part": 0, "parts": wire.MAX_REPORT_PARTS + 1, "data": b""}, "parts"),
        ({"part": 0, "parts": 1, "data": b"x" * (wire.REPORT_PART_BYTES + 1)}, "data"),
        ({"part": 0, "parts": 1, "data": "text"}, "data"),
    ],
)
def test_a_report_part_out_of_its_bounds_is_refused(fields: dict[str, Any], match: str) -> None:
    with pytest.raises(wire.WireError, match=match):  # at the latest where it arrives
        wire.decode(wire.encode(wire.ReportPart(mission=MISSION, sender="D1", **fields)))


def test_a_report_part_with_an_unknown_key_is_refused_on_decode() -> None:
    topic, payload = wire.encode(
        wire.ReportPart(mission=MISSION, sender="D1", part=0, parts=1, data=b"\x80")
    )
    import msgpack

    body = msgpack.unpackb(payload)
    body["zz"] = 1
    with pytest.raises(wire.WireError, match="unexpected keys"):
        wire.decode([topic, msgpack.packb(body)])


def test_the_single_message_threshold_leaves_room_for_the_envelope() -> None:
    # The largest report sent whole still encodes within the wire limit.
    filler = "x" * (SINGLE_REPORT_BYTES - 64)
    msgs = report_messages(MISSION, "D1", {"f": filler})
    assert len(msgs) == 1
    over_the_wire(msgs[0])


def test_a_large_report_crosses_a_secure_link_whole_once_with_a_part_lost(
    tmp_path: Path,
) -> None:
    report = big_report(40_000)
    with network(tmp_path) as net:
        net.keys(["A", "B"])
        inbox = Inbox()
        b = net.link("B", ["A"], inbox, secure=True)
        a = net.link("A", ["B"], secure=True)
        assert a.wait_subscribed([wire.topic_to("B")], WAIT_S)
        lossy = Lossy(a)
        lost: list[int] = []

        def lose_part_one_once(m: wire.Message) -> bool:
            if isinstance(m, wire.ReportPart) and m.part == 1 and not lost:
                lost.append(m.seq)
                return True
            return False

        lossy.drop = lose_part_one_once
        msgs = report_messages(MISSION, "A", report, dest="B")
        assert len(msgs) > 2
        for m in msgs:
            assert a.send(m)
        assert inbox.wait_type(wire.Report, 1)
        assert a.flush(WAIT_S, peers=["B"])  # acknowledged: the sender may exit
        reports = inbox.of(wire.Report)
        assert len(reports) == 1 and reports[0].report == report
        assert not inbox.of(wire.ReportPart)  # the parts never reach the application
        assert lost and lossy.dropped == 1 and a.retransmissions >= 1
        assert b.delivery_errors == 0
