"""The compile warning "the same drone given two actions at once in a PAR_"."""

from __future__ import annotations

from eamos.compiler import compile_mission

HEADER = "var Drone1 Quadcopter\nvar Drone2 Quadcopter\n"


def warnings_of(body: str) -> list[tuple[str, str]]:
    compiled = compile_mission(HEADER + body, "t.go")
    return [(str(w.loc), w.message) for w in compiled.warnings]


def test_two_moves_of_one_drone_in_a_par_is_a_warning_at_the_second():
    found = warnings_of(
        "func SEQ_Main() { Drone1.Arm(); Drone1.Takeoff(2); PAR_Both(); Drone1.Land() }\n"
        "func PAR_Both() {\n    Drone1.FlyByX(3)\n    Drone1.FlyByY(3)\n}\n"
        "func SEQ_Two() { Drone2.Arm() }\n"
    )
    found = [w for w in found if "PAR_" in w[1]]
    assert found == [
        (
            "6:5",
            "the same drone given two actions at once in a PAR_: Drone1.FlyByY runs in "
            "PAR_Both together with Drone1.FlyByX (line 5); a drone makes one motion at a "
            "time, so one of them fails 'busy'",
        )
    ]


def test_through_a_called_block_too():
    found = warnings_of(
        "func PAR_Main() { SEQ_A(); Drone1.FlyByX(1); Drone2.Arm() }\n"
        "func SEQ_A() { Drone1.Arm(); Drone1.Takeoff(2) }\n"
    )
    assert [loc for loc, m in found if "two actions at once" in m] == ["3:28"]


def test_different_drones_payloads_and_control_structures_are_fine():
    assert not [
        m
        for _, m in warnings_of(
            "func PAR_Main() {\n    Drone1.Takeoff(2)\n    Drone2.Takeoff(2)\n"
            "    Drone1.TurnOnCamera()\n"
            "    WaitUntil(Drone2.Z() > 1, SEQ_Go)\n}\n"
            "func SEQ_Go() { Drone1.FlyByX(1) }\n"
        )
        if "two actions at once" in m
    ]
