"""The bytes on the wire are plain MessagePack: one message of every kind read back with the
``msgpack`` package, key by key, and the same maps packed by ``msgpack`` (as the previous
encoder wrote them, ``v`` and ``t`` first) decoded into the same messages."""

from __future__ import annotations

from typing import Any

import msgpack
import pytest

from eamos.net import wire

M = "survey-1"

#: (message, topic, its payload as a map): the expected maps are written out, not derived.
KINDS: list[tuple[wire.Message, bytes, dict[str, Any]]] = [
    (
        wire.Trigger(M, "D1", "D2", "takeoff", "scan", (0, 3), "done", seq=7, incarnation=11),
        b"to/D2",
        {"d": "D2", "sn": "takeoff", "dn": "scan", "i": [0, 3], "st": "done", "q": 7, "n": 11},
    ),
    (
        wire.Interrupt(M, "GCS", "D3", "loop1", (2,), "suspend", seq=3),
        b"to/D3",
        {"d": "D3", "sc": "loop1", "i": [2], "md": "suspend", "q": 3, "n": 0},
    ),
    (
        wire.TelemetrySample(
            M, "D3", 12.5, 1.0, -2.0, 10.25, 47.39, 8.54, 510.0, 87.5, True, False
        ),
        b"tm/D3",
        {
            "ts": 12.5,
            "x": 1.0,
            "y": -2.0,
            "z": 10.25,
            "lat": 47.39,
            "lon": 8.54,
            "alt": 510.0,
            "bat": 87.5,
            "arm": True,
            "lnd": False,
            "n": 0,
        },
    ),
    (
        wire.Ready(M, "D1", "sha256:abc", seq=1),
        b"to/GCS",
        {"ck": "sha256:abc", "d": "GCS", "q": 1, "n": 0},
    ),
    (wire.Start(M, "GCS", "run-7f3a", seq=1), b"all", {"dp": "run-7f3a", "q": 1, "n": 0}),
    (wire.Abort(M, "GCS", "operator", seq=2), b"all", {"r": "operator", "q": 2, "n": 0}),
    (wire.Complete(M, "GCS", seq=3, incarnation=5), b"all", {"q": 3, "n": 5}),
    (
        wire.Operator(M, "GCS", "hold", "D2", "cli user ann", seq=4),
        b"all",
        {"c": "hold", "tg": "D2", "o": "cli user ann", "q": 4, "n": 0},
    ),
    (
        wire.Amend(M, "GCS", "D2", 1, "prepare", b"{}", seq=5),
        b"to/D2",
        {"d": "D2", "nb": 1, "ph": "prepare", "pg": b"{}", "r": "", "q": 5, "n": 0},
    ),
    (
        wire.Progress(M, "D2", "started", "n4", "goto", {"lat": 1.5, "path": [1, "a", None]}),
        b"to/GCS",
        {
            "st": "started",
            "nd": "n4",
            "a": "goto",
            "dt": {"lat": 1.5, "path": [1, "a", None]},
            "d": "GCS",
            "n": 0,
        },
    ),
    (wire.Resolved(M, "D2", seq=4), b"to/GCS", {"d": "GCS", "q": 4, "n": 0}),
    (
        wire.Report(M, "D2", {"nodes": {"n1": "done"}, "blob": b"\x00\x01"}, seq=5),
        b"to/GCS",
        {"rp": {"nodes": {"n1": "done"}, "blob": b"\x00\x01"}, "d": "GCS", "q": 5, "n": 0},
    ),
    (
        wire.ReportPart(M, "D2", 1, 3, b"\x81\xa1a", seq=6),
        b"to/GCS",
        {"pi": 1, "pn": 3, "pd": b"\x81\xa1a", "d": "GCS", "q": 6, "n": 0},
    ),
    (
        wire.Ack(M, "D2", "D1", 17, 2, nack=True, dest_incarnation=9),
        b"to/D1",
        {"d": "D1", "a": 17, "b": 2, "nk": True, "di": 9, "n": 0},
    ),
    (
        wire.Heartbeat(M, "D1", {"D2": 17}, 4, True, {"D3": 2}, {"GCS": 1}, {"D3": 5, "GCS": 6}),
        b"hb/D1",
        {
            "hs": {"D2": 17},
            "bs": 4,
            "end": True,
            "ak": {"D3": 2},
            "bk": {"GCS": 1},
            "ki": {"D3": 5, "GCS": 6},
            "n": 0,
        },
    ),
]

CODES = {
    wire.Trigger: "trg",
    wire.Interrupt: "int",
    wire.TelemetrySample: "tel",
    wire.Ready: "rdy",
    wire.Start: "sta",
    wire.Abort: "abt",
    wire.Complete: "cmp",
    wire.Operator: "opc",
    wire.Amend: "amd",
    wire.Progress: "prg",
    wire.Resolved: "res",
    wire.Report: "rep",
    wire.ReportPart: "rpp",
    wire.Ack: "ack",
    wire.Heartbeat: "hb",
}


def expected(msg: wire.Message, own: dict[str, Any]) -> dict[str, Any]:
    return {"v": 7, "t": CODES[type(msg)], "m": M, "s": msg.sender, **own}


def test_every_kind_is_here() -> None:
    assert {type(msg) for msg, _, _ in KINDS} == set(wire.MESSAGE_TYPES) == set(CODES)


@pytest.mark.parametrize(("msg", "topic", "own"), KINDS, ids=lambda v: type(v).__name__)
def test_msgpack_reads_every_kind_key_by_key(
    msg: wire.Message, topic: bytes, own: dict[str, Any]
) -> None:
    frames = wire.encode(msg)
    assert frames[0] == topic
    body = msgpack.unpackb(frames[1], raw=False)
    assert body == expected(msg, own)
    # Types as the table says: bin stays bin (bytes), str stays str, numbers keep their kind.
    for key, value in expected(msg, own).items():
        assert type(body[key]) is type(value), key
    # The same bytes msgpack packs for that map in this encoder's key order: only the
    # order of the keys ("t" first, "v" and "n" last) differs from the previous encoder.
    assert frames[1] == msgpack.packb(body, use_bin_type=True)
    assert list(body)[:1] == ["t"] and list(body)[-2:] == ["v", "n"]


@pytest.mark.parametrize(("msg", "topic", "own"), KINDS, ids=lambda v: type(v).__name__)
def test_maps_packed_by_msgpack_in_any_key_order_decode(
    msg: wire.Message, topic: bytes, own: dict[str, Any]
) -> None:
    body = expected(msg, own)  # "v", "t" first: the order the previous encoder wrote
    assert wire.decode([topic, msgpack.packb(body, use_bin_type=True)]) == msg
    backwards = dict(reversed(body.items()))
    assert wire.decode([topic, msgpack.packb(backwards, use_bin_type=True)]) == msg
