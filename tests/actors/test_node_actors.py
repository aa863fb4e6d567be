"""Node actors with the fake adapter: order, forks and joins, every control structure,
interruption, loops, duplicates, failure and abort.

Each test runs a real mission (compiled from text) on real runtimes and real
ZeroMQ sockets (inproc); only the vehicles are fakes.
"""

from __future__ import annotations

import itertools

import pytest

from eamos.actors.messages import Trigger
from eamos.hal.api import ActionResult
from eamos.hal.fake import FakeAdapter

from .fleet_harness import WAIT_S, make_fleet


@pytest.fixture
def fleets():
    made = []

    def build(source, adapters=None, auto=True):
        fleet = make_fleet(source, adapters, auto=auto)
        made.append(fleet)
        return fleet

    yield build
    for fleet in made:
        fleet.close()


def run(fleets, source, adapters=None, auto=True):
    fleet = fleets(source, adapters, auto)
    fleet.start()
    assert fleet.wait_resolved(WAIT_S), f"unresolved: {fleet.station.unresolved()}"
    fleet.finish()
    return fleet


def started(fleet, drone):
    return [a["start"] for a in fleet.reports[drone]["actions"]]


def test_sequence_runs_in_order_and_counts_triggers(fleets):
    fleet = run(
        fleets,
        """
func SEQ_Main() {
    D1.Arm()
    D1.Takeoff(1.5)
    D1.FlyByX(1)
    D1.Land()
}""",
    )
    assert fleet.actions("D1") == [
        ("Arm()", "ok"),
        ("Takeoff(1.5)", "ok"),
        ("FlyByX(1)", "ok"),
        ("Land()", "ok"),
    ]
    acts = fleet.reports["D1"]["actions"]
    assert all(a["end"] <= b["start"] for a, b in itertools.pairwise(acts))
    report = fleet.reports["D1"]
    assert report["ok"] and report["triggers_received"] == report["external_in"] == 1


def test_fork_and_join_across_drones(fleets):
    fleet = run(
        fleets,
        """
func SEQ_Main() {
    PAR_Both()
    D3.Land()
}
func PAR_Both() {
    D1.TurnOn()
    D2.TurnOn()
}""",
    )
    land = fleet.reports["D3"]["actions"][0]
    ends = [fleet.reports[d]["actions"][0]["end"] for d in ("D1", "D2")]
    assert land["start"] >= max(ends)
    for name in ("D1", "D2", "D3"):
        r = fleet.reports[name]
        assert (
            r["triggers_sent"] == r["external_out"] and r["triggers_received"] == r["external_in"]
        )


@pytest.mark.parametrize(("battery", "expected"), [(80, "TurnOnCamera()"), (20, "Land()")])
def test_if_takes_one_branch_and_joins(fleets, battery, expected):
    fake = FakeAdapter("D1", auto=True)
    fleet = fleets(
        """
func SEQ_Main() {
    D1.TurnOn()
    If(D1.Battery() > 50, SEQ_Then, SEQ_Else)
    D1.Calibrate()
}
func SEQ_Then() { D1.TurnOnCamera() }
func SEQ_Else() { D1.Land() }""",
        {"D1": fake},
    )
    fake.push_telemetry(battery_pct=battery)
    fleet.start()
    assert fleet.wait_resolved(WAIT_S)
    fleet.finish()
    assert [a for a, _ in fleet.actions("D1")] == ["TurnOn()", expected, "Calibrate()"]
    report = fleet.reports["D1"]
    assert report["triggers_received"] == report["external_in"]


def test_wait_until_reacts_to_telemetry(fleets):
    d1 = FakeAdapter("D1", auto=True)
    fleet = fleets(
        """
var D1 Quadcopter
func SEQ_Main() {
    D2.TurnOn()
    WaitUntil(D1.Z() > 1, SEQ_Go)
}
func SEQ_Go() { D2.FlyByX(1) }""",
        {"D1": d1, "D2": FakeAdapter("D2", auto=True)},
    )
    fleet.start()
    d2 = fleet.adapters["D2"]
    d2.wait_started("TurnOn", WAIT_S)
    # The wait lives on D1 (the drone it reads); nothing moves until its Z changes.
    assert not fleet.wait_resolved(0.5)
    assert [c.action for c in d2.calls_of("run")] == ["TurnOn"]
    d1.push_telemetry(z_m=2.0)
    assert fleet.wait_resolved(WAIT_S)
    fleet.finish()
    assert fleet.actions("D2") == [("TurnOn()", "ok"), ("FlyByX(1)", "ok")]


