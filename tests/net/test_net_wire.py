"""Wire format: round trips, checks at decode, and rejection of malformed input."""

from __future__ import annotations

from typing import Any

import msgpack
import msgspec
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from msgspec.structs import replace

from eamos.net import (
    TOPIC_ALL,
    WIRE_VERSION,
    Abort,
    Ack,
    Complete,
    Heartbeat,
    Interrupt,
    Message,
    Progress,
    Ready,
    Report,
    ReportPart,
    Resolved,
    Start,
    TelemetrySample,
    Trigger,
    WireError,
    decode,
    encode,
    topic_telemetry,
    topic_to,
    wire,
)
from eamos.net.wire import MAX_PAYLOAD_BYTES, MESSAGE_TYPES

M = "survey-1"

SAMPLES: list[Message] = [
    Trigger(M, "D1", "D2", "takeoff", "scan", (0, 3), "done"),
    Trigger(M, "D1", "D2", "a", "b", (), "skipped"),
    Trigger(M, "D1", "D2", "a", "b", (1,), "failed"),
    Interrupt(M, "D1", "D3", "loop1", (2,), "all"),
    Interrupt(M, "GCS", "D3", "par0", (), "waits"),
    TelemetrySample(M, "D3", 12.5, 1.0, -2.0, 10.25, 47.39, 8.54, 510.0, 87.5, True, False),
    Ready(M, "D1", "sha256:abc"),
    Ready(M, "D1", "x", dest="ground"),
    Start(M, "GCS"),
    Abort(M, "GCS", "operator pressed abort"),
    Complete(M, "GCS"),
    Progress(M, "D2", "started", "n4", "goto", {"lat": 1.5, "path": [1, "a", None], "ok": True}),
    Progress(M, "D2", "done", "n4", "goto"),
    Resolved(M, "D2"),
    Report(M, "D2", {"nodes": {"n1": "done"}, "time_s": 31.2, "blob": b"\x00\x01"}),
    Trigger(M, "D1", "D2", "a", "b", (4,), "done", seq=17),
    Start(M, "GCS", seq=1),
    Ack(M, "D2", "D1", 17, 0),
    Ack(M, "GCS", "D1", 3, 2, nack=True),
    Heartbeat(M, "D1", {"D2": 17, "GCS": 4}, 0),
    Heartbeat(M, "GCS", {}, 3, leaving=True),
    ReportPart(M, "D2", 1, 3, b"\x81\xa1a", seq=5),
    wire.Operator(M, "GCS", "pause", origin="monitor page"),
    wire.Amend(M, "GCS", "D1", 2, "prepare", b'{"format": "eamos-program"}', seq=3),
    wire.Amend(M, "D1", "GCS", 2, "refused", reason="n5 FlyByX(12) has begun"),
]


def test_samples_cover_every_type() -> None:
    assert {type(m) for m in SAMPLES} == set(MESSAGE_TYPES)


@pytest.mark.parametrize("msg", SAMPLES, ids=lambda m: type(m).__name__)
def test_round_trip(msg: Message) -> None:
    frames = encode(msg)
    assert len(frames) == 2
    assert all(isinstance(f, bytes) for f in frames)
    assert decode(frames) == msg
    body = msgpack.unpackb(frames[1], raw=False)
    assert body["v"] == WIRE_VERSION
    assert body["m"] == M
    assert body["s"] == msg.sender


@pytest.mark.parametrize(
    ("msg", "topic"),
    [
        (SAMPLES[0], b"to/D2"),
        (SAMPLES[3], b"to/D3"),
        (SAMPLES[5], b"tm/D3"),
        (SAMPLES[6], b"to/GCS"),
        (SAMPLES[7], b"to/ground"),
        (Start(M, "GCS"), TOPIC_ALL),
        (Abort(M, "D1", "battery"), b"all"),
        (Complete(M, "GCS"), b"all"),
        (Resolved(M, "D1"), b"to/GCS"),
        (Ack(M, "D2", "D1", 1, 0), b"to/D1"),
        (Heartbeat(M, "D2"), b"hb/D2"),
    ],
)
def test_topics(msg: Message, topic: bytes) -> None:
    assert encode(msg)[0] == topic


def test_topic_helpers() -> None:
    assert topic_to("D1") == b"to/D1"
    assert topic_telemetry("D1") == b"tm/D1"
    assert TOPIC_ALL == b"all"


