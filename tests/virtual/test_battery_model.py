"""The simulated battery drains with flight time and load: a battery If can take its Else.

Issue 14: with the old 1 % per mission, ``If(D1.Battery() > 90, ...)`` always
took Then in simulation.  The model (hover + speed + climb, docs/safety.md)
makes a long flight reach the Else branch, and a short one not.
"""

from __future__ import annotations

import pytest

from eamos.compiler import compile_mission
from eamos.virtual import run_virtual

MISSION = """\
var D1 Quadcopter

func SEQ_Main() {
    D1.Arm()
    D1.Takeoff(5)
    RepeatFor(LAPS, SEQ_Lap)
    If(D1.Battery() > 90, SEQ_Full, SEQ_Low)
    D1.Land()
    D1.Disarm()
}
func SEQ_Lap() { D1.FlyByX(40); D1.FlyByX(-40) }
func SEQ_Full() { D1.FlyByZ(1) }
func SEQ_Low() { D1.FlyByZ(-1) }
"""


@pytest.mark.parametrize("laps,branch", [(1, "FlyByZ(1)"), (8, "FlyByZ(-1)")])
def test_a_long_flight_takes_the_low_battery_branch(laps: int, branch: str) -> None:
    run = run_virtual(compile_mission(MISSION.replace("LAPS", str(laps)), "b.go").programs)
    assert not run.timed_out
    names = [f"{a}({', '.join(f'{x:g}' for x in args)})" for a, args, _ in run.actions("D1")]
    assert branch in names
    final = run.drones["D1"].final
    assert final is not None
    # 8 laps of 80 m at 2 m/s: about 6 minutes in the air at 4-5 % a minute.
    if laps == 8:
        assert 60.0 < final.battery_pct < 80.0
    else:
        assert final.battery_pct > 90.0
