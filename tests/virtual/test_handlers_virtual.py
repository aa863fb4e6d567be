"""Try in the virtual-time driver: a rejected action on one drone, the other's Body cancelled."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from eamos.compiler import compile_file, compile_mission
from eamos.hal.sim.settings import SimSettings
from eamos.virtual import run_virtual, sim_vehicles

REPO = Path(__file__).resolve().parents[2]
TRY_RESCUE = REPO / "missions" / "try_rescue.go"
REJECT = Path(__file__).with_name("try_reject.toml")


def fleet_settings(path: Path) -> dict[str, SimSettings]:
    doc = tomllib.loads(path.read_text())
    return {name: SimSettings.from_mapping(d["hal"]) for name, d in doc["drones"].items()}


def results(run, drone: str) -> list[tuple[str, str]]:
    return [(a.action, a.result) for a in run.drones[drone].actions]


def test_a_rejected_action_is_caught_and_the_other_drone_is_cancelled_mid_flight() -> None:
    compiled = compile_file(TRY_RESCUE)
    run = run_virtual(compiled.programs, sim_vehicles(fleet_settings(REJECT)))
    assert run.ok, run.waiting  # a caught failure is not a failure of the run
    assert results(run, "Drone2") == [
        ("Arm", "ok"),
        ("Takeoff", "ok"),
        ("FlyByY", "ok"),
        ("FlyByZ", "caught"),  # the rest of Drone2's Body (FlyByY(3)) never starts
        ("FlyToXYZ", "ok"),  # OnFailure
        ("Land", "ok"),
        ("Disarm", "ok"),
    ]
    caught = run.drones["Drone2"].actions[3]
    assert caught.reason == "rejected by vehicle; caught by the Try at line 16"
    d1 = run.drones["Drone1"].actions
    assert [(a.action, a.result) for a in d1] == [
        ("Arm", "ok"),
        ("Takeoff", "ok"),
        ("FlyByX", "cancelled"),  # mid-flight, when Drone2's climb was rejected
        ("FlyToXYZ", "ok"),
        ("Land", "ok"),
        ("Disarm", "ok"),
    ]
    leg = d1[2]
    assert leg.end == pytest.approx(caught.end, abs=0.2)
    assert 0 < leg.end - leg.start < 10  # 30 m at the simulator's speed takes far longer
    assert all(
        o.final is None or o.final.z_m == pytest.approx(0, abs=0.15) for o in run.drones.values()
    )
    # Loop-free: every external arc carried exactly one trigger (Table 7), caught or not.
    for name, outcome in run.drones.items():
        stats = compiled.programs[name].stats()
        assert (outcome.triggers_sent, outcome.triggers_received) == (
            stats["external_out"],
            stats["external_in"],
        ), name
    assert not run.drones["Drone1"].blocked and not run.drones["Drone2"].blocked


def test_without_a_failure_on_failure_is_skipped_with_every_arc_counted() -> None:
    compiled = compile_file(TRY_RESCUE)
    run = run_virtual(compiled.programs)
    assert run.ok
    assert "FlyToXYZ" not in [a.action for o in run.drones.values() for a in o.actions]
    assert [a for a, _ in results(run, "Drone2")][2:5] == ["FlyByY", "FlyByZ", "FlyByY"]
    for name, outcome in run.drones.items():
        stats = compiled.programs[name].stats()
        assert outcome.triggers_sent == stats["external_out"], name
        assert outcome.triggers_received == stats["external_in"], name


def test_the_same_mission_without_try_fails_as_before() -> None:
    source = TRY_RESCUE.read_text().replace("Try(PAR_Survey, PAR_Recover)", "PAR_Survey()")
    source = source.replace("func PAR_Recover", "func PAR_Unused")
    compiled = compile_mission(source, "no_try.go")
    run = run_virtual(compiled.programs, sim_vehicles(fleet_settings(REJECT)), time_limit_s=120)
    assert not run.ok
    assert ("FlyByZ", "failed") in results(run, "Drone2")
    assert run.drones["Drone2"].blocked


NESTED = """package m

var D1 Quadcopter

func SEQ_M() {
	D1.Arm()
	D1.Takeoff(2)
	Try(SEQ_Outer, SEQ_OuterFail)
	D1.Land()
}

func SEQ_Outer() {
	Try(SEQ_Inner, SEQ_InnerFail)
	D1.FlyByY(1)
}

func SEQ_Inner() {
	D1.FlyByX(1)
	D1.FlyByZ(1)
}

func SEQ_InnerFail() {
	D1.PauseFor(1)
}

