"""A node calls an adapter that answers at once directly: no hop, one message to the executive.

A real node actor on a real dispatcher, the uniform API's real bookkeeping over the
FakeAdapter (the HAL seam); the executive and the next node are recorders.
"""

from __future__ import annotations

from typing import Any

from eamos.actors.dispatch import Dispatcher
from eamos.actors.logic import Route
from eamos.actors.messages import ActionRecord, NodeEvent, NodeResolved, Trigger
from eamos.actors.node import ExecutiveNews, Links, MissionNode, Wire
from eamos.actors.uniform_api import UniformSpace
from eamos.hal.api import ActionResult
from eamos.hal.fake import FakeAdapter
from eamos.logs import make_logger
from eamos.program.format import ProgramNode

from .recorder import WAIT_S, Recorder


def _node(fake: FakeAdapter) -> tuple[Any, dict[str, Recorder], Dispatcher]:
    dispatcher = Dispatcher(workers=1, name="test-direct")
    peers = {name: Recorder() for name in ("n8", "hal", "board", "out", "executive")}
    space = UniformSpace(fake, make_logger(None))
    links = Links(
        {"n8": peers["n8"]}, peers["hal"], peers["board"], peers["out"], peers["executive"], space
    )
    spec = ProgramNode("n5", 5, "action", "D1", True, label="Arm()", action="Arm", args=())
    routes = (Route("n8", "D1", "seq", False),)
    ref = MissionNode.start(
        dispatcher, spec, routes, frozenset({"n1"}), frozenset(), "D1", make_logger(None)
    )
    ref.tell(Wire(links))
    return ref, peers, dispatcher


def test_an_action_that_ends_at_once_is_one_turn_and_one_message_to_the_executive() -> None:
    fake = FakeAdapter("D1", auto=True)
    ref, peers, dispatcher = _node(fake)
    try:
        ref.tell(Trigger("n1", "n5", (), "done"))
        assert peers["n8"].wait_count(1) == [Trigger("n5", "n8", (), "done")]
        (news,) = peers["executive"].wait_count(1)
        assert isinstance(news, ExecutiveNews)
        running, record, resolved = news.items
        assert isinstance(running, NodeEvent) and running.state == "running"
        assert isinstance(record, ActionRecord) and (record.action, record.result) == ("Arm", "ok")
        assert resolved == NodeResolved("n5", "done")
        assert peers["hal"].messages == []  # the uniform-API actor was not involved
        assert [c.method for c in fake.calls] == ["run", "finish"]
    finally:
        ref.stop()
        dispatcher.shutdown()


def test_an_action_that_ends_later_is_answered_to_the_node_once() -> None:
    fake = FakeAdapter("D1")
    ref, peers, dispatcher = _node(fake)
    try:
        ref.tell(Trigger("n1", "n5", (), "done"))
        handle = fake.wait_started("Arm", WAIT_S)
        (started,) = peers["executive"].wait_count(1)
        assert [type(x) for x in started.items] == [NodeEvent]
        fake.finish(handle, ActionResult("failed", "no GPS"))
        assert peers["n8"].wait_count(1) == [Trigger("n5", "n8", (), "failed")]
        _, ended = peers["executive"].wait_count(2)
        assert [type(x) for x in ended.items] == [ActionRecord, NodeResolved]
        assert ended.items[0].reason == "no GPS"
        assert peers["hal"].messages == []
    finally:
        ref.stop()
        dispatcher.shutdown()
