"""The fleet file's [safety] section and homes: validation, geofence, ceiling, battery."""

from __future__ import annotations

from pathlib import Path

import pytest

from eamos.check import check_mission
from eamos.check.limits import inside
from eamos.compiler import compile_mission
from eamos.config import ConfigError, FleetConfig, SafetySettings

from .test_check_missions import CROSSING, line_of


def fleet(tmp_path: Path, text: str) -> FleetConfig:
    path = tmp_path / "fleet.toml"
    path.write_text(text)
    return FleetConfig.load(path)


def test_safety_and_homes_are_read(tmp_path):
    f = fleet(
        tmp_path,
        """
[safety]
min_separation_m = 3
max_altitude_m = 40
geofence_m = [[-10, -10], [-10, 10], [10, 10], [10, -10]]
battery_reserve_pct = 25
[drones.Drone1]
home_m = [1, 2]
[drones.Drone2]
home_lla = [46.6103, 14.2640]
""",
    )
    assert f.safety == SafetySettings(3.0, 40.0, ((-10, -10), (-10, 10), (10, 10), (10, -10)), 25.0)
    assert f.homes_m == {"Drone1": (1.0, 2.0)} and f.homes_lla == {"Drone2": (46.6103, 14.264)}
    assert FleetConfig.empty().safety == SafetySettings()


@pytest.mark.parametrize(
    "text,where",
    [
        ("[safety]\nmin_separation = 2\n", "safety.min_separation: unknown field (did you mean"),
        ("[safety]\nmin_separation_m = 0\n", "safety.min_separation_m: must be greater than 0"),
        ("[safety]\nmax_altitude_m = 'high'\n", "safety.max_altitude_m: must be a number"),
        ("[safety]\nbattery_reserve_pct = 120\n", "safety.battery_reserve_pct: must be between"),
        ("[safety]\ngeofence_m = [[0, 0], [1, 1]]\n", "safety.geofence_m: must be a polygon"),
        ("[safety]\ngeofence_m = [[0, 0], [1, 1], [1]]\n", "safety.geofence_m[2]: must be a list"),
        ("safety = 3\n", "safety: must be a table"),
        ("drones = 5\n", "drones: must be a table of drones"),
        ("drones = [1, 2]\n", "drones: must be a table of drones"),
        ("[drones.D1]\nhome_m = [1]\n", "drones.D1.home_m: must be a list of 2 numbers"),
        ("[drones.D1]\nhome_m = [1, true]\n", "drones.D1.home_m[1]: must be a number"),
        ("[drones.D1]\nhome_lla = [100, 0]\n", "drones.D1.home_lla: latitude -90..90"),
        ("[drones.D1]\nhome_m = [0, 0]\nhome_lla = [0, 0]\n", "drones.D1: give home_m or"),
    ],
)
def test_bad_safety_settings_are_located_errors(tmp_path, text, where):
    with pytest.raises(ConfigError) as err:
        fleet(tmp_path, text)
    assert str(err.value).startswith(f"{tmp_path / 'fleet.toml'}: {where}")


def test_homes_from_the_fleet_file_move_the_drones_apart(tmp_path):
    crossing = compile_mission(CROSSING.replace("CLIMB", "2"), "t.go")
    far = fleet(tmp_path, "[drones.Drone2]\nhome_m = [20, 5]\n")
    report = check_mission(crossing, far)
    assert report.ok, report.lines()
    assert report.settings["homes_m"] == {"Drone1": [0.0, 0.0], "Drone2": [20.0, 5.0]}
    # 5 m apart east again, given as latitude/longitude: they meet again.
    lla = fleet(
        tmp_path,
        "[drones.Drone1]\nhome_lla = [46.6103, 14.2640]\n"
        "[drones.Drone2]\nhome_lla = [46.6103, 14.26406548]\n",
    )
    report = check_mission(crossing, lla)
    assert report.settings["homes_m"]["Drone2"] == pytest.approx([0.0, 5.0], abs=0.01)
    assert [f.check for f in report.findings] == ["separation"]


# The fence is 6 m around the drones' homes: the Then branch stays inside, Else leaves.
FENCE_IF = """\
var Drone1 Quadcopter

func SEQ_Main() {
    Drone1.Arm()
    Drone1.Takeoff(2)
    If(Drone1.Battery() > 30, SEQ_Near, SEQ_Far)
    Drone1.Land()
    Drone1.Disarm()
}
func SEQ_Near() { Drone1.FlyByX(3) }
func SEQ_Far() { Drone1.FlyByX(8) }
"""


