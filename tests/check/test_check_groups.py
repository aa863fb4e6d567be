"""`eamos check` of missions with groups and loops: it flies the expanded programs, and each
finding points at the statement inside the loop (the members are the drones Team_0 ...).

Homes: with no fleet file the members stand lined up 5 m apart east, in index order
(Team_0 at east 0, Team_1 at east 5, ...).
"""

from __future__ import annotations

from pathlib import Path

from eamos.check import check_mission
from eamos.compiler import compile_file, compile_mission

REPO = Path(__file__).resolve().parents[2]

# Every member flies 2.5 m east per index: Team[i] ends at east 7.5 i, so the loop's
# FlyByY brings neighbours within the minimum separation unless SPREAD keeps them apart.
CONVERGE = """\
var Team [4]Quadcopter

func SEQ_Main() {
    PAR_Up()
    PAR_Move()
    PAR_Down()
}
func PAR_Up() {
    for _, d := range Team {
        d.Arm()
        d.Takeoff(2)
    }
}
func PAR_Move() {
    for i, d := range Team {
        d.FlyByY(SPREAD * i)
    }
}
func PAR_Down() {
    for _, d := range Team {
        d.Land()
        d.Disarm()
    }
}
"""


def _line(source: str, text: str) -> int:
    (hit,) = [i for i, line in enumerate(source.splitlines(), 1) if text in line]
    return hit


def test_a_separation_finding_points_at_the_statement_in_the_loop() -> None:
    source = CONVERGE.replace("SPREAD", "-4")  # Team[i] flies 4 i west: towards Team[i-1]
    report = check_mission(compile_mission(source, "converge.go"))
    assert not report.ok
    found = [f for f in report.findings if f.check == "separation"]
    assert found, report.findings
    move, land = _line(source, "d.FlyByY("), _line(source, "d.Land()")
    # Neighbours meet while flying the loop's FlyByY (each pair once), then land close.
    pairs = {tuple(sorted(p.drone for p in f.places)) for f in found if f.line == move}
    assert pairs == {("Team_0", "Team_1"), ("Team_1", "Team_2"), ("Team_2", "Team_3")}
    for finding in found:
        assert {p.line for p in finding.places} <= {move, land}


def test_the_same_loop_spreading_the_members_passes() -> None:
    report = check_mission(compile_mission(CONVERGE.replace("SPREAD", "2"), "spread.go"))
    assert report.ok and report.findings == ()


def test_a_member_left_in_the_air_is_named_and_located_in_the_loop() -> None:
    source = CONVERGE.replace("SPREAD", "2").replace(
        "    for _, d := range Team {\n        d.Land()",
        "    for _, d := range Team[1:] {\n        d.Land()",
    )
    report = check_mission(compile_mission(source, "left.go"))
    (finding,) = [f for f in report.findings if f.check == "termination"]
    assert "Team_0 is left hovering armed" in finding.message
    assert finding.line == _line(source, "d.FlyByY(")


def test_the_100_drone_example_passes_the_check() -> None:
    compiled = compile_file(REPO / "missions" / "fleets" / "fleet100.go")
    report = check_mission(compiled)
    assert report.ok, [f.message for f in report.findings][:5]
    assert report.findings == ()


def test_fleet_files_name_the_members_as_the_programs_do(tmp_path: Path) -> None:
    import pytest

    from eamos.config import ConfigError, FleetConfig

    source = CONVERGE.replace("SPREAD", "2")
    compiled = compile_mission(source, "fleet.go")
    path = tmp_path / "fleet.toml"
    # Team[1]'s home 1 m from Team[0]'s: they take off too close together.
    path.write_text(
        "[drones.Team_0]\nhome_m = [0.0, 0.0]\n[drones.Team_1]\nhome_m = [0.0, 1.0]\n",
        encoding="utf-8",
    )
    report = check_mission(compiled, FleetConfig.load(path))
    found = [f for f in report.findings if f.check == "separation"]
    assert found and {p.drone for p in found[0].places} == {"Team_0", "Team_1"}
    # A table for a member the group does not have is refused, naming the members.
    path.write_text("[drones.Team_4]\nhome_m = [0.0, 0.0]\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"drones\.Team_4: not a drone of the mission"):
        check_mission(compiled, FleetConfig.load(path))
