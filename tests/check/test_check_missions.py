"""Missions built to fail each check give exactly the expected finding at the expected lines.

Homes: with no fleet file the drones stand lined up 5 m apart east (Drone1 at
east 0, Drone2 at east 5), so a drone flying FlyByY(+5) from its home reaches
the other one's home column.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from eamos.check import check_mission
from eamos.cli.main import main
from eamos.compiler import compile_file, compile_mission
from eamos.config import FleetConfig

REPO = Path(__file__).resolve().parents[2]
MISSIONS = REPO / "missions"


def check_source(source: str, **kw):
    return check_mission(compile_mission(source, "t.go"), **kw)


def line_of(source: str, text: str) -> int:
    (hit,) = [i for i, line in enumerate(source.splitlines(), 1) if text in line]
    return hit


# Drone1 flies east over Drone2's home while Drone2 flies west over Drone1's: they meet
# half way, at the same height (Takeoff(2) both) unless CLIMB says otherwise.
CROSSING = """\
var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Main() {
    PAR_Arm()
    PAR_Up()
    PAR_Cross()
    PAR_Land()
    PAR_Disarm()
}
func PAR_Arm() { Drone1.Arm(); Drone2.Arm() }
func PAR_Up() { Drone1.Takeoff(2); Drone2.Takeoff(CLIMB) }
func PAR_Cross() {
    Drone1.FlyByY(5)
    Drone2.FlyByY(-5)
}
func PAR_Land() { Drone1.Land(); Drone2.Land() }
func PAR_Disarm() { Drone1.Disarm(); Drone2.Disarm() }
"""


def test_two_drones_crossing_at_the_same_height_is_a_separation_error_at_their_lines():
    source = CROSSING.replace("CLIMB", "2")
    report = check_source(source)
    assert not report.ok
    (finding,) = report.findings
    assert finding.check == "separation" and finding.severity == "error"
    lines = {p.drone: p.line for p in finding.places}
    assert lines == {
        "Drone1": line_of(source, "Drone1.FlyByY(5)"),
        "Drone2": line_of(source, "Drone2.FlyByY(-5)"),
    }
    assert finding.line == line_of(source, "Drone1.FlyByY(5)")
    assert finding.col == 5
    # They fly the same profile in opposite directions: they meet at east 2.5, at 2 m.
    positions = dict(finding.positions)
    assert positions["Drone1"][1] == pytest.approx(2.5, abs=0.05)
    assert positions["Drone1"][2] == pytest.approx(2.0, abs=0.05)
    assert "within 0.00 m horizontally" in finding.message
    assert finding.time_s is not None and finding.time_s > 0
    assert finding.branch == report.runs[0].branch


def test_crossing_three_metres_above_the_other_passes():
    report = check_source(CROSSING.replace("CLIMB", "5"))
    assert report.ok and report.findings == ()
    # ... but not with a minimum separation above 3 m.
    strict = check_source(CROSSING.replace("CLIMB", "5"), min_separation_m=3.5)
    assert [f.check for f in strict.findings] == ["separation"]


DEADLOCK = """\
var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Main() {
    PAR_Arm()
    PAR_Up()
    PAR_Wait()
    PAR_Land()
}
func PAR_Arm() { Drone1.Arm(); Drone2.Arm() }
func PAR_Up() { Drone1.Takeoff(2); Drone2.Takeoff(4) }
func PAR_Wait() {
    WaitUntil(Drone2.X() > 1, SEQ_One)
    WaitUntil(Drone1.X() > 1, SEQ_Two)
}
func SEQ_One() { Drone1.FlyByX(2) }
func SEQ_Two() { Drone2.FlyByX(2) }
func PAR_Land() { Drone1.Land(); Drone2.Land() }
"""


def test_a_deadlock_through_two_drones_waits_names_both_waits():
    report = check_source(DEADLOCK, time_limit_s=60)
    deadlocks = [f for f in report.findings if f.check == "deadlock"]
    assert len(deadlocks) == 1
    (finding,) = deadlocks
    assert finding.severity == "error"
    first, second = line_of(DEADLOCK, "Drone2.X() > 1"), line_of(DEADLOCK, "Drone1.X() > 1")
    wait_lines = [p.line for p in finding.places if "WaitUntil" in p.label]
    assert sorted(wait_lines) == [first, second]
    assert "WaitUntil" in finding.message and "deadlock" in finding.message
    assert report.runs[0].timed_out
    # The drones are left hovering, armed: that is reported too.
    left = {f.places[0].drone for f in report.findings if f.check == "termination"}
    assert left == {"Drone1", "Drone2"}


BUSY = """\
var Drone1 Quadcopter

