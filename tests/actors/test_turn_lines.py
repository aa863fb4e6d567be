"""A node's turn sends its triggers to other drones before it writes its log lines.

A real node actor on a real dispatcher, the real Outbox and the uniform API's real
bookkeeping over the FakeAdapter (the HAL seam), real log files written by a real
LogWriter; the link under the Outbox is a stand-in that looks at the log files at
the moment a trigger goes out.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

from eamos.actors.dispatch import Dispatcher
from eamos.actors.logic import Route
from eamos.actors.messages import RemoteTrigger
from eamos.actors.node import Links, MissionNode, Wire
from eamos.actors.outbox import Outbox
from eamos.actors.uniform_api import UniformSpace
from eamos.hal.fake import FakeAdapter
from eamos.logs import DroneLogs
from eamos.net import wire
from eamos.program.format import ProgramNode

from .recorder import WAIT_S, Recorder


def events(path: Path) -> list[str]:
    if not path.exists():
        return []
    return [json.loads(line)["event"] for line in path.read_text().splitlines()]


def lines(folder: Path, name: str) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (folder / f"{name}.log").read_text().splitlines()]


class PeekingLink:
    """Takes the Outbox's wire messages; notes what the log files held at that moment."""

    def __init__(self, logs: DroneLogs, folder: Path) -> None:
        self.logs = logs
        self.folder = folder
        self.sent: list[wire.Message] = []
        self.seen: list[tuple[list[str], list[str]]] = []
        self.done = threading.Event()

    def send(self, msg: wire.Message) -> bool:
        assert self.logs.writer is not None
        self.logs.writer.flush()  # whatever was logged before the send is on disk now
        self.seen.append((events(self.folder / "mission.log"), events(self.folder / "uniform.log")))
        self.sent.append(msg)
        self.done.set()
        return True


def arm_node(dispatcher: Dispatcher, links: Links, logs: DroneLogs) -> Any:
    """D1's node n5, Arm() then a trigger to D2's n9, started, wired and triggered."""
    spec = ProgramNode("n5", 5, "action", "D1", True, label="Arm()", action="Arm", args=())
    routes = (Route("n9", "D2", "seq", True),)
    ref = MissionNode.start(
        dispatcher, spec, routes, frozenset({"n1"}), frozenset(), "D1", logs.mission
    )
    ref.tell(Wire(links))
    ref.tell(RemoteTrigger("n1", "n5", (), "done", "D0"))
    return ref


def test_the_trigger_to_another_drone_leaves_before_the_turns_lines(tmp_path: Path) -> None:
    logs = DroneLogs.open(tmp_path, "D1")
    link = PeekingLink(logs, tmp_path)
    outbox = Outbox(link, "D1", "m1", logs.mission)  # type: ignore[arg-type]
    fake = FakeAdapter("D1", auto=True)
    space = UniformSpace(fake, logs.uniform)
    dispatcher = Dispatcher(workers=1, name="test-turn-lines")
    peers = {name: Recorder() for name in ("hal", "board", "executive")}
    links = Links({}, peers["hal"], peers["board"], outbox, peers["executive"], space)
    ref = arm_node(dispatcher, links, logs)
    try:
        assert link.done.wait(WAIT_S)
        peers["executive"].wait_count(2)  # the turn ended (its news after the trigger)
        ref.stop()
    finally:
        dispatcher.shutdown()
        logs.close()
    (msg,) = link.sent
    assert isinstance(msg, wire.Trigger)
    assert (msg.dest, msg.src_node, msg.dst_node, msg.status) == ("D2", "n5", "n9", "done")
    # When it left, the action had run (uniform.call) but none of the turn's other lines
    # were written: they wait until the trigger is out.
    mission_then, uniform_then = link.seen[0]
    assert "mission.node.triggered" not in mission_then
    assert uniform_then == ["uniform.call"]
    # Afterwards every line is there, in the order of the events.
    mine = [
        e
        for e in events(tmp_path / "mission.log")
        if e.startswith(("mission.node.", "mission.outbridge.", "mission.inbridge."))
    ]
    assert mine == [
        "mission.node.triggered",
        "mission.outbridge.sent",
        "mission.node.finished",
        "mission.inbridge.received",
    ]
    assert events(tmp_path / "uniform.log") == ["uniform.call", "uniform.result"]
    assert outbox.counts() == {"triggers_sent": 1, "by_dest": {"D2": 1}}
    # Each line keeps the time of what it says, not of its writing.
    ts = {e["event"]: e["ts"] for name in ("mission", "uniform") for e in lines(tmp_path, name)}
    assert ts["mission.node.triggered"] <= ts["uniform.call"] <= ts["uniform.result"]
    assert ts["uniform.result"] <= ts["mission.outbridge.sent"] <= ts["mission.node.finished"]


class ExecutiveAtSend(PeekingLink):
    """Also notes what the executive had been told when a trigger left."""

    def __init__(self, logs: DroneLogs, folder: Path, executive: Recorder) -> None:
        super().__init__(logs, folder)
        self.executive = executive
        self.told: list[list[Any]] = []

    def send(self, msg: wire.Message) -> bool:
        with self.executive.changed:
            self.told.append(list(self.executive.messages))
        return super().send(msg)