def test_pause_until_and_pause_while(fleets):
    d1 = FakeAdapter("D1", auto=True)
    fleet = fleets(
        """
func SEQ_Main() {
    D1.TurnOn()
    D1.PauseUntil(D1.Battery() < 90)
    D1.Calibrate()
    PauseWhile(D1.Armed())
    D1.PreFlightCheck()
}""",
        {"D1": d1},
    )
    d1.push_telemetry(armed=True)
    fleet.start()
    d1.wait_started("TurnOn", WAIT_S)
    assert not fleet.wait_resolved(0.5)
    d1.push_telemetry(battery_pct=80)
    d1.wait_started("Calibrate", WAIT_S)
    assert not fleet.wait_resolved(0.5)
    d1.push_telemetry(armed=False)
    assert fleet.wait_resolved(WAIT_S)
    fleet.finish()
    assert [a for a, _ in fleet.actions("D1")] == ["TurnOn()", "Calibrate()", "PreFlightCheck()"]


def test_repeat_for_runs_body_n_times_with_distinct_iterations(fleets):
    fleet = run(
        fleets,
        """
func SEQ_Main() {
    RepeatFor(3, SEQ_Body)
    D1.Land()
}
func SEQ_Body() {
    D1.FlyByX(1)
    D2.FlyByX(1)
}""",
    )
    d1 = fleet.reports["D1"]["actions"]
    assert [a["action"] for a in d1] == ["FlyByX"] * 3 + ["Land"]
    assert [a["iteration"] for a in d1[:3]] == [[0], [1], [2]]
    assert [a["iteration"] for a in fleet.reports["D2"]["actions"]] == [[0], [1], [2]]


def test_repeat_while_stops_when_condition_changes(fleets):
    d1 = FakeAdapter("D1")
    fleet = fleets(
        """
func SEQ_Main() {
    RepeatWhile(D1.Battery() > 50, SEQ_Body, SEQ_Home)
}
func SEQ_Body() { D1.FlyByX(1) }
func SEQ_Home() { D1.Land() }""",
        {"D1": d1},
        auto=False,
    )
    fleet.start()
    d1.finish(d1.wait_started("FlyByX", WAIT_S, count=1))
    d1.finish(d1.wait_started("FlyByX", WAIT_S, count=2))
    h3 = d1.wait_started("FlyByX", WAIT_S, count=3)
    d1.push_telemetry(battery_pct=40)  # during the 3rd iteration: it still completes
    d1.finish(h3)
    d1.finish(d1.wait_started("Land", WAIT_S))
    assert fleet.wait_resolved(WAIT_S)
    fleet.finish()
    assert [a for a, _ in fleet.actions("D1")] == ["FlyByX(1)"] * 3 + ["Land()"]


def test_repeat_until_abandons_a_wait_when_its_condition_ends_the_loop(fleets):
    # Experiment D's shape: the loop body waits for a condition; when the loop's own
    # condition ends the loop, the waiting body is abandoned and Exit runs.
    d3 = FakeAdapter("D3", auto=True)
    fleet = fleets(
        """
func SEQ_Main() {
    RepeatUntil(D3.X() > 30, SEQ_Body, SEQ_Exit)
}
func SEQ_Body() { WaitUntil(D3.Y() > 5, SEQ_Move) }
func SEQ_Move() { D1.FlyByX(0.2) }
func SEQ_Exit() { D3.Land() }""",
        {"D3": d3, "D1": FakeAdapter("D1", auto=True)},
    )
    d3.push_telemetry(x_m=0.0, y_m=0.0)
    fleet.start()
    assert not fleet.wait_resolved(0.5)
    d3.push_telemetry(x_m=40.0)
    assert fleet.wait_resolved(WAIT_S)
    fleet.finish()
    assert fleet.actions("D1") == []
    assert fleet.actions("D3") == [("Land()", "ok")]


def test_do_while_interrupts_running_action_and_skips_rest_then_runs_exit(fleets):
    d1 = FakeAdapter("D1")
    fleet = fleets(
        """
func SEQ_Main() {
    D1.Takeoff(2)
    DoWhile(D1.Battery() > 30, SEQ_Patrol, SEQ_Home)
    D1.Disarm()
}
func SEQ_Patrol() {
    D1.FlyByX(10)
    D1.FlyByY(10)
}
func SEQ_Home() { D1.Land() }""",
        {"D1": d1},
        auto=False,
    )
    fleet.start()
    d1.finish(d1.wait_started("Takeoff", WAIT_S))
    d1.wait_started("FlyByX", WAIT_S)
    d1.push_telemetry(battery_pct=20)
    d1.finish(d1.wait_started("Land", WAIT_S))
    d1.finish(d1.wait_started("Disarm", WAIT_S))
    assert fleet.wait_resolved(WAIT_S)
    fleet.finish()
    assert fleet.actions("D1") == [
        ("Takeoff(2)", "ok"),
        ("FlyByX(10)", "cancelled"),
        ("Land()", "ok"),
        ("Disarm()", "ok"),
    ]
    assert [c.action for c in d1.calls_of("cancel")] == ["FlyByX"]
    assert "FlyByY" not in [c.action for c in d1.calls_of("run")]