func SEQ_Main() {
    Drone1.Arm()
    Drone1.Takeoff(2)
    PAR_Both()
    Drone1.Land()
    Drone1.Disarm()
}
func PAR_Both() {
    Drone1.FlyByX(3)
    Drone1.FlyByY(3)
}
"""


def test_a_par_with_two_moves_of_one_drone_fails_and_leaves_it_hovering_armed():
    report = check_source(BUSY)
    by_check = {f.check: f for f in report.findings if f.severity == "error"}
    assert set(by_check) == {"action", "termination"}
    assert "busy" in by_check["action"].message
    assert by_check["action"].line in (line_of(BUSY, "FlyByX(3)"), line_of(BUSY, "FlyByY(3)"))
    term = by_check["termination"]
    assert "Drone1 is left hovering armed" in term.message
    assert term.line in (line_of(BUSY, "FlyByX(3)"), line_of(BUSY, "FlyByY(3)"))
    (pos,) = [p for d, p in term.positions if d == "Drone1"]
    assert pos[2] == pytest.approx(2.0, abs=0.15)
    # The compiler said so before any simulation.
    (warning,) = report.warnings
    assert warning.check == "compile" and "two actions at once in a PAR_" in warning.message
    assert warning.line == line_of(BUSY, "FlyByY(3)")


def _fleet(mission: str) -> FleetConfig | None:
    if mission in ("experiment_d", "experiment_d_lands"):
        return FleetConfig.load(REPO / "configs" / "experiment_d_pilot.toml")
    return None


@pytest.mark.parametrize("mission", sorted(p.stem for p in MISSIONS.glob("*.go")))
def test_every_mission_passes_or_its_findings_are_explained(mission):
    report = check_mission(compile_file(MISSIONS / f"{mission}.go"), _fleet(mission))
    if mission != "experiment_d":
        assert report.ok and report.findings == (), report.lines()
        return
    # Experiment D as printed (Listing 13) never lands D1 and D2: the check says so,
    # naming each drone's last action, on every branch of the pilot's flight it
    # explores (the loops stopping early leave D1 or D2 elsewhere; those are findings
    # of their own).  D3 lands and disarms by itself, as its autopilot would.
    assert {f.check for f in report.findings} == {"termination"}
    left = {f.message.split(" at ")[0] for f in report.findings}
    assert left == {"D1 is left hovering armed", "D2 is left hovering armed"}
    assert all("end with D" in f.message and ".Land()" in f.message for f in report.findings)
    assert report.runs[0].branch == "as simulated" and len(report.runs) == 64
    assert all(r.errors == 2 for r in report.runs)


def test_the_command_exit_codes_and_json(capsys, tmp_path):
    assert main(["check", str(MISSIONS / "experiment_b.go")]) == 0
    out = capsys.readouterr().out
    assert "run 1/1" in out and "0 error(s)" in out
    bad = tmp_path / "crossing.go"
    bad.write_text(CROSSING.replace("CLIMB", "2"))
    assert main(["check", str(bad), "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["ok"] is False and doc["errors"] == 1
    (finding,) = doc["findings"]
    assert finding["check"] == "separation"
    assert finding["line"] == line_of(CROSSING, "Drone1.FlyByY(5)")
    assert doc["runs"][0]["checked"] == [
        "actions",
        "termination",
        "deadlock",
        "separation",
        "duration",
    ]
    assert main(["check", str(bad)]) == 1
    out = capsys.readouterr().out
    assert f"{bad}:{finding['line']}:5: error: Drone1 and Drone2 come within" in out
    broken = tmp_path / "broken.go"
    broken.write_text("func SEQ_Main( {\n")
    assert main(["check", str(broken)]) == 2
    fleet = tmp_path / "fleet.toml"
    fleet.write_text('[drones.Drone1.hal]\nadapter = "sim"\nhorizontal_sped_mps = 3\n')
    assert main(["check", str(MISSIONS / "experiment_b.go"), "--fleet", str(fleet)]) == 2
    assert "horizontal_sped_mps" in capsys.readouterr().err


def test_the_picture_marks_the_conflict(tmp_path):
    import xml.etree.ElementTree as ET

    bad = tmp_path / "crossing.go"
    bad.write_text(CROSSING.replace("CLIMB", "2"))
    out = tmp_path / "check.svg"
    assert main(["check", str(bad), "--svg", str(out)]) == 1
    root = ET.fromstring(out.read_text())
    ns = "{http://www.w3.org/2000/svg}"
    assert len(root.findall(f"{ns}polyline[@class='track']")) == 2
    assert len(root.findall(f"{ns}polyline[@class='altitude']")) == 2
    assert len(root.findall(f"{ns}circle[@class='finding']")) == 2  # one per drone
    texts = [t.text or "" for t in root.iter(f"{ns}text")]
    assert any(t.startswith("separation: Drone1 and Drone2 at") for t in texts)
    assert main(["check", str(bad), "--svg", str(tmp_path / "no" / "such" / "x.svg")]) == 2


# Ends with Land(), no Disarm(): the autopilot disarms after the landing (2 s).
LANDS = """\
var Drone1 Quadcopter

