"""The ground station's one run loop (``eamos.ground.fly``), driven without sockets or threads.

A scripted stand-in for the ground station's runtime answers what the station
sends (Start, Complete, Abort) by handing the station the drones' replies, so
every phase runs in this thread; a fake monotonic clock decides when a silent
drone is given up.
"""

from __future__ import annotations

import io
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import eamos.ground
import eamos.ground.local
import eamos.ground.node
import eamos.ops.start
from eamos.ground import (
    DroneReport,
    Flight,
    GroundStation,
    Limits,
    PlainDisplay,
    RunSummary,
    fly,
    summarize,
)
from eamos.net import wire
from eamos.net.link import PeerStatus

MISSION = "m-1"
DRONES = ["Drone1", "Drone2"]


def report(ok: bool = True) -> dict[str, Any]:
    """A drone's report as it travels (JSON)."""
    return {
        "ok": ok,
        "resolved": True,
        "aborted": False,
        "abort_reason": "",
        "triggers_sent": 1,
        "triggers_received": 1,
        "external_out": 1,
        "external_in": 1,
        "mdg": {"nodes": 2},
        "blocked_nodes": [],
        "actions": [],
        "final": {"x": 0.0, "y": 0.0, "z": 0.0, "armed": False, "battery": 90.0},
    }


GCS_REPORT = DroneReport.from_json(report())


class ScriptedFleet:
    """The ground station's runtime, as far as the station uses it, with scripted drones.

    ``replies[kind]`` names the drones answering a message of that kind
    (``"start"``: they resolve; ``"complete"``/``"abort"``: they report).
    """

    out = None  # no out-bridge: the station does not wait for subscriptions

    def __init__(self, station: GroundStation, replies: dict[str, list[str]]) -> None:
        self.station = station
        self.replies = replies
        self.sent: list[Any] = []
        self.aborted: list[str] = []
        self.on_start: Callable[[], None] = lambda: None

    def send(self, msg: Any) -> None:
        self.sent.append(msg)
        if isinstance(msg, wire.Start):
            self.on_start()
            for name in self.replies.get("start", []):
                self.station.handle(wire.Resolved(mission=MISSION, sender=name))
        kinds: dict[type, str] = {wire.Complete: "complete", wire.Abort: "abort"}
        kind = kinds.get(type(msg))
        for name in self.replies.get(kind or "", []):
            self.station.handle(wire.Report(mission=MISSION, sender=name, report=report()))

    def fire(self) -> None:
        # The ground station's own program runs and resolves at once.
        self.station.handle(wire.Resolved(mission=MISSION, sender="GCS"))

    def abort(self, reason: str) -> None:
        self.aborted.append(reason)


def station_and_fleet(
    replies: dict[str, list[str]], give_up_s: float | None = None, clock: Any = time.monotonic
) -> tuple[GroundStation, ScriptedFleet, io.StringIO]:
    out = io.StringIO()
    display = PlainDisplay(out, clock=lambda: 0.0)
    station = GroundStation(
        DRONES, MISSION, on_change=display.event, give_up_s=give_up_s, clock=clock
    )
    fleet = ScriptedFleet(station, replies)
    station.attach(fleet)  # type: ignore[arg-type]  # the runtime's interface, scripted
    return station, fleet, out


def ready(station: GroundStation, *names: str) -> None:
    for name in names:
        station.handle(wire.Ready(mission=MISSION, sender=name, program_checksum="sha256:0"))


def run(station: GroundStation, limits: Limits, stop: threading.Event | None = None) -> Flight:
    return fly(station, PlainDisplay(io.StringIO()), stop or threading.Event(), limits)


def test_a_mission_starts_completes_and_collects_every_report() -> None:
    station, fleet, out = station_and_fleet({"start": DRONES, "complete": DRONES})
    ready(station, *DRONES)
    flight = fly(station, PlainDisplay(out), threading.Event(), Limits(5, 30))
    assert flight.ok and flight.ready_s is not None and flight.missing_reports == ()
    assert [type(m).__name__ for m in fleet.sent] == ["Start", "Complete"]
    views = station.snapshot()
    assert all(views[d].report == GCS_REPORT for d in DRONES)
    assert "all drones ready: start" in out.getvalue()


def test_no_start_trigger_when_a_drone_is_not_ready() -> None:
    station, fleet, _ = station_and_fleet({"abort": ["Drone1"]})
    ready(station, "Drone1")
    flight = run(station, Limits(ready_timeout_s=0.2, timeout_s=30, report_aborted_s=5))
    assert flight.outcome == "not ready: waiting for Drone2" and flight.ready_s is None
    assert [type(m).__name__ for m in fleet.sent] == ["Abort"]
    assert fleet.aborted == [flight.outcome]
    # Drone2 never became ready: it sends no report and is not waited for.
    assert flight.missing_reports == ()


def test_the_operator_stops_the_mission_and_everyone_reports() -> None:
    station, fleet, _ = station_and_fleet({"start": ["Drone1"], "abort": DRONES})
    stop = threading.Event()
    fleet.on_start = stop.set  # the operator presses Ctrl-C right after the start
    ready(station, *DRONES)
    flight = run(station, Limits(5, 30), stop)
    assert flight.outcome == "aborted by the operator"
    assert [type(m).__name__ for m in fleet.sent] == ["Start", "Abort"]
    assert flight.missing_reports == ()


