"""Branch exploration: conditions the simulation cannot know are taken both ways (or early).

A battery's real charge, and a drone flown by a person, are unknowable; a
drone's own position in the simulation is not.
"""

from __future__ import annotations

from eamos.check import check_mission
from eamos.check.branches import ChoicePoint, other_way
from eamos.compiler import compile_mission

# Drone1 crosses Drone2's path only on the Else branch (battery at most 50 %).
IF_BATTERY = """\
var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Main() {
    PAR_Arm()
    PAR_Up()
    If(Drone1.Battery() > 50, SEQ_Stay, SEQ_Cross)
    PAR_Land()
    PAR_Disarm()
}
func PAR_Arm() { Drone1.Arm(); Drone2.Arm() }
func PAR_Up() { Drone1.Takeoff(2); Drone2.Takeoff(2) }
func SEQ_Stay() { Drone1.FlyByX(3) }
func SEQ_Cross() { Drone1.FlyByY(5) }
func PAR_Land() { Drone1.Land(); Drone2.Land() }
func PAR_Disarm() { Drone1.Disarm(); Drone2.Disarm() }
"""


def line_of(source: str, text: str) -> int:
    (hit,) = [i for i, line in enumerate(source.splitlines(), 1) if text in line]
    return hit


def test_an_if_on_a_battery_is_taken_both_ways_and_the_finding_names_the_branch():
    report = check_mission(compile_mission(IF_BATTERY, "t.go"))
    if_line = line_of(IF_BATTERY, "If(")
    assert [r.branch for r in report.runs] == [
        f"If line {if_line}: then",
        f"If line {if_line}: else",
    ]
    assert [r.errors for r in report.runs] == [0, 1]
    (finding,) = report.findings
    assert finding.check == "separation"
    assert finding.branch == f"If line {if_line}: else"
    assert finding.line == line_of(IF_BATTERY, "Drone1.FlyByY(5)")
    assert report.unexplored == 0


def test_a_condition_on_a_position_the_simulation_knows_is_not_explored():
    source = IF_BATTERY.replace("Drone1.Battery() > 50", "Drone1.Z() > 1")
    report = check_mission(compile_mission(source, "t.go"))
    assert [r.branch for r in report.runs] == ["as simulated"]
    assert report.ok


WAIT_BATTERY = """\
var Drone1 Quadcopter

func SEQ_Main() {
    Drone1.Arm()
    Drone1.Takeoff(2)
    WaitUntil(Drone1.Battery() < 20, SEQ_Home)
    Drone1.Disarm()
}
func SEQ_Home() { Drone1.Land() }
"""


def test_a_wait_on_a_battery_ends_early_or_as_simulated_and_the_run_count_is_bounded():
    report = check_mission(compile_mission(WAIT_BATTERY, "t.go"), time_limit_s=60)
    wait_line = line_of(WAIT_BATTERY, "WaitUntil")
    assert [r.branch for r in report.runs] == [
        "as simulated",
        f"WaitUntil line {wait_line}: wait ends at once",
    ]
    # As simulated the battery does not fall below 20 % within the limit: a deadlock.
    assert report.runs[0].timed_out and not report.runs[1].timed_out
    (deadlock,) = [f for f in report.findings if f.check == "deadlock"]
    assert deadlock.line == wait_line and deadlock.branch == "as simulated"
    assert report.runs[1].errors == 0
    bounded = check_mission(compile_mission(WAIT_BATTERY, "t.go"), time_limit_s=60, max_runs=1)
    assert len(bounded.runs) == 1 and bounded.unexplored == 1
    assert "1 more not explored" in bounded.lines()[-1]


def test_the_other_way_of_each_kind_of_decision():
    assert other_way("if", "if", True) is False
    assert other_way("wait_until", "wait", False) is True  # ends the wait at once
    assert other_way("wait_until", "wait", True) is None  # already ends it
    assert other_way("repeat_while", "loop", True) is False  # stops the loop
    assert other_way("do_while", "do", True) is False  # skips Body
    assert other_way("do_until", "do", True) is None
    point = ChoicePoint("D3", "n4", "repeat_while", 12, 2, "loop", 3, 1, False)
    assert point.label() == "RepeatWhile line 12: loop stops before iteration 4"
