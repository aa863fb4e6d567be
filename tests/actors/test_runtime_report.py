"""The drone report: a typed value with the first version's JSON, and a fresh final state."""

from __future__ import annotations

import subprocess
import sys
import threading
from collections.abc import Iterator
from concurrent.futures import Future
from dataclasses import replace
from typing import Any

import pytest

from eamos.actors import DroneReport, DroneReportError, FinalState
from eamos.actors.board import FinalSample, LocalSample, TelemetryBoard, WhenSettled
from eamos.actors.dispatch import Dispatcher
from eamos.hal import make_adapter
from eamos.hal.api import Telemetry
from eamos.logs import make_logger

from .fleet_harness import WAIT_S, make_fleet

#: The keys (and their order) the first version wrote; the ground station,
#: eamos.ops and `eamos report` read them.
REPORT_KEYS = [
    "ok",
    "resolved",
    "aborted",
    "abort_reason",
    "triggers_sent",
    "triggers_received",
    "external_out",
    "external_in",
    "mdg",
    "blocked_nodes",
    "actions",
    "final",
    "adapter_error",
    "retransmissions",
    "duplicates_dropped",
    "net",
]

THREE_DRONES_DISARM = """
func PAR_Fly() {
    SEQ_D1()
    SEQ_D2()
    SEQ_D3()
}
func SEQ_D1() {
    D1.Arm()
    D1.Disarm()
}
func SEQ_D2() {
    D2.Arm()
    D2.Disarm()
}
func SEQ_D3() {
    D3.Arm()
    D3.Disarm()
}
"""


def test_a_report_keeps_the_first_versions_json_and_reads_back() -> None:
    fleet = make_fleet("func SEQ_Main() {\n    D1.Arm()\n    D1.TurnOn()\n}\n")
    try:
        fleet.start()
        assert fleet.wait_resolved(WAIT_S)
        data = fleet.finish()["D1"]
    finally:
        fleet.close()
    assert list(data) == REPORT_KEYS
    # The first version's keys, then whether it stands on the ground (a left-armed drone).
    assert list(data["final"]) == ["x", "y", "z", "armed", "battery", "landed"]
    assert list(data["actions"][0]) == [
        "node",
        "action",
        "args",
        "iteration",
        "start",
        "end",
        "result",
    ]
    report = DroneReport.from_json(data)
    assert report.ok and report.actions[1].action == "TurnOn"
    assert report.to_json() == data
    # The summary's own keys around a report are ignored.
    assert DroneReport.from_json({**data, "exit_code": 0}) == report


def test_a_broken_report_is_refused_with_the_key_named() -> None:
    good = DroneReport(
        ok=False,
        resolved=True,
        aborted=True,
        abort_reason="stopped",
        triggers_sent=1,
        triggers_received=2,
        external_out=1,
        external_in=2,
        mdg={"nodes": 3},
        blocked_nodes=("n4",),
        actions=(),
        final=FinalState(1.0, 2.0, 0.0, False, 88.5),
    ).to_json()
    assert DroneReport.from_json(good).final == FinalState(1.0, 2.0, 0.0, False, 88.5)
    for key, value in [("ok", None), ("triggers_sent", True), ("actions", "x")]:
        with pytest.raises(DroneReportError, match=key):
            DroneReport.from_json({**good, key: value})
    with pytest.raises(DroneReportError, match="final"):
        DroneReport.from_json({**good, "final": {"x": 1}})
    without = dict(good)
    del without["resolved"]
    with pytest.raises(DroneReportError, match="resolved"):
        DroneReport.from_json(without)