def test_do_until_completed_body_skips_exit(fleets):
    fleet = run(
        fleets,
        """
func SEQ_Main() {
    DoUntil(D1.Battery() < 10, SEQ_Work, SEQ_Home)
    D1.Calibrate()
}
func SEQ_Work() { D1.FlyByX(1) }
func SEQ_Home() { D1.Land() }""",
    )
    assert [a for a, _ in fleet.actions("D1")] == ["FlyByX(1)", "Calibrate()"]


def test_do_interrupt_reaches_other_drones(fleets):
    d1 = FakeAdapter("D1", auto=True)
    d2 = FakeAdapter("D2")
    fleet = fleets(
        """
var D1 Quadcopter
func SEQ_Main() {
    DoWhile(D1.Battery() > 30, SEQ_Body)
    D2.Land()
}
func SEQ_Body() {
    D2.FlyByX(50)
    D2.FlyByY(50)
}""",
        {"D1": d1, "D2": d2},
        auto=False,
    )
    fleet.start()
    d2.wait_started("FlyByX", WAIT_S)
    d1.push_telemetry(battery_pct=10)
    d2.finish(d2.wait_started("Land", WAIT_S))
    assert fleet.wait_resolved(WAIT_S)
    fleet.finish()
    assert fleet.actions("D2") == [("FlyByX(50)", "cancelled"), ("Land()", "ok")]


def test_duplicate_trigger_to_a_node_is_ignored(fleets):
    d1 = FakeAdapter("D1")
    fleet = fleets(
        """
func SEQ_Main() {
    D1.Arm()
    D1.TurnOn()
}""",
        {"D1": d1},
        auto=False,
    )
    fleet.start()
    d1.finish(d1.wait_started("Arm", WAIT_S))
    d1.wait_started("TurnOn", WAIT_S)
    runtime = fleet.runtimes["D1"]
    turn_on = next(n.key for n in runtime.program.native_nodes() if n.action == "TurnOn")
    arm = next(n.key for n in runtime.program.native_nodes() if n.action == "Arm")
    runtime.nodes[turn_on].tell(Trigger(arm, turn_on, (), "done"))  # a duplicate
    d1.finish("TurnOn")
    assert fleet.wait_resolved(WAIT_S)
    assert [c.action for c in d1.calls_of("run")] == ["Arm", "TurnOn"]


def test_failed_action_blocks_dependents_but_not_independent_drones(fleets):
    fleet = run(
        fleets,
        """
func PAR_Main() {
    SEQ_One()
    SEQ_Two()
}
func SEQ_One() {
    D1.Takeoff(1)
    D1.FlyByX(1)
}
func SEQ_Two() {
    D2.Takeoff(1)
    D2.FlyByX(1)
    D2.Land()
}""",
        {
            "D1": FakeAdapter(
                "D1", auto=True, results={"Takeoff": ActionResult("failed", "rejected")}
            )
        },
    )
    assert fleet.actions("D1") == [("Takeoff(1)", "failed")]
    assert not fleet.reports["D1"]["ok"] and fleet.reports["D1"]["blocked_nodes"]
    assert fleet.actions("D2") == [("Takeoff(1)", "ok"), ("FlyByX(1)", "ok"), ("Land()", "ok")]
    assert fleet.reports["D2"]["ok"]


def test_abort_cancels_the_running_action_and_lands(fleets):
    d1 = FakeAdapter("D1")
    fleet = fleets(
        """
func SEQ_Main() {
    D1.Takeoff(1)
    D1.FlyByX(100)
    D1.FlyByY(100)
}""",
        {"D1": d1},
        auto=False,
    )
    fleet.start()
    d1.finish(d1.wait_started("Takeoff", WAIT_S))
    d1.wait_started("FlyByX", WAIT_S)
    fleet.station.abort("test")
    d1.wait_for(lambda f: any(c.method == "abort" for c in f.calls), WAIT_S)
    assert "FlyByY" not in [c.action for c in d1.calls_of("run")]


def test_two_runtimes_of_one_drone_in_one_process_are_independent(fleets):
    a = run(fleets, "func SEQ_M() { D1.TurnOn() }")
    b = run(fleets, "func SEQ_M() { D1.TurnOn()\n D1.Calibrate() }")
    assert len(a.reports["D1"]["actions"]) == 1 and len(b.reports["D1"]["actions"]) == 2
