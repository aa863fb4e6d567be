"""The node actors' failure policy: an exception resolves the node ``failed``, once.

Messages are ``tell``-ed, as in a runtime (an ``ask`` returns the exception to
the asker instead, as in Pykka).

A node actor whose logic raises logs the exception with its traceback in the
mission log, sends ``failed`` to its successors (local and remote), tells the
executive (progress and resolution) and ignores later messages.  The actor
runs on a real dispatcher; its peers are recorders.
"""

from __future__ import annotations

import json
from typing import Any

import pytest

from eamos.actors.dispatch import Dispatcher
from eamos.actors.logic import ActionLogic, PassThrough, Route
from eamos.actors.messages import Fire, NodeEvent, NodeResolved, SendTrigger, Trigger
from eamos.actors.node import Links, MissionNode, Wire
from eamos.actors.uniform_api import ActionFinished, CancelAction, RunAction
from eamos.hal.api import ActionResult
from eamos.logs import close_logger, make_logger
from eamos.program.format import ProgramNode

from .recorder import WAIT_S, Recorder


class Boom(RuntimeError):
    pass


class FaultyFork(PassThrough):
    def trigger(self, src, iteration, status):  # type: ignore[no-untyped-def]
        raise Boom("logic bug")


class FaultyAction(ActionLogic):
    def action_finished(self, iteration, status, reason, start_s, end_s):  # type: ignore[no-untyped-def]
        raise Boom("bad result")


ROUTES = (Route("n8", "D1", "seq", False), Route("n9", "D2", "seq", True))


@pytest.fixture
def harness(tmp_path):
    dispatcher = Dispatcher(workers=1, name="test-failure")
    log = make_logger(tmp_path / "mission.log")
    refs = []
    peers = {
        name: Recorder(unpack_news=True) for name in ("n8", "hal", "board", "out", "executive")
    }
    links = Links(
        {"n8": peers["n8"]}, peers["hal"], peers["board"], peers["out"], peers["executive"]
    )

    def start(logic_class: type, spec: ProgramNode) -> Any:
        logic = logic_class(spec, ROUTES, frozenset({"n1"}))
        ref = MissionNode.start(
            dispatcher, spec, ROUTES, frozenset({"n1"}), frozenset(), "D1", log, logic=logic
        )
        refs.append(ref)
        ref.tell(Wire(links))
        return ref

    yield start, peers, tmp_path / "mission.log"
    for ref in refs:
        ref.stop()
    dispatcher.shutdown()
    close_logger(log)


def crash_lines(path) -> list[dict]:
    lines = [json.loads(x) for x in path.read_text().splitlines()]
    return [x for x in lines if x["event"] == "mission.node.crashed"]


def test_a_node_that_raises_resolves_failed_and_blocks_its_successors(harness, capfd):
    start, peers, log_path = harness
    ref = start(FaultyFork, ProgramNode("n5", 5, "fork", "D1", True, label="fork"))
    ref.tell(Trigger("n1", "n5", (), "done"))
    assert peers["n8"].wait_for(Trigger) == Trigger("n5", "n8", (), "failed")
    assert peers["out"].wait_for(SendTrigger) == SendTrigger(
        "D2", Trigger("n5", "n9", (), "failed")
    )
    assert peers["executive"].wait_for(NodeResolved) == NodeResolved("n5", "failed")
    event = peers["executive"].wait_for(NodeEvent)
    assert event.state == "failed" and "logic bug" in event.detail
    # Later messages are no-ops: nothing more is sent, nothing more is logged.
    before = {name: len(p.messages) for name, p in peers.items()}
    ref.tell(Trigger("n1", "n5", (), "done"))
    ref.tell(Trigger("n2", "n5", (), "done"))
    ref.ask(Fire(), timeout=WAIT_S)  # answered after the two triggers were handled
    assert {name: len(p.messages) for name, p in peers.items()} == before
    (line,) = crash_lines(log_path)
    assert "Boom: logic bug" in line["exception"] and "Traceback" in line["exception"]
    assert ref.is_alive()
    # ... and one line on stderr (the node's node.out): the operator sees it too.
    err = capfd.readouterr().err
    assert err.count("eamos-node D1: internal error in node n5: Boom('logic bug')") == 1


def test_a_node_failing_on_its_action_result_blocks_the_rest(harness):
    start, peers, log_path = harness
    spec = ProgramNode(
        "n5", 5, "action", "D1", True, label="FlyByX(1)", action="FlyByX", args=(1.0,)
    )
    ref = start(FaultyAction, spec)
    ref.tell(Trigger("n1", "n5", (), "done"))
    run = peers["hal"].wait_for(RunAction)
    ref.tell(ActionFinished(run.token, "FlyByX", (1.0,), ActionResult("ok"), 1.0, 2.0))
    assert peers["n8"].wait_for(Trigger).status == "failed"
    assert peers["executive"].wait_for(NodeResolved) == NodeResolved("n5", "failed")
    assert len(crash_lines(log_path)) == 1


def test_a_crash_with_an_action_out_cancels_it(harness):
    class CrashOnTelemetry(ActionLogic):
        def telemetry(self, drone, values):  # type: ignore[no-untyped-def]
            raise Boom("telemetry")

    from eamos.actors.messages import TelemetryChanged

    start, peers, _ = harness
    spec = ProgramNode("n5", 5, "action", "D1", True, action="FlyByX", args=(1.0,))
    ref = start(CrashOnTelemetry, spec)
    ref.tell(Trigger("n1", "n5", (), "done"))
    run = peers["hal"].wait_for(RunAction)
    ref.tell(TelemetryChanged("D1", {}))
    assert peers["hal"].wait_for(CancelAction) == CancelAction(run.token)
    assert peers["executive"].wait_for(NodeResolved) == NodeResolved("n5", "failed")