func SEQ_Main() {
    Drone1.Arm()
    Drone1.Takeoff(2)
    Drone1.FlyByX(3)
    Drone1.Land()
}
"""


def test_a_mission_ending_with_land_passes_the_drone_disarming_after_its_landing():
    report = check_source(LANDS)
    assert report.ok and report.findings == (), report.lines()
    # The run ends when the mission does; the drone disarms 2 s later (not in duration).
    (run,) = report.runs
    _branch, tracks = report.tracks[0]
    last = tracks["Drone1"].points[-1]
    assert not last.armed and not last.airborne
    assert last.t_s == pytest.approx(run.duration_s + 2.0, abs=0.05)


def test_a_type_that_does_not_disarm_after_landing_leaves_the_drone_armed(tmp_path):
    fleet_file = tmp_path / "fleet.toml"
    fleet_file.write_text("[types.Quadcopter.hal]\ndisarm_after_landing_s = 0\n")
    report = check_source(LANDS, fleet=FleetConfig.load(fleet_file))
    (term,) = report.errors
    assert term.check == "termination" and term.line == line_of(LANDS, "Land()")
    assert term.message.startswith("Drone1 is left on the ground armed at (2.99, 0.00, 0.00)")
    assert "disarm_after_landing_s = 0" in term.message
    assert "end with Drone1.Disarm()" in term.message
    # A Disarm() at the end makes it pass.
    ends = LANDS.replace("Drone1.Land()", "Drone1.Land()\n    Drone1.Disarm()")
    assert check_source(ends, fleet=FleetConfig.load(fleet_file)).ok


def test_a_drone_armed_that_never_takes_off_is_left_armed():
    source = "var Drone1 Quadcopter\nfunc SEQ_Main() {\n    Drone1.Arm()\n    Drone1.Land()\n}\n"
    (term,) = check_source(source).errors
    assert term.check == "termination"
    assert term.message.startswith("Drone1 is left on the ground armed")
    assert "never took off" in term.message


def test_a_drone_left_hovering_is_found_with_a_hint_to_land():
    source = (
        "var Drone1 Quadcopter\nfunc SEQ_Main() {\n    Drone1.Arm()\n    Drone1.Takeoff(2)\n}\n"
    )
    (term,) = check_source(source).errors
    assert term.message.startswith("Drone1 is left hovering armed")
    assert "end with Drone1.Land()" in term.message


def test_landing_and_taking_off_again_after_the_disarm_needs_a_new_arm():
    # As on PX4 and ArduCopter: once disarmed after a landing, a take-off needs Arm().
    again = LANDS.replace(
        "    Drone1.Land()\n",
        "    Drone1.Land()\n    Drone1.PauseFor(5)\n    Drone1.Takeoff(2)\n    Drone1.Land()\n",
    )
    failed = [f for f in check_source(again).errors if f.check == "action"]
    assert failed and "not armed" in failed[0].message
    rearmed = again.replace("PauseFor(5)\n", "PauseFor(5)\n    Drone1.Arm()\n")
    assert check_source(rearmed).ok


# The language doc's library example (docs/mission-language.md, "Libraries").
LIBRARY = """\
package patrol