def test_a_mission_that_does_not_end_times_out_and_aborts() -> None:
    station, fleet, _ = station_and_fleet({"start": ["Drone1"], "abort": DRONES})
    ready(station, *DRONES)
    flight = run(station, Limits(5, timeout_s=0.5))
    assert flight.outcome == "timed out after 0.5 s (unresolved: Drone2)"
    assert [type(m).__name__ for m in fleet.sent] == ["Start", "Abort"]


def test_a_drone_given_up_is_waited_for_neither_to_resolve_nor_to_report() -> None:
    now = [0.0]
    station, fleet, _ = station_and_fleet(
        {"start": ["Drone1"], "complete": ["Drone1"]}, give_up_s=5.0, clock=lambda: now[0]
    )
    ready(station, *DRONES)

    def drone2_goes_silent() -> None:
        station.handle(PeerStatus("Drone2", "lost", 3.0, 1))
        now[0] = 10.0  # ... and stays silent past give_up_s

    fleet.on_start = drone2_goes_silent
    t0 = time.monotonic()
    flight = run(station, Limits(5, 60, report_ok_s=60))
    assert time.monotonic() - t0 < 30  # not the 60 s report wait
    assert flight.ok and flight.missing_reports == ()
    assert [type(m).__name__ for m in fleet.sent] == ["Start", "Complete"]
    summary = summarize(
        "m", MISSION, flight.outcome, 0.0, 1.0, Path("."), station.snapshot(), DRONES,
        list(station.failures), GCS_REPORT,
    )  # fmt: skip
    assert not summary.ok
    data = summary.to_json()
    assert data["drones"]["Drone2"] == {"ok": False, "error": "no report", "link": "lost"}
    assert data["links"] == {"Drone1": "up", "Drone2": "lost"}
    assert data["failures"] == ["Drone2: silent for more than 5 s"]


def test_a_drone_that_dies_while_the_others_report_is_not_waited_for() -> None:
    station, fleet, _ = station_and_fleet({"start": DRONES, "complete": ["Drone1"]})
    ready(station, *DRONES)
    # Drone2's process dies right after the mission is declared complete.
    original = fleet.send

    def send(msg: Any) -> None:
        original(msg)
        if isinstance(msg, wire.Complete):
            station.fail("Drone2", "process exited with code 1")

    fleet.send = send  # type: ignore[method-assign]
    t0 = time.monotonic()
    flight = run(station, Limits(5, 30, report_ok_s=60))
    assert time.monotonic() - t0 < 30 and flight.missing_reports == ()


def test_a_drone_that_stays_silent_past_the_report_wait_is_named() -> None:
    station, _, _ = station_and_fleet({"start": DRONES, "complete": ["Drone1"]})
    ready(station, *DRONES)
    out = io.StringIO()
    flight = fly(station, PlainDisplay(out), threading.Event(), Limits(5, 30, report_ok_s=0.3))
    assert flight.missing_reports == ("Drone2",)
    assert "some drones sent no report: Drone2" in out.getvalue()


def test_eamos_run_eamos_start_and_eamos_node_fly_through_the_same_loop() -> None:
    # The three ground stations differ in how drones start, not in how a mission flies.
    assert eamos.ground.local.fly is fly
    assert eamos.ground.node.fly is fly
    assert eamos.ops.start.fly is fly


def test_the_summary_of_a_flight_reads_back() -> None:
    station, _, _ = station_and_fleet({"start": DRONES, "complete": DRONES})
    ready(station, *DRONES)
    flight = run(station, Limits(5, 30))
    summary = summarize(
        "m", MISSION, flight.outcome, flight.started, flight.started + 2, Path("/tmp/run"),
        station.snapshot(), DRONES, list(station.failures), GCS_REPORT,
        exits={"Drone1": 0, "Drone2": 0},
    )  # fmt: skip
    assert summary.ok and summary.duration_s == 2.0
    assert RunSummary.from_json(summary.to_json()) == summary


def test_an_unreadable_report_counts_as_a_failure_and_is_not_waited_for() -> None:
    station, _, _ = station_and_fleet({})
    station.handle(wire.Report(mission=MISSION, sender="Drone1", report={"ok": True}))
    assert station.snapshot()["Drone1"].report is None
    assert station.failures == ["Drone1: unreadable report (report: no 'actions')"]
    assert station.wait_reports(["Drone1"], 0)


def test_a_given_up_drone_whose_node_restarted_is_waited_for_again() -> None:
    """A restarted node (a new incarnation, net.peer.restarted) is back, like a returned link."""
    now = [0.0]
    station, _, _ = station_and_fleet({}, give_up_s=5.0, clock=lambda: now[0])
    ready(station, *DRONES)
    station.handle(PeerStatus("Drone2", "lost", 3.0, 1))
    now[0] = 10.0  # silent past give_up_s
    station.wait_resolved(0.01)
    assert station.snapshot()["Drone2"].given_up
    assert station.failures == ["Drone2: silent for more than 5 s"]
    station.handle(PeerStatus("Drone2", "restarted", 0.0, 2))
    view = station.snapshot()["Drone2"]
    assert not view.given_up and view.link == "restarted" and view.silent_since is None
    assert station.failures == []
