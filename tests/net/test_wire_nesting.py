"""A message nested deep, anywhere, is refused with WireError: nothing in decode recurses on it.

One 1 KB payload of nested arrays (issue 28, item 2) used to raise RecursionError from the
repr in decode's error text and kill the receive thread.  msgpack's unpacker keeps its own
stack, the plain-data check walks with a list, and error texts show no nested value.
"""

from __future__ import annotations

import inspect
import struct
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import msgpack
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from eamos.net import wire

M = "m"
PROGRESS = msgpack.unpackb(
    wire.encode(wire.Progress(M, "D1", "ok", "n1", "Arm()", {"at": 1.5}))[1], raw=False
)
HEARTBEAT = msgpack.unpackb(wire.encode(wire.Heartbeat(M, "D1", {"D2": 3}))[1], raw=False)
TRIGGER = msgpack.unpackb(
    wire.encode(wire.Trigger(M, "D1", "D2", "a", "b", (1,), "done"))[1], raw=False
)
TOPICS = {"prg": b"to/GCS", "hb": b"hb/D1", "trg": b"to/D2"}

#: One level of nesting each: an array of one, a map of one, and their 16- and 32-bit forms.
OPENERS = [b"\x91", b"\x81\xa1k", b"\xdc\x00\x01", b"\xde\x00\x01\xa1k", b"\xdd\x00\x00\x00\x01"]


def nested(opener: bytes, depth: int, leaf: bytes = b"\x01") -> bytes:
    return opener * depth + leaf


def splice(base: dict[str, Any], key: str, value: bytes, first: bool) -> bytes:
    """``base`` packed as a map with ``key``'s value replaced by the raw bytes ``value``."""
    items = [msgpack.packb(k) + msgpack.packb(v) for k, v in base.items() if k != key]
    mine = msgpack.packb(key) + value
    items = [mine, *items] if first else [*items, mine]
    return b"\xde" + struct.pack(">H", len(items)) + b"".join(items)


def outcome(frames: list[bytes]) -> wire.Message | wire.WireError:
    """What decode makes of ``frames``: a message or a WireError, and nothing else."""
    try:
        return wire.decode(frames)
    except wire.WireError as exc:
        assert len(str(exc)) < 1000, "an error text must not grow with the input"
        return exc


@contextmanager
def little_stack(frames: int = 120) -> Iterator[None]:
    """Python's recursion limit set ``frames`` above the current depth, then restored."""
    old = sys.getrecursionlimit()
    sys.setrecursionlimit(len(inspect.stack(0)) + frames)
    try:
        yield
    finally:
        sys.setrecursionlimit(old)


def test_the_reported_payload_is_refused() -> None:
    # Issue 28's payload (wire version 4 then), in today's version: refused as malformed.
    frames = [
        b"all",
        b"\x82\xa1v" + bytes([wire.WIRE_VERSION]) + b"\xa1t" + b"\x91" * 1000 + b"\x01",
    ]
    got = outcome(frames)
    assert isinstance(got, wire.WireError) and got.reason == "malformed"
    assert "unknown message type of type list" in str(got)


ADVERSARIAL = [
    pytest.param(base, key, opener, depth, first, id=f"{code}-{key}-{opener.hex()}-{depth}-{first}")
    for code, base in (("prg", PROGRESS), ("hb", HEARTBEAT), ("trg", TRIGGER))
    for key in [
        "t",
        "v",
        "zz",
        *(["dt"] if code == "prg" else []),
        *(["hs"] if code == "hb" else []),
    ]
    + (["i"] if code == "trg" else [])
    for opener in OPENERS[:2]
    for depth in (33, 1000, 5000)
    for first in (True, False)
]


@pytest.mark.parametrize(("base", "key", "opener", "depth", "first"), ADVERSARIAL)
def test_deep_values_anywhere_are_refused_with_little_stack(
    base: dict[str, Any], key: str, opener: bytes, depth: int, first: bool
) -> None:
    frames = [TOPICS[base["t"]], splice(base, key, nested(opener, depth), first)]
    with little_stack():
        got = outcome(frames)
    assert isinstance(got, wire.WireError)


@pytest.mark.parametrize("opener", OPENERS)
def test_a_whole_payload_of_nesting_is_refused(opener: bytes) -> None:
    depth = (wire.MAX_PAYLOAD_BYTES - 8) // len(opener)
    with little_stack():
        got = outcome([b"to/GCS", nested(opener, depth)])
    assert isinstance(got, wire.WireError) and got.reason == "malformed"


@pytest.mark.parametrize("key", ["dt", "zz", "t"])
def test_error_texts_stay_short_whatever_the_input(key: str) -> None:
    huge = msgpack.packb("x" * (wire.MAX_PAYLOAD_BYTES // 2))
    for value in (huge, msgpack.packb([["y" * 1000] * 100])):
        got = outcome([b"to/GCS", splice(PROGRESS, key, value, first=True)])
        assert isinstance(got, wire.WireError)
    keys = {f"key{i}" * 50: 1 for i in range(2000)}
    assert isinstance(outcome([b"to/GCS", msgpack.packb(PROGRESS | keys)]), wire.WireError)


# -- the property: decode returns a message or raises WireError, whatever arrives ----------

scalars: st.SearchStrategy[Any] = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**63), 2**64 - 1),
    st.floats(),
    st.text(max_size=6),
    st.binary(max_size=6),
)
keys = st.sampled_from(["t", "v", "m", "s", "n", "dt", "rp", "hs", "i", "q", "zz"])


@st.composite
def adversarial_payloads(draw: st.DrawFn) -> tuple[bytes, bytes]:
    code = draw(st.sampled_from(sorted(TOPICS)))
    base = {"prg": PROGRESS, "hb": HEARTBEAT, "trg": TRIGGER}[code]
    base = dict(base)
    for key in draw(st.lists(keys, max_size=3)):  # a few keys changed, removed or added
        if draw(st.booleans()):
            base.pop(key, None)
        else:
            base[key] = draw(scalars)
    deep = nested(
        b"".join(draw(st.lists(st.sampled_from(OPENERS), min_size=1, max_size=3))),
        draw(st.integers(0, 3000)),
        msgpack.packb(draw(scalars)),
    )
    payload = splice(base, draw(keys), deep, first=draw(st.booleans()))
    if draw(st.booleans()):  # and cut, or with bytes flipped
        cut = draw(st.integers(0, len(payload)))
        payload = payload[:cut] + draw(st.binary(max_size=8)) + payload[cut + 1 :]
    topic = draw(st.sampled_from([TOPICS[code], b"to/GCS", b"all"]))
    return topic, payload


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(adversarial_payloads())
def test_decode_returns_a_message_or_raises_wire_error(frames: tuple[bytes, bytes]) -> None:
    got = outcome(list(frames))
    if not isinstance(got, wire.WireError):
        assert isinstance(got, wire.MESSAGE_TYPES)
        # Compared as bytes: NaN floats are unequal to themselves.
        assert wire.encode(wire.decode(wire.encode(got))) == wire.encode(got)