def test_decode_normalises() -> None:
    # The constructor keeps what it is given; decode makes arrays tuples, numbers floats.
    trig = decode(encode(Trigger(M, "D1", "D2", "a", "b", [1, 2], "done")))  # type: ignore[arg-type]
    assert isinstance(trig, Trigger) and trig.iteration == (1, 2)
    hash(trig)  # hashable: usable as a dict key by the runtime
    tel = TelemetrySample(M, "D1", 1, 2, 3, 4, 5, 6, 7, 8, False, True)
    back = decode(encode(tel))
    assert isinstance(back, TelemetrySample) and isinstance(back.time_s, float)
    assert back == tel


@pytest.mark.parametrize(
    "make",
    [
        lambda: Trigger(M, "D1", "D2", "a", "b", (), "ok"),  # type: ignore[arg-type]  # deliberately invalid
        lambda: Trigger(M, "D1", "D2", "a", "b", (True,), "done"),
        lambda: Trigger(M, "D1", "", "a", "b", (), "done"),
        lambda: Trigger(M, "D1", "D/2", "a", "b", (), "done"),
        lambda: Trigger(1, "D1", "D2", "a", "b", (), "done"),  # type: ignore[arg-type]  # deliberately invalid
        lambda: Interrupt(M, "D1", "D2", "s", (), "some"),  # type: ignore[arg-type]  # deliberately invalid
        lambda: TelemetrySample(M, "D1", 0, 0, 0, 0, 0, 0, 0, 0, 1, False),  # type: ignore[arg-type]  # deliberately invalid
        lambda: TelemetrySample(M, "D1", True, 0, 0, 0, 0, 0, 0, 0, True, False),
        lambda: Progress(M, "D1", "s", "n", "a", {1: "x"}),  # type: ignore[dict-item]  # deliberately invalid
        lambda: Progress(M, "D1", "s", "n", "a", {"x": object()}),
        lambda: Report(M, "D1", ["not", "a", "map"]),  # type: ignore[arg-type]  # deliberately invalid
        lambda: Trigger(M, "D1", "D2", "a", "b", (), "done", seq=-1),
        lambda: Trigger(M, "D1", "D2", "a", "b", (), "done", seq=True),
        lambda: Trigger(M, "D1", "D2", "a", "b", (), "done", seq=1.0),  # type: ignore[arg-type]  # deliberately invalid
        lambda: Trigger(M, "D1", "D2", "a", "b", (), "done", seq=2**63),
        lambda: Ack(M, "D1", "D2", 1, 0, nack=1),  # type: ignore[arg-type]  # deliberately invalid
        lambda: Heartbeat(M, "D1", {"D2": -1}),
        lambda: Heartbeat(M, "D1", {"D/2": 1}),
        lambda: Heartbeat(M, "D1", {1: 1}),  # type: ignore[dict-item]  # deliberately invalid
    ],
)
def test_what_a_bad_construction_makes_is_refused_where_it_arrives(make: Any) -> None:
    # Constructors check nothing (this process's own values); decode checks everything
    # (encode already refuses what MessagePack cannot carry).
    with pytest.raises(WireError):
        decode(encode(make()))


def test_encode_rejects_non_messages() -> None:
    with pytest.raises(WireError):
        encode("hello")  # type: ignore[arg-type]


def test_encode_rejects_oversize() -> None:
    with pytest.raises(WireError, match="exceeds"):
        encode(Report(M, "D1", {"x": "a" * MAX_PAYLOAD_BYTES}))


# -- malformed input, table-driven ------------------------------------------

GOOD: dict[str, Any] = msgpack.unpackb(encode(SAMPLES[0])[1], raw=False)


def body(**changes: Any) -> bytes:
    """The good Trigger payload with keys changed (value ``...`` deletes the key)."""
    data = {k: v for k, v in GOOD.items() if changes.get(k) is not ...}
    data.update({k: v for k, v in changes.items() if v is not ...})
    return msgpack.packb(data, use_bin_type=True)


def deep(depth: int) -> Any:
    value: Any = 1
    for _ in range(depth):
        value = [value]
    return value


def progress_payload(detail: Any) -> bytes:
    data = msgpack.unpackb(encode(SAMPLES[12])[1], raw=False)
    data["dt"] = detail
    return msgpack.packb(data, use_bin_type=True)