func SEQ_OuterFail() {
	D1.PauseFor(2)
}
"""


def test_nested_try_the_innermost_catches_and_the_outer_body_goes_on() -> None:
    run = run_virtual(
        compile_mission(NESTED, "n.go").programs,
        sim_vehicles({"D1": SimSettings(reject_actions=("FlyByZ",))}),
    )
    assert run.ok, run.waiting
    assert [(a.action, a.args, a.result) for a in run.drones["D1"].actions][2:] == [
        ("FlyByX", (1.0,), "ok"),
        ("FlyByZ", (1.0,), "caught"),
        ("PauseFor", (1.0,), "ok"),  # the inner OnFailure
        ("FlyByY", (1.0,), "ok"),  # the outer Body goes on; its OnFailure is skipped
        ("Land", (), "ok"),
    ]


LOOPED = """package m

var D1 Quadcopter

func SEQ_M() {
	D1.Arm()
	D1.Takeoff(2)
	RepeatFor(3, SEQ_Round)
	D1.Land()
}

func SEQ_Round() {
	Try(SEQ_Hop, SEQ_Note)
}

func SEQ_Hop() {
	D1.FlyByX(1)
	D1.FlyByZ(1)
}

func SEQ_Note() {
	D1.PauseFor(1)
}
"""


def test_a_try_in_a_loop_catches_in_every_iteration() -> None:
    run = run_virtual(
        compile_mission(LOOPED, "l.go").programs,
        sim_vehicles({"D1": SimSettings(reject_actions=("FlyByZ",))}),
    )
    assert run.ok, run.waiting
    acts = [(a.action, a.iteration, a.result) for a in run.drones["D1"].actions]
    for i in range(3):
        assert ("FlyByZ", (i,), "caught") in acts
        assert ("PauseFor", (i,), "ok") in acts
    assert acts[-1] == ("Land", (), "ok")


FAST_DRAIN = Path(__file__).with_name("fast_drain.toml")


def test_whenever_on_battery_fires_twice_and_resumes_what_is_left_of_the_leg() -> None:
    compiled = compile_file(REPO / "missions" / "whenever_battery.go")
    run = run_virtual(compiled.programs, sim_vehicles(fleet_settings(FAST_DRAIN)))
    assert run.ok, run.waiting
    d1 = run.drones["Drone1"].actions
    dips = [a for a in d1 if a.action == "FlyByZ"]
    assert [(a.args, a.iteration) for a in dips] == [
        ((-1.0,), (0,)),
        ((1.0,), (0,)),
        ((-1.0,), (1,)),
        ((1.0,), (1,)),
    ]
    # Each firing: the outbound leg is cancelled (suspended), the Handler runs, and the leg
    # is re-issued for the rest of its 20 m (it was past 15 m: less than 5 m are left).
    for loop in (1, 2):
        legs = [a for a in d1 if a.action == "FlyByX" and a.iteration == (loop,)]
        assert [a.result for a in legs] == ["cancelled", "ok", "ok"]
        assert legs[0].reason == "suspended: a Whenever handler runs"
        assert 0 < legs[1].args[0] < 5 and legs[2].args == (-20.0,)
    assert run.drones["Drone1"].final.x_m == pytest.approx(0.0, abs=0.2)
    # Drone2 runs guarded statements but is not in the Handler: never interrupted.
    assert [(a.action, a.result) for a in run.drones["Drone2"].actions][2] == ("PauseFor", "ok")


def test_whenever_that_never_fires_changes_nothing() -> None:
    run = run_virtual(compile_file(REPO / "missions" / "whenever_battery.go").programs)
    assert run.ok
    assert "FlyByZ" not in run.drones["Drone1"].action_names()
    assert [a.result for a in run.drones["Drone1"].actions] == ["ok"] * 10


def test_abandon_skips_the_rest_of_the_block_on_both_drones() -> None:
    compiled = compile_file(REPO / "missions" / "whenever_abandon.go")
    run = run_virtual(compiled.programs, sim_vehicles(fleet_settings(FAST_DRAIN)))
    assert run.ok, run.waiting
    assert results(run, "Drone1") == [
        ("Arm", "ok"),
        ("Takeoff", "ok"),
        ("FlyByX", "ok"),
        ("FlyByY", "ok"),
        ("FlyByX", "cancelled"),  # suspended, then abandoned: never re-issued
        ("FlyToXYZ", "ok"),  # the Handler
        ("Land", "ok"),
        ("Disarm", "ok"),
    ]
    # Drone2's running leg is cancelled by the Abandon(), and the mission goes on.
    assert results(run, "Drone2") == [
        ("Arm", "ok"),
        ("Takeoff", "ok"),
        ("FlyByY", "ok"),
        ("FlyByX", "ok"),
        ("FlyByY", "cancelled"),
        ("Land", "ok"),
        ("Disarm", "ok"),
    ]
    abandon_at = run.drones["Drone1"].actions[5].end
    assert run.drones["Drone2"].actions[4].end == pytest.approx(abandon_at, abs=0.2)
    assert all(
        o.final is None or o.final.z_m == pytest.approx(0, abs=0.15) for o in run.drones.values()
    )


def test_without_the_event_the_survey_completes() -> None:
    run = run_virtual(compile_file(REPO / "missions" / "whenever_abandon.go").programs)
    assert run.ok
    assert all(a.result == "ok" for o in run.drones.values() for a in o.actions)


@pytest.mark.parametrize("name", ["try_rescue", "whenever_battery", "whenever_abandon"])
def test_the_preflight_check_runs_the_handler_missions(name: str) -> None:
    from eamos.check import check_mission
    from eamos.config import FleetConfig

    compiled = compile_file(REPO / "missions" / f"{name}.go")
    for fleet in (None, FleetConfig.load(REJECT if name == "try_rescue" else FAST_DRAIN)):
        report = check_mission(compiled, fleet)
        assert not report.errors, report.errors
        assert report.runs


WHENEVER_IN_TRY = """package m