def test_importing_the_report_loads_neither_pykka_nor_zmq() -> None:
    code = (
        "import sys, eamos.actors.report\nprint([m for m in ('pykka', 'zmq') if m in sys.modules])"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert out.stdout.strip() == "[]"


# -- the final state -------------------------------------------------------------------------


def sample(armed: bool, time_s: float = 0.0, landed: bool = True) -> Telemetry:
    return Telemetry("D1", time_s, 0.0, 0.0, 0.0, 46.6, 14.2, 400.0, 90.0, armed, landed)


@pytest.fixture
def board() -> Iterator[Any]:
    dispatcher = Dispatcher(workers=1, name="board-test")
    ref = TelemetryBoard.start(dispatcher, "D1", None, "m")
    yield ref
    ref.stop(block=True, timeout=WAIT_S)
    dispatcher.shutdown()


def final(
    board: Any, after_s: float | None, wait_s: float, action: str | None = None
) -> Future[Telemetry | None]:
    reply: Future[Telemetry | None] = Future()
    board.tell(FinalSample(after_s, wait_s, reply, action))
    return reply


def test_the_final_state_is_the_first_sample_after_the_last_action(board: Any) -> None:
    board.tell(LocalSample(sample(armed=True), received_s=1.0))
    # The last action (Disarm) was recorded at 2.0: the sample at 1.0 is stale.
    reply = final(board, after_s=2.0, wait_s=WAIT_S)
    board.tell(LocalSample(sample(armed=False), received_s=3.0))
    got = reply.result(timeout=WAIT_S)
    assert got is not None and got.armed is False


def test_a_sample_after_the_last_action_is_the_answer_at_once(board: Any) -> None:
    board.tell(LocalSample(sample(armed=False), received_s=3.0))
    got = final(board, after_s=2.0, wait_s=WAIT_S).result(timeout=WAIT_S)
    assert got is not None and got.armed is False
    nothing_changed = final(board, after_s=None, wait_s=WAIT_S).result(timeout=WAIT_S)
    assert nothing_changed == got


def test_without_a_new_sample_the_latest_one_is_the_answer_at_the_deadline(board: Any) -> None:
    board.tell(LocalSample(sample(armed=False), received_s=1.0))
    got = final(board, after_s=2.0, wait_s=0.2).result(timeout=WAIT_S)
    assert got is not None and got.armed is False  # the adapter's state did not change


def test_a_stopping_board_answers_a_waiting_request() -> None:
    dispatcher = Dispatcher(workers=1, name="board-test")
    ref = TelemetryBoard.start(dispatcher, "D1", None, "m")
    ref.tell(LocalSample(replace(sample(armed=True)), received_s=1.0))
    reply = final(ref, after_s=2.0, wait_s=WAIT_S)
    ref.stop(block=True, timeout=WAIT_S)
    dispatcher.shutdown()
    assert reply.result(timeout=WAIT_S) is not None


@pytest.mark.parametrize("speedup,run", [(10, 0), (10, 1), (10, 2), (2, 0)])
def test_a_fleet_whose_last_action_is_disarm_reports_armed_false(speedup: int, run: int) -> None:
    """Issue 9 item 11: with the last sample, armed in 1/3 of the reports at speed-up 10, all at 2.

    (The simulator sends a sample every 0.1 simulated seconds, after its done callbacks.)
    """
    adapters = {
        d: make_adapter(d, {"adapter": "sim", "speedup": speedup}, make_logger(None))
        for d in ("D1", "D2", "D3")
    }
    fleet = make_fleet(THREE_DRONES_DISARM, adapters)
    try:
        fleet.start()
        assert fleet.wait_resolved(WAIT_S), fleet.station.unresolved()
        reports = fleet.finish()
    finally:
        fleet.close()
    for drone in ("D1", "D2", "D3"):
        assert reports[drone]["ok"], (drone, reports[drone])
        assert fleet.actions(drone)[-1] == ("Disarm()", "ok")
        final_state = reports[drone]["final"]
        assert final_state["armed"] is False, (drone, final_state)
        assert final_state["z"] == pytest.approx(0.0, abs=0.01), (drone, final_state)


def test_a_sample_showing_the_last_actions_effect_needs_no_wait(board: Any) -> None:
    board.tell(LocalSample(sample(armed=False), received_s=1.0))
    # Recorded at 2.0, but the sample already shows the Disarm: no wait (30 s here).
    got = final(board, after_s=2.0, wait_s=WAIT_S, action="Disarm").result(timeout=5.0)
    assert got is not None and got.armed is False


# -- waiting for the disarm after landing ---------------------------------------------------


def settled(board: Any, after_s: float | None, action: str | None = None) -> threading.Event:
    event = threading.Event()
    board.tell(WhenSettled(event, after_s, action))
    return event


def test_settled_waits_for_the_disarm_after_a_landing(board: Any) -> None:
    # The sample before the Land ended (at 2.0) shows it in the air: too old to tell.
    board.tell(LocalSample(sample(armed=True, landed=False), received_s=1.0))
    event = settled(board, after_s=2.0, action="Land")
    board.tell(LocalSample(sample(armed=True, landed=True), received_s=2.5))
    assert not event.wait(0.3)  # landed, still armed: the autopilot disarms a moment later
    board.tell(LocalSample(sample(armed=False, landed=True), received_s=4.5))
    assert event.wait(WAIT_S)


def test_settled_at_once_when_disarmed_or_left_in_the_air(board: Any) -> None:
    board.tell(LocalSample(sample(armed=False), received_s=3.0))
    assert settled(board, after_s=2.0, action="Land").wait(WAIT_S)
    board.tell(LocalSample(sample(armed=True, landed=False), received_s=4.0))
    # Hovering after its last action: nothing will disarm it, no wait.
    assert settled(board, after_s=3.5, action="Takeoff").wait(WAIT_S)
    # Armed on the ground, never flown: not settled (the caller's wait is bounded).
    board.tell(LocalSample(sample(armed=True), received_s=5.0))
    assert not settled(board, after_s=4.5, action="Arm").wait(0.3)