def test_a_geofence_breach_only_on_the_else_branch(tmp_path):
    f = fleet(tmp_path, "[safety]\ngeofence_m = [[-6, -6], [-6, 6], [6, 6], [6, -6]]\n")
    report = check_mission(compile_mission(FENCE_IF, "t.go"), f)
    if_line = line_of(FENCE_IF, "If(")
    (finding,) = report.findings
    assert finding.check == "geofence" and finding.severity == "error"
    assert finding.branch == f"If line {if_line}: else"
    assert finding.line == line_of(FENCE_IF, "FlyByX(8)")
    (pos,) = [p for _, p in finding.positions]
    assert pos[0] == pytest.approx(6.0, abs=1e-6)  # exactly where it crosses the edge
    assert [r.errors for r in report.runs] == [0, 1]
    assert "geofence" in report.runs[0].checked


def test_the_ceiling(tmp_path):
    f = fleet(tmp_path, "[safety]\nmax_altitude_m = 1.5\n")
    report = check_mission(compile_mission(FENCE_IF, "t.go"), f)
    assert {x.check for x in report.findings} == {"geofence"}
    assert all("above the ceiling of 1.5 m" in x.message for x in report.findings)
    assert all(x.line == line_of(FENCE_IF, "Takeoff(2)") for x in report.findings)


# Each hop takes about 8 s in the air; at 60 %/min the battery lasts two hops above 20 %.
HOPS = """\
var Drone1 Quadcopter

func SEQ_Main() {
    Drone1.Arm()
    RepeatFor(3, SEQ_Hop)
    Drone1.Disarm()
}
func SEQ_Hop() {
    Drone1.Takeoff(2)
    Drone1.FlyByX(2)
    Drone1.Land()
}
"""


def test_a_battery_that_runs_out_only_in_the_third_loop_iteration(tmp_path):
    f = fleet(
        tmp_path,
        "[safety]\nbattery_reserve_pct = 20\n"
        "[drones.Drone1.hal]\nbattery_pct = 42\ndrain_airborne_pct_per_min = 60\n",
    )
    report = check_mission(compile_mission(HOPS, "t.go"), f)
    (finding,) = report.findings
    assert finding.check == "battery"
    assert "lands with" in finding.message and "in loop iteration 3" in finding.message
    assert finding.line == line_of(HOPS, "Drone1.Land()")
    assert check_mission(compile_mission(HOPS.replace("3, SEQ", "2, SEQ"), "t.go"), f).ok


def test_point_in_polygon_on_a_concave_fence():
    u_shape = ((0, 0), (0, 10), (10, 10), (10, 7), (3, 7), (3, 3), (10, 3), (10, 0))
    assert inside(u_shape, 1, 5) and inside(u_shape, 8, 1) and not inside(u_shape, 8, 5)
    assert inside(u_shape, 0, 5)  # on an edge


LLA_MEET = """\
var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Main() {
    PAR_Arm()
    PAR_Up()
    PAR_Meet()
    PAR_Land()
    PAR_Disarm()
}
func PAR_Arm() { Drone1.Arm(); Drone2.Arm() }
func PAR_Up() { Drone1.Takeoff(3); Drone2.Takeoff(3) }
func PAR_Meet() {
    Drone1.FlyToLLA(46.6104, 14.2641, 3)
    Drone2.FlyToLLA(46.6104, 14.2641, 3)
}
func PAR_Land() { Drone1.Land(); Drone2.Land() }
func PAR_Disarm() { Drone1.Disarm(); Drone2.Disarm() }
"""


def test_flytolla_targets_are_one_place_for_every_drone_at_its_own_home(tmp_path):
    """Two drones sent to one latitude/longitude meet there, from homes 5 m apart.

    Each simulated drone stands at its home in the fleet frame, so a global
    target is the same point for both (a separation error); were both at the
    frame's origin, the targets would be 5 m apart and nothing found.
    """
    compiled = compile_mission(LLA_MEET, "meet.go")
    report = check_mission(compiled, None)
    separations = [f for f in report.findings if f.check == "separation"]
    assert separations, report.lines()
    assert {line_of(LLA_MEET, "Drone1.FlyToLLA"), line_of(LLA_MEET, "Drone2.FlyToLLA")} <= {
        p.line for p in separations[0].places
    }


def test_a_misspelt_drone_table_is_refused_by_the_check(tmp_path):
    """``[drones.Dron1]`` is a typo, not a drone: the check says so (eamos check, run, rollout)."""
    f = fleet(tmp_path, "[drones.Dron1]\nhome_m = [0, 1]\n")
    compiled = compile_mission(CROSSING.replace("CLIMB", "5"), "c.go")
    with pytest.raises(ConfigError, match=r"drones\.Dron1: not a drone of the mission.*Drone1"):
        check_mission(compiled, f)