var D1 Quadcopter
var D2 Quadcopter

func SEQ_M() {
	PAR_Up()
	Try(SEQ_Guarded, SEQ_Recover)
	PAR_Down()
}

func PAR_Up() {
	SEQ_U1()
	SEQ_U2()
}

func SEQ_U1() {
	D1.Arm()
	D1.Takeoff(2)
}

func SEQ_U2() {
	D2.Arm()
	D2.Takeoff(2)
}

func SEQ_Guarded() {
	Whenever(D1.X() > 4, SEQ_Dip)
	D1.FlyByX(10)
	D2.FlyByZ(1)
	D1.FlyByX(-10)
}

func SEQ_Dip() {
	D1.FlyByZ(-1)
	D1.FlyByZ(1)
}

func SEQ_Recover() {
	D1.FlyToXYZ(0, 0, 2)
}

func PAR_Down() {
	D1.Land()
	D2.Land()
}
"""


def test_a_failure_inside_a_guarded_block_is_caught_by_the_try_around_it() -> None:
    run = run_virtual(
        compile_mission(WHENEVER_IN_TRY, "wt.go").programs,
        sim_vehicles({"D2": SimSettings(reject_actions=("FlyByZ",))}),
        time_limit_s=300,
    )
    assert run.ok, run.waiting
    d1 = [(a.action, a.args, a.result) for a in run.drones["D1"].actions]
    assert ("FlyByZ", (-1.0,), "ok") in d1  # the Handler fired once, D1 past 4 m
    assert ("FlyToXYZ", (0.0, 0.0, 2.0), "ok") in d1  # OnFailure ran
    assert ("FlyByX", (-10.0,), "ok") not in d1  # the rest of the guarded block was skipped
    assert ("FlyByZ", (1.0,), "caught") in [
        (a.action, a.args, a.result) for a in run.drones["D2"].actions
    ]


BAD_ON_FAILURE = """package m

var D1 Quadcopter

func SEQ_M() {
	D1.Arm()
	D1.Takeoff(2)
	Try(SEQ_Body, SEQ_Fail)
	D1.Land()
	D1.Disarm()
}

func SEQ_Body() {
	D1.FlyByX(3)
	D1.FlyByX(-3)
}

func SEQ_Fail() {
	D1.FlyByZ(-10)
}
"""


def test_the_check_explores_a_failing_body_and_finds_a_bad_on_failure() -> None:
    from eamos.check import check_mission

    report = check_mission(compile_mission(BAD_ON_FAILURE, "bad.go"))
    assert [r.branch for r in report.runs] == [
        "as simulated",
        "Try line 8: Body fails at its first action (D1)",
    ]
    errors = report.errors
    assert errors and all("Body fails" in e.branch for e in errors), errors
    assert any("FlyByZ" in e.message for e in errors), errors


def test_the_check_also_runs_a_battery_handler_that_fires_at_once() -> None:
    from eamos.check import check_mission

    report = check_mission(compile_file(REPO / "missions" / "whenever_abandon.go"))
    assert [r.branch for r in report.runs] == [
        "as simulated",
        "Whenever line 19: Handler fires at once",
    ]
    assert not report.errors
    # Fired at once, the survey is abandoned at its start: a much shorter run.
    assert report.runs[1].duration_s < report.runs[0].duration_s / 2
