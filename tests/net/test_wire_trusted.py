"""The sender's fast path: messages of its own values built without the field checks,
and the plain-data check (progress batches, reports) on its set-lookup path."""

from __future__ import annotations

import pytest

from eamos.net import wire
from eamos.net.progress import progress_batch
from eamos.net.trusted import trusted
from eamos.net.wire_fields import MAX_DEPTH, _check_map

TRIGGER = {
    "mission": "m1",
    "sender": "D1",
    "dest": "D2",
    "src_node": "n5",
    "dst_node": "n9",
    "iteration": (2, 0),
    "status": "done",
}


def test_a_trusted_message_is_the_checked_one() -> None:
    checked = wire.Trigger(**TRIGGER)  # type: ignore[arg-type]
    fast = trusted(wire.Trigger, **TRIGGER)
    assert fast == checked and hash(fast) == hash(checked)
    assert (fast.seq, fast.incarnation) == (0, 0)  # the defaults
    assert wire.encode(fast) == wire.encode(checked)
    assert wire.decode(wire.encode(fast)) == checked


def test_trusted_fills_default_factories_afresh_and_refuses_unknown_fields() -> None:
    one = trusted(wire.Progress, mission="m", sender="D1", state="s", node="n", action="a")
    two = trusted(wire.Progress, mission="m", sender="D1", state="s", node="n", action="a")
    assert one.detail == {} and one.detail is not two.detail
    assert one.dest == wire.GROUND_STATION
    with pytest.raises(TypeError, match="colour"):
        trusted(wire.Trigger, colour="red", **TRIGGER)


def test_the_checks_still_guard_the_constructor_and_decode() -> None:
    with pytest.raises(wire.WireError, match="dest"):
        wire.Trigger(**{**TRIGGER, "dest": "a/b"})  # type: ignore[arg-type]
    bad = trusted(wire.Trigger, **{**TRIGGER, "status": "maybe"})
    with pytest.raises(wire.WireError, match="status"):
        wire.decode(wire.encode(bad))  # a peer's message is checked where it arrives


def nested(depth: int) -> object:
    value: object = 1
    for _ in range(depth):
        value = [value]
    return value


@pytest.mark.parametrize("container", [list, tuple, dict])
def test_plain_data_depth_limit_is_where_it_was(container: type) -> None:
    def wrap(depth: int) -> object:
        value: object = "leaf"
        for _ in range(depth):
            value = {"k": value} if container is dict else container([value])
        return value

    # The map itself is depth 0; MAX_DEPTH levels below it pass, one more does not.
    _check_map({"x": wrap(MAX_DEPTH - 1)}, "f")
    with pytest.raises(wire.WireError, match="deeper"):
        _check_map({"x": wrap(MAX_DEPTH)}, "f")
    _check_map({"x": wrap(MAX_DEPTH - 1) if container is dict else container()}, "f")


def test_plain_data_refuses_what_it_refused() -> None:
    class Key(str):
        pass

    class Many(list):  # type: ignore[type-arg]
        pass

    _check_map({Key("a"): Many([1, 2.5, None, True, b"x"]), "b": {"c": ("d",)}}, "f")
    with pytest.raises(wire.WireError, match="map keys must be str"):
        _check_map({"a": {1: "x"}}, "f")
    with pytest.raises(wire.WireError, match="set is not plain data"):
        _check_map({"a": [{1, 2}]}, "f")
    with pytest.raises(wire.WireError, match="object is not plain data"):
        _check_map({"a": {"b": object()}}, "f")


def test_a_full_progress_batch_round_trips() -> None:
    events = [
        ("ok", f"n{i}", "Arm()", {"iteration": [i], "detail": "", "finished": i, "at": 1.5})
        for i in range(256)
    ]
    batch = progress_batch("m1", "D1", events)
    assert wire.decode(wire.encode(batch)) == batch