import (
\t"fleet"
\t"shapes"
)

var D1 Quadcopter
var D2 DroneType1

func SEQ_Main() {
\tfleet.PAR_TakeOff2(D1, D2, 3)
\tshapes.SEQ_Square(D1, SIDE)
\tfleet.PAR_Land2(D1, D2)
}
"""
SHAPES = REPO / "eamos" / "missions_lib" / "shapes" / "shapes.go"
FLEET = REPO / "eamos" / "missions_lib" / "fleet" / "fleet.go"


def test_findings_inside_library_blocks_name_the_library_file(tmp_path, capsys):
    # A 5 m square flies D1 over D2's home (5 m east, no fleet file): in shapes.go.
    mission = tmp_path / "patrol.go"
    mission.write_text(LIBRARY.replace("SIDE", "5"))
    report = check_mission(compile_file(mission))
    (finding,) = report.errors
    assert finding.check == "separation"
    assert Path(finding.file) == SHAPES.resolve()
    assert finding.line == line_of(SHAPES.read_text(), "d.FlyByX(-side_m)")
    d1, d2 = finding.places
    assert Path(d1.file) == SHAPES.resolve() and Path(d2.file) == FLEET.resolve()
    assert d2.line == line_of(FLEET.read_text(), "d.Takeoff(height_m)")
    assert f"(line {d1.line} of shapes.go)" in finding.message
    assert f"(line {d2.line} of fleet.go)" in finding.message
    # The text names the library file, with its line; the JSON too, for every place.
    assert main(["check", str(mission)]) == 1
    out = capsys.readouterr().out
    assert out.startswith(f"{SHAPES.resolve()}:{finding.line}:{finding.col}: error: D1 and D2")
    assert main(["check", str(mission), "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["file"] == str(mission)
    (found,) = doc["findings"]
    assert Path(found["file"]) == SHAPES.resolve() and found["line"] == finding.line
    assert [Path(p["file"]).name for p in found["places"]] == ["shapes.go", "fleet.go"]


def test_a_finding_in_the_mission_file_names_the_mission_file(capsys, tmp_path):
    mission = tmp_path / "crossing.go"
    mission.write_text(CROSSING.replace("CLIMB", "2"))
    assert main(["check", str(mission), "--json"]) == 1
    (found,) = json.loads(capsys.readouterr().out)["findings"]
    assert found["file"] == str(mission)
    assert {p["file"] for p in found["places"]} == {str(mission)}


def test_the_docs_library_example_passes_and_lands_with_the_fleet_blocks():
    report = check_mission(compile_mission(LIBRARY.replace("SIDE", "2"), "patrol.go"))
    assert report.ok and report.findings == (), report.lines()


def test_a_branch_decided_in_a_library_file_names_the_library_file(tmp_path):
    # An If on the battery inside a library block: the branch labels say which file's line.
    (tmp_path / "insp").mkdir()
    (tmp_path / "insp" / "insp.go").write_text(
        "package insp\n\n"
        "func SEQ_Look(d Quadcopter) {\n"
        "\tIf(d.Battery() > 50, SEQ_Far(d), SEQ_Near(d))\n"
        "}\n\n"
        "func SEQ_Far(d Quadcopter) { d.FlyByX(4) }\n\n"
        "func SEQ_Near(d Quadcopter) { d.FlyByX(1) }\n"
    )
    mission = tmp_path / "m.go"
    mission.write_text(
        'import "insp"\n\nvar D1 Quadcopter\n\n'
        "func SEQ_Main() {\n\tD1.Arm()\n\tD1.Takeoff(2)\n\tinsp.SEQ_Look(D1)\n\tD1.Land()\n}\n"
    )
    report = check_mission(compile_file(mission))
    assert report.ok, report.lines()
    assert sorted(run.branch for run in report.runs) == [
        "If line 4 of insp.go: else",
        "If line 4 of insp.go: then",
    ]