TO = b"to/D2"
MALFORMED: list[tuple[str, Any, str]] = [
    ("no frames", [], "2 frames"),
    ("one frame", [TO], "2 frames"),
    ("three frames", [TO, body(), b""], "2 frames"),
    ("not a list", b"to/D2", "2 frames"),
    ("str frames", ["to/D2", "x"], "bytes"),
    ("empty payload", [TO, b""], "msgpack"),
    ("reserved byte", [TO, b"\xc1"], "msgpack"),
    ("truncated", [TO, body()[:-3]], "msgpack"),
    ("trailing data", [TO, body() + b"\x01"], "msgpack"),
    ("bad utf-8", [TO, b"\x81\xa1v\xa2\xff\xfe"], "msgpack"),
    ("int map key", [TO, b"\x81\x01\x01"], "msgpack"),
    ("huge declared array", [TO, b"\xdd\xff\xff\xff\xff"], "msgpack"),
    ("ext type", [TO, b"\xd6\xff\x00\x00\x00\x00"], "msgpack"),
    ("array payload", [TO, msgpack.packb([1, "trg"])], "map"),
    ("missing version", [TO, body(v=...)], "version"),
    ("version 1", [TO, body(v=1)], "version"),
    ("version 2", [TO, body(v=2)], "version"),
    ("version 3", [TO, body(v=3)], "version"),
    ("version 4", [TO, body(v=4)], "version"),
    ("version 5", [TO, body(v=5)], "version"),
    ("version 6", [TO, body(v=6)], "version"),
    ("version 8", [TO, body(v=8)], "version"),
    ("version true", [TO, body(v=True)], "version"),
    ("version float", [TO, body(v=3.0)], "version"),
    ("version str", [TO, body(v="2")], "version"),
    ("seq negative", [TO, body(q=-1)], "seq"),
    ("seq float", [TO, body(q=1.0)], "seq"),
    ("seq missing", [TO, body(q=...)], "missing"),
    ("missing type", [TO, body(t=...)], "type"),
    ("unknown type", [TO, body(t="zzz")], "type"),
    ("int type", [TO, body(t=3)], "type"),
    ("missing field", [TO, body(sn=...)], "missing"),
    ("extra field", [TO, body(zz=1)], "unexpected"),
    ("mission not str", [TO, body(m=5)], "mission"),
    ("sender empty", [TO, body(s="")], "sender"),
    ("iteration str", [TO, body(i="0")], "iteration"),
    ("iteration bool", [TO, body(i=[True])], "iteration"),
    ("iteration float", [TO, body(i=[1.5])], "iteration"),
    ("iteration map", [TO, body(i={"a": 1})], "iteration"),
    ("status unknown", [TO, body(st="maybe")], "status"),
    ("status list", [TO, body(st=["done"])], "status"),
    ("topic other drone", [b"to/D3", body()], "topic"),
    ("topic broadcast", [b"all", body()], "topic"),
    ("topic empty", [b"", body()], "topic"),
    ("start addressed", [TO, encode(Start(M, "GCS"))[1]], "topic"),
    ("telemetry wrong drone", [b"tm/D1", encode(SAMPLES[5])[1]], "topic"),
    ("oversize topic", [b"to/" + b"x" * 300, body()], "topic"),
    ("oversize payload", [TO, b"\x00" * (MAX_PAYLOAD_BYTES + 1)], "payload"),
    ("detail not map", [b"to/GCS", progress_payload([1, 2])], "detail"),
    ("detail too deep", [b"to/GCS", progress_payload({"x": deep(40)})], "deeper"),
    ("detail ext", [b"to/GCS", progress_payload({"x": msgpack.ExtType(5, b"ab")})], "msgpack"),
]


@pytest.mark.parametrize(
    ("frames", "why"), [c[1:] for c in MALFORMED], ids=[c[0] for c in MALFORMED]
)
def test_decode_rejects(frames: Any, why: str) -> None:
    with pytest.raises(WireError, match=why):
        decode(frames)


def test_version_errors_say_so() -> None:
    """Receivers log "version" drops (an older or newer program) apart from garbage."""
    with pytest.raises(WireError) as info:
        decode([TO, body(v=1)])
    assert info.value.reason == "version"
    with pytest.raises(WireError) as info:
        decode([TO, body(sn=...)])
    assert info.value.reason == "malformed"


def test_sequence_numbers_default_to_zero_and_survive() -> None:
    assert Trigger(M, "D1", "D2", "a", "b", (), "done").seq == 0
    assert Ready(M, "D1", "x").seq == 0
    msg = decode(encode(Report(M, "D1", {}, seq=2**62)))
    assert isinstance(msg, Report) and msg.seq == 2**62


def test_bytes_keys_are_not_str_keys() -> None:
    data = {(k.encode() if k == "v" else k): v for k, v in GOOD.items()}
    with pytest.raises(WireError, match="version"):
        decode([TO, msgpack.packb(data, use_bin_type=True)])


def test_telemetry_number_fields_reject_bool_and_str() -> None:
    data = msgpack.unpackb(encode(SAMPLES[5])[1], raw=False)
    for key, bad in [("x", True), ("lat", "47"), ("arm", 1), ("lnd", None)]:
        changed = dict(data, **{key: bad})
        with pytest.raises(WireError):
            decode([b"tm/D3", msgpack.packb(changed)])
    ints = dict(data, x=3, ts=10)  # other implementations may send integral floats as ints
    msg = decode([b"tm/D3", msgpack.packb(ints)])
    assert isinstance(msg, TelemetrySample)
    assert msg.x_m == 3.0