def test_the_action_record_reaches_the_executive_before_the_trigger_leaves(
    tmp_path: Path,
) -> None:
    # The peer may end the mission on this trigger; this drone's report, asked of its
    # executive then, must already hold the action whose end the trigger announced
    # (tests/actors/test_node_actors.py's RepeatFor once missed a last iteration).
    from eamos.actors.messages import ActionRecord

    logs = DroneLogs.open(tmp_path, "D1")
    executive = Recorder(unpack_news=True)
    link = ExecutiveAtSend(logs, tmp_path, executive)
    outbox = Outbox(link, "D1", "m1", logs.mission)  # type: ignore[arg-type]
    space = UniformSpace(FakeAdapter("D1", auto=True), logs.uniform)
    dispatcher = Dispatcher(workers=1, name="test-turn-lines-3")
    peers = {name: Recorder() for name in ("hal", "board")}
    links = Links({}, peers["hal"], peers["board"], outbox, executive, space)  # type: ignore[arg-type]
    ref = arm_node(dispatcher, links, logs)
    try:
        assert link.done.wait(WAIT_S)
        ref.stop()
    finally:
        dispatcher.shutdown()
        logs.close()
    (told,) = link.told
    records = [m for m in told if isinstance(m, ActionRecord)]
    assert [(r.node, r.action, r.result) for r in records] == [("n5", "Arm", "ok")]
    # The turn's log lines still waited for the trigger.
    assert "mission.node.triggered" not in link.seen[0][0]


def test_a_held_result_line_is_written_before_any_later_line_of_the_uniform_log(
    tmp_path: Path,
) -> None:
    from eamos.actors.uniform_api import RunAction

    logs = DroneLogs.open(tmp_path, "D1")
    fake = FakeAdapter("D1", auto=True)
    space = UniformSpace(fake, logs.uniform)
    asker: Any = Recorder()  # answered inline: nothing is told to it
    try:
        first = space.run(RunAction("a", "Arm", (), asker), later=True)
        assert first is not None and first.result.ok
        # Not written yet; the next call's line writes it first.
        second = space.run(RunAction("b", "Disarm", (), asker), later=True)
        assert second is not None
        space.write_results()
        space.write_results()  # nothing held: nothing written twice
    finally:
        logs.close()
    lines = [json.loads(x) for x in (tmp_path / "uniform.log").read_text().splitlines()]
    assert [(x["event"], x["token"]) for x in lines] == [
        ("uniform.call", "a"),
        ("uniform.result", "a"),
        ("uniform.call", "b"),
        ("uniform.result", "b"),
    ]
    assert lines[1]["start_s"] == round(first.start_s, 6)
    assert lines[1]["end_s"] == round(first.end_s, 6)
    assert lines[1]["status"] == "ok" and lines[1]["args"] == []


def test_a_stand_in_out_bridge_is_told_the_trigger(tmp_path: Path) -> None:
    # Nodes also work with anything that takes messages (tests' recorders).
    from eamos.actors.messages import SendTrigger, Trigger

    logs = DroneLogs.open(tmp_path, "D1")
    dispatcher = Dispatcher(workers=1, name="test-turn-lines-2")
    peers = {name: Recorder() for name in ("hal", "board", "out", "executive")}
    space = UniformSpace(FakeAdapter("D1", auto=True), logs.uniform)
    links = Links({}, peers["hal"], peers["board"], peers["out"], peers["executive"], space)
    ref = arm_node(dispatcher, links, logs)
    try:
        assert peers["out"].wait_for(SendTrigger) == SendTrigger(
            "D2", Trigger("n5", "n9", (), "done")
        )
        peers["executive"].wait_count(1)
        ref.stop()
    finally:
        dispatcher.shutdown()
        logs.close()
    assert "mission.node.finished" in events(tmp_path / "mission.log")


def test_turn_order_puts_records_before_triggers_to_other_drones_only() -> None:
    # Pure: the order a node applies a turn's effects in.
    from eamos.actors.logic.effects import Effect, Emit, Progress, Record, Resolve, StartAction
    from eamos.actors.messages import ActionRecord, NodeEvent
    from eamos.actors.node import turn_order

    record = Record(ActionRecord("n5", "Arm", (), (), 1.0, 2.0, "ok"))
    progress = Progress(NodeEvent("n5", "running", "Arm"))
    local = Emit(Route("n6", "D1", "seq", False), (), "done")
    remote = Emit(Route("n9", "D2", "seq", True), (), "done")
    resolve = Resolve((), "done", True)
    start = StartAction((1,), "Arm", ())
    turn: list[Effect] = [start, local, record, remote, progress, resolve]
    assert turn_order(turn) == ([record, progress], [remote], [start, local, resolve])
    # Without a trigger to another drone, the turn keeps its order.
    alone: list[Effect] = [start, record, local, resolve]
    assert turn_order(alone) == ([], [], alone)
