"""One way to build a message: the constructor, plainly, inside a process; decode, which
checks every field, at the trust boundary.  And the plain-data check (progress batches,
reports) that bounds nesting without recursing."""

from __future__ import annotations

from typing import Any

import msgpack
import pytest

from eamos.net import wire
from eamos.net.progress import progress_batch
from eamos.net.wire import MAX_DEPTH, plain_map

TRIGGER: dict[str, Any] = {
    "mission": "m1",
    "sender": "D1",
    "dest": "D2",
    "src_node": "n5",
    "dst_node": "n9",
    "iteration": (2, 0),
    "status": "done",
}


def test_a_constructed_message_is_the_decoded_one() -> None:
    made = wire.Trigger(**TRIGGER)  # type: ignore[arg-type]
    back = wire.decode(wire.encode(made))
    assert back == made and hash(back) == hash(made)
    assert (made.seq, made.incarnation, made.version) == (0, 0, wire.WIRE_VERSION)  # defaults
    assert wire.encode(back) == wire.encode(made)


def test_constructors_fill_default_factories_afresh_and_refuse_unknown_fields() -> None:
    one = wire.Progress(mission="m", sender="D1", state="s", node="n", action="a")
    two = wire.Progress(mission="m", sender="D1", state="s", node="n", action="a")
    assert one.detail == {} and one.detail is not two.detail
    assert one.dest == wire.GROUND_STATION
    with pytest.raises(TypeError, match="colour"):
        wire.Trigger(colour="red", **TRIGGER)  # type: ignore[call-arg]  # deliberately invalid


def test_messages_are_frozen() -> None:
    msg = wire.Trigger(**TRIGGER)  # type: ignore[arg-type]
    with pytest.raises(AttributeError):
        msg.seq = 3  # type: ignore[misc]


def test_the_checks_guard_decode() -> None:
    # Built plainly (no check), refused where it arrives, naming the field.
    bad_dest = wire.Trigger(**{**TRIGGER, "dest": "a/b"})  # type: ignore[arg-type]
    with pytest.raises(wire.WireError, match=r"Trigger\.dest"):
        wire.decode(wire.encode(bad_dest))
    bad_status = wire.Trigger(**{**TRIGGER, "status": "maybe"})  # type: ignore[arg-type]
    with pytest.raises(wire.WireError, match=r"Trigger\.status"):
        wire.decode(wire.encode(bad_status))


def test_encode_refuses_what_messagepack_cannot_carry() -> None:
    for detail in ({"a": object()}, {"a": [object()]}):
        msg = wire.Progress(
            mission="m", sender="D1", state="s", node="n", action="a", detail=detail
        )
        with pytest.raises(wire.WireError, match="cannot encode Progress"):
            wire.encode(msg)


def wrap(container: type, depth: int) -> object:
    value: object = "leaf"
    for _ in range(depth):
        value = {"k": value} if container is dict else [value]
    return value


@pytest.mark.parametrize("container", [list, dict])
def test_plain_data_depth_limit_is_where_it_was(container: type) -> None:
    # The map itself is depth 0; MAX_DEPTH levels below it pass, one more does not.
    assert plain_map({"x": wrap(container, MAX_DEPTH - 1)}, "f")
    with pytest.raises(wire.WireError, match="f: nested deeper than 32"):
        plain_map({"x": wrap(container, MAX_DEPTH)}, "f")
    plain_map({"x": wrap(container, MAX_DEPTH - 1) if container is dict else []}, "f")


@pytest.mark.parametrize("container", [list, dict])
def test_decode_bounds_the_depth_of_detail_and_report_where_it_was(container: type) -> None:
    for depth, ok in ((MAX_DEPTH - 1, True), (MAX_DEPTH, False)):
        msgs: list[wire.Message] = [
            wire.Progress("m", "D1", "s", "n", "a", {"x": wrap(container, depth)}),
            wire.Report("m", "D1", {"x": wrap(container, depth)}),
        ]
        for msg in msgs:
            if ok:
                assert wire.decode(wire.encode(msg)) == msg
            else:
                with pytest.raises(wire.WireError, match="nested deeper than 32"):
                    wire.decode(wire.encode(msg))


def test_plain_data_refuses_what_it_refused() -> None:
    assert plain_map({"a": [1, 2.5, None, True, b"x"], "b": {"c": ["d"]}}, "f")
    with pytest.raises(wire.WireError, match="map keys must be str"):
        plain_map({"a": {1: "x"}}, "f")
    with pytest.raises(wire.WireError, match="map keys must be str"):
        plain_map({"a": [{b"k": "x"}]}, "f")
    with pytest.raises(wire.WireError, match="expected a map, got list"):
        plain_map([1], "f")
    # On the wire, msgpack itself refuses int keys and ext types.
    payload = msgpack.unpackb(wire.encode(wire.Report("m", "D1", {}))[1], raw=False) | {
        "rp": {"a": {1: "x"}}
    }
    with pytest.raises(wire.WireError, match="msgpack"):
        wire.decode([b"to/GCS", msgpack.packb(payload)])


def test_a_full_progress_batch_round_trips() -> None:
    events = [
        ("ok", f"n{i}", "Arm()", {"iteration": [i], "detail": "", "finished": i, "at": 1.5})
        for i in range(256)
    ]
    batch = progress_batch("m1", "D1", events)
    assert wire.decode(wire.encode(batch)) == batch
