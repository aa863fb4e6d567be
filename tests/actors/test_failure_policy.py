"""The runtime's failure policy, on whole inproc fleets: a run with a failure ends, failed.

An exception inside an action (the adapter raises), in the executive or in the
telemetry board must end the run promptly with a failed report, never leave it
waiting for ``mission_timeout_s`` (600 s), and never leave a drone in the air
without saying so.  Faults are injected at the HAL seam (an adapter that raises)
or as a malformed message to a runtime part (a bug in a sender).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from eamos.actors.messages import NodeEvent, RemoteTelemetry
from eamos.hal.fake import FakeAdapter
from eamos.logs import read_log
from eamos.net import wire

from .fleet_harness import WAIT_S, Fleet, make_fleet

#: Well under a ground-station heartbeat plus the actors' hops on a loaded machine;
#: far under mission_timeout_s.
PROMPT_S = 10.0

TWO_DRONES = """
func SEQ_Main() {
    D1.Arm()
    D1.Takeoff(1)
    D2.Arm()
    D2.Takeoff(1)
    D1.Land()
}
"""


@pytest.fixture
def fleets(tmp_path: Path) -> Iterator[Any]:
    made: list[Fleet] = []

    def build(source: str, adapters: dict[str, Any]) -> Fleet:
        fleet = make_fleet(source, adapters, log_dir=tmp_path / f"fleet{len(made)}")
        made.append(fleet)
        return fleet

    yield build
    for fleet in made:
        fleet.close()


def failures_logged(fleet: Fleet, drone: str) -> list[dict[str, Any]]:
    log_dir = fleet.runtimes[drone].log_dir
    assert log_dir is not None
    fleet.runtimes[drone].logs.close()  # flushed
    return [e for e in read_log(log_dir / "mission.log") if e["event"] == "mission.failure"]


def resolved_within(fleet: Fleet, seconds: float) -> float:
    t0 = time.monotonic()
    assert fleet.wait_resolved(seconds), f"unresolved: {fleet.station.unresolved()}"
    return time.monotonic() - t0


def test_an_action_that_raises_ends_the_run_failed(fleets: Any) -> None:
    d1 = FakeAdapter("D1", auto=True, run_errors={"Takeoff": RuntimeError("motor driver bug")})
    fleet = fleets(TWO_DRONES, {"D1": d1, "D2": FakeAdapter("D2", auto=True)})
    fleet.start()
    resolved_within(fleet, PROMPT_S)
    reports = fleet.finish()
    assert fleet.actions("D1") == [("Arm()", "ok"), ("Takeoff(1)", "failed")]
    assert "motor driver bug" in reports["D1"]["actions"][1]["reason"]
    assert not reports["D1"]["ok"] and not reports["D2"]["ok"]
    assert reports["D2"]["blocked_nodes"] and not reports["D2"]["actions"]


def test_an_exception_in_the_executive_aborts_the_drone_and_ends_the_run(fleets: Any) -> None:
    d1, d2 = FakeAdapter("D1", auto=False), FakeAdapter("D2", auto=True)
    fleet = fleets(TWO_DRONES, {"D1": d1, "D2": d2})
    fleet.start()
    d1.finish(d1.wait_started("Arm", timeout=WAIT_S))
    d1.wait_started("Takeoff", timeout=WAIT_S)  # D1 is flying; D2 waits for it
    # A malformed event (a sender's bug): the executive raises on it.
    fleet.runtimes["D1"].executive.tell(NodeEvent("n0", "running", "Takeoff", None))  # type: ignore[arg-type]
    resolved_within(fleet, PROMPT_S)
    d1.wait_for(lambda fake: bool(fake.calls_of("abort")), WAIT_S)  # it lands
    reports = fleet.finish()
    d1_report = reports["D1"]
    assert d1_report["aborted"] and not d1_report["ok"]
    assert d1_report["abort_reason"].startswith("internal error in the executive: TypeError")
    # The drone waiting for D1 was released: blocked, resolved, not hanging.
    assert reports["D2"]["blocked_nodes"] and not reports["D2"]["ok"]
    assert not reports["D2"]["aborted"] and not d2.calls_of("run")
    assert fleet.runtimes["D1"].aborted.is_set()
    # Logged once, with its traceback, in D1's mission log.
    (failure,) = failures_logged(fleet, "D1")
    assert failure["part"] == "executive"
    assert "Traceback" in failure["traceback"] and "TypeError" in failure["traceback"]


def test_an_exception_in_the_telemetry_board_aborts_the_drone(fleets: Any) -> None:
    d1 = FakeAdapter("D1", auto=False)
    fleet = fleets("func SEQ_Main() {\n    D1.Arm()\n    D1.Takeoff(1)\n}\n", {"D1": d1})
    fleet.start()
    d1.wait_started("Arm", timeout=WAIT_S)
    runtime = fleet.runtimes["D1"]
    runtime.board.tell(RemoteTelemetry("D1", None))  # type: ignore[arg-type]
    resolved_within(fleet, PROMPT_S)
    d1.wait_for(lambda fake: bool(fake.calls_of("abort")), WAIT_S)
    report = fleet.finish()["D1"]
    assert report["aborted"] and not report["ok"]
    assert "telemetry board" in report["abort_reason"]
    (failure,) = failures_logged(fleet, "D1")
    assert failure["part"] == "telemetry board" and "AttributeError" in failure["traceback"]
    # The board lives on: the report still has the vehicle's state.
    assert report["final"] is not None and report["final"]["armed"] is False


def test_an_exception_routing_a_wire_message_aborts_the_drone(fleets: Any) -> None:
    d1 = FakeAdapter("D1", auto=False)
    fleet = fleets("func SEQ_Main() {\n    D1.Arm()\n    D1.Takeoff(1)\n}\n", {"D1": d1})
    fleet.start()
    d1.wait_started("Arm", timeout=WAIT_S)
    router = fleet.runtimes["D1"].router
    assert router is not None
    # A message that breaks routing (a decoder bug would let it through): no iteration.
    broken = wire.Interrupt("m", "GCS", dest="D1", scope="1", iteration=None, mode="all")  # type: ignore[arg-type]
    router(broken)
    resolved_within(fleet, PROMPT_S)
    report = fleet.finish()["D1"]
    assert report["aborted"] and "in-bridge" in report["abort_reason"]
    (failure,) = failures_logged(fleet, "D1")
    assert failure["part"] == "in-bridge"
