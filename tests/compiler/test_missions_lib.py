"""The standard library (eamos/missions_lib/): each block flown in virtual time.

A mission imports the shipped libraries, compiles, and runs in the
virtual-time driver; each drone must end where the block says it ends.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from eamos.compiler import compile_file, compile_mission
from eamos.compiler.libraries import STANDARD_LIBRARY
from eamos.virtual import run_virtual

MISSION = """package stdlib_demo

import (
	"fleet"
	"shapes"
	"survey"
)

var D1 Quadcopter
var D2 DroneType1
var D3 DroneType3
var D4 Quadcopter

func SEQ_Main() {
	fleet.PAR_TakeOff4(D1, D2, D3, D4, 3)
	PAR_Work()
	fleet.PAR_Land4(D1, D2, D3, D4)
}

func PAR_Work() {
	shapes.SEQ_Orbit(D1, 10, 0, 4, 3)
	survey.SEQ_Lawnmower(D2, -10, 0, 8, 6, 5)
	shapes.SEQ_Square(D3, 5)
	survey.SEQ_Sweep(D4, 6, 1.5, 2)
}
"""


def _near(a: float, b: float) -> bool:
    return math.isclose(a, b, abs_tol=0.1)


def test_every_standard_library_block_flies_where_it_says(tmp_path: Path) -> None:
    path = tmp_path / "stdlib_demo.go"
    path.write_text(MISSION, encoding="utf-8")
    compiled = compile_file(path)
    run = run_virtual(compiled.programs, time_limit_s=600)
    assert run.ok, run
    finals = {d: run.drones[d].final for d in ("D1", "D2", "D3", "D4")}
    # The orbit ends on the point's north side; the survey at the far corner; the square home.
    assert (_near(finals["D1"].x_m, 14), _near(finals["D1"].y_m, 0)) == (True, True)
    assert (_near(finals["D2"].x_m, -10), _near(finals["D2"].y_m, 6)) == (True, True)
    assert (_near(finals["D3"].x_m, 0), _near(finals["D3"].y_m, 0)) == (True, True)
    # The sweep: two pairs of legs, each 2 * 1.5 m east.
    assert (_near(finals["D4"].x_m, 0), _near(finals["D4"].y_m, 6)) == (True, True)
    assert [args for a, args, _ in run.actions("D4") if a.startswith("FlyBy")] == [
        (6.0,),
        (1.5,),
        (-6.0,),
        (1.5,),
    ] * 2
    assert all(f.landed for f in finals.values())
    orbit = [args for action, args, _ in run.actions("D1") if action == "FlyToXYZ"]
    assert len(orbit) == 9  # an octagon, closed
    assert all(_near(math.hypot(x - 10, y), 4) for x, y, _ in orbit)
    assert [a for a, _, _ in run.actions("D3")] == [
        "Arm",
        "Takeoff",
        "FlyByX",
        "FlyByY",
        "FlyByX",
        "FlyByY",
        "Land",
    ]
    # Each program records the library files its own nodes come from.
    used = {
        drone: {Path(p).relative_to(STANDARD_LIBRARY).as_posix() for p, _ in prog.libraries}
        for drone, prog in compiled.programs.items()
    }
    assert used == {
        "GCS": set(),
        "D1": {"fleet/fleet.go", "shapes/shapes.go"},
        "D2": {"fleet/fleet.go", "survey/survey.go"},
        "D3": {"fleet/fleet.go", "shapes/shapes.go"},
        "D4": {"fleet/fleet.go", "survey/survey.go"},
    }


PACKAGES = sorted(p.name for p in STANDARD_LIBRARY.iterdir() if p.is_dir() and p.name[0] != "_")


@pytest.mark.parametrize("package", PACKAGES)
def test_each_library_compiles_without_warnings(package: str) -> None:
    source = f'import "{package}"\n\nfunc SEQ_Main() {{\n\tD1.Arm()\n}}\n'
    compiled = compile_mission(source, "<mission>")
    assert [d for d in compiled.warnings if d.loc.file] == []