# -- fuzzing: anything malformed raises WireError and nothing else -------------

KNOWN_KEYS = sorted({f.encode_name for cls in MESSAGE_TYPES for f in msgspec.structs.fields(cls)})
plain = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(min_value=-(2**63), max_value=2**64 - 1)
    | st.floats()
    | st.text(max_size=8)
    | st.binary(max_size=8),
    lambda children: (
        st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=4), children, max_size=4)
    ),
    max_leaves=12,
)
payload_maps = st.dictionaries(
    st.sampled_from(KNOWN_KEYS) | st.text(max_size=3),
    plain,
    max_size=12,
).map(lambda d: {"v": WIRE_VERSION, **d})
topics = st.sampled_from([b"to/D2", b"to/GCS", b"tm/D3", b"all", b""]) | st.binary(max_size=12)


def check_decode(frames: Any) -> None:
    try:
        msg = decode(frames)
    except WireError:
        return
    # Anything accepted must be a proper message that survives another round trip
    # (compared as bytes: NaN floats are unequal to themselves).
    assert isinstance(msg, MESSAGE_TYPES)
    assert encode(decode(encode(msg))) == encode(msg)


FUZZ = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@FUZZ
@given(st.lists(st.binary(max_size=64), max_size=4))
def test_fuzz_random_frames(frames: list[bytes]) -> None:
    check_decode(frames)


@FUZZ
@given(topics, st.binary(max_size=256))
def test_fuzz_random_payload_bytes(topic: bytes, payload: bytes) -> None:
    check_decode([topic, payload])


@FUZZ
@given(topics, st.sampled_from([str(c.__struct_config__.tag) for c in MESSAGE_TYPES]), payload_maps)
def test_fuzz_random_maps(topic: bytes, code: str, data: dict[str, Any]) -> None:
    check_decode([topic, msgpack.packb({**data, "t": code}, use_bin_type=True)])


@FUZZ
@given(
    st.sampled_from(SAMPLES),
    st.lists(st.tuples(st.integers(min_value=0), st.integers(0, 255)), min_size=1, max_size=4),
)
def test_fuzz_mutated_good_messages(msg: Message, flips: list[tuple[int, int]]) -> None:
    topic, payload = encode(msg)
    mutated = bytearray(payload)
    for pos, value in flips:
        mutated[pos % len(mutated)] = value
    check_decode([topic, bytes(mutated)])


@pytest.mark.parametrize("cls", MESSAGE_TYPES, ids=lambda c: c.__name__)
def test_no_two_fields_share_a_wire_key(cls: Any) -> None:
    """One key per field: a shared key silently overwrote the incarnation (or the node)."""
    keys = [f.encode_name for f in msgspec.structs.fields(cls)]
    assert len(keys) == len(set(keys)) and "t" not in keys, keys


def test_progress_keeps_its_node_and_its_sender_incarnation() -> None:
    msg = Progress(M, "D2", "ok", "n4", "Arm", incarnation=1234567)
    back = decode(encode(msg))
    assert back == msg and back.node == "n4" and back.incarnation == 1234567


@pytest.mark.parametrize("msg", SAMPLES, ids=lambda m: type(m).__name__)
def test_replace_stamps_what_it_changes_and_decode_checks_it(msg: Message) -> None:
    """The session stamps seq and incarnation with msgspec's replace; the receiver checks."""
    stamped = replace(msg, incarnation=99)
    assert stamped.incarnation == 99 and stamped.sender == msg.sender
    assert decode(encode(stamped)) == stamped
    with pytest.raises(WireError, match="incarnation"):
        decode(encode(replace(msg, incarnation=-1)))
    with pytest.raises(TypeError, match="no field"):
        replace(msg, nonsense=1)


def test_replace_keeps_the_check_across_fields() -> None:
    part = ReportPart(M, "D1", 1, 2, b"x")
    with pytest.raises(WireError, match="of 2 parts"):
        replace(part, part=2)
    bad = msgpack.unpackb(encode(part)[1]) | {"pi": 2}
    with pytest.raises(WireError, match="of 2 parts"):
        decode([b"to/GCS", msgpack.packb(bad)])


def test_decoded_equals_constructed() -> None:
    """decode builds messages through msgspec: they must be the same values."""
    for msg in SAMPLES:
        back = decode(encode(msg))
        assert type(back) is type(msg) and back == msg
        assert msgspec.structs.asdict(back) == msgspec.structs.asdict(msg)
