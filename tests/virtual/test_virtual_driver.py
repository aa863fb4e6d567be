"""The synchronous virtual-time driver: whole missions in one thread, in milliseconds.

Every control structure runs here on the simulator's pure core; what the
driver must report (records, resolutions, final states, what still waits at
the time limit) is checked on missions from ``missions/`` and small ones.
"""

from __future__ import annotations

import time
import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from eamos.compiler import compile_file, compile_mission
from eamos.hal.api import ActionHandle, ActionResult, Telemetry
from eamos.hal.sim.settings import SimSettings
from eamos.program.uniform import Command
from eamos.virtual import STEP_S, VirtualMission, run_virtual, sim_vehicles

REPO = Path(__file__).resolve().parents[2]
MISSIONS = REPO / "missions"
EVERY_STRUCTURE = Path(__file__).with_name("every_structure.go")
LOOP_FREE = {
    "experiment_a",
    "experiment_b",
    "experiment_c",
    "listing01_demo",
    "inspection_if",
    "relay_wait",
}
CPU_BUDGET_S = 1.0  # per mission; they take milliseconds (experiment D about 0.1 s)


def pilot_settings() -> dict[str, SimSettings]:
    doc = tomllib.loads((REPO / "configs" / "experiment_d_pilot.toml").read_text())
    return {name: SimSettings.from_mapping(d["hal"]) for name, d in doc["drones"].items()}


def settings_for(mission: str) -> dict[str, SimSettings]:
    # Experiment D's D3 is flown by a scripted pilot (its variant that lands everyone too).
    return pilot_settings() if mission in ("experiment_d", "experiment_d_lands") else {}


def run_source(source: str, settings: dict[str, SimSettings] | None = None, **kw: Any):
    return run_virtual(compile_mission(source, "t.go").programs, sim_vehicles(settings), **kw)


def names(run, drone: str) -> list[str]:
    return [f"{a}({', '.join(f'{x:g}' for x in args)})" for a, args, _ in run.actions(drone)]


@pytest.mark.parametrize(
    "mission", [*sorted(p.stem for p in MISSIONS.glob("*.go")), "every_structure"]
)
def test_every_mission_resolves_ok_in_milliseconds(mission):
    path = EVERY_STRUCTURE if mission == "every_structure" else MISSIONS / f"{mission}.go"
    compiled = compile_file(path)
    started = time.process_time()
    run = run_virtual(compiled.programs, sim_vehicles(settings_for(mission)))
    cpu_s = time.process_time() - started
    assert run.ok, run.waiting
    assert cpu_s < CPU_BUDGET_S, cpu_s
    for name, outcome in run.drones.items():
        assert outcome.all_resolved and outcome.ok, name
        assert all(a.result in ("ok", "cancelled") for a in outcome.actions)
        if outcome.final is not None and not (mission == "experiment_d" and name in ("D1", "D2")):
            assert outcome.final.z_m == pytest.approx(0.0, abs=0.15), name
            # Landed, and disarmed: by Disarm(), or by itself 2 s after its landing.
            assert outcome.final.landed and not outcome.final.armed, name
        if mission in LOOP_FREE:
            stats = compiled.programs[name].stats()
            assert outcome.triggers_sent == stats["external_out"], name
            assert outcome.triggers_received == stats["external_in"], name


def test_every_structure_gives_the_expected_action_order():
    run = run_virtual(compile_file(EVERY_STRUCTURE).programs)
    assert names(run, "GCS") == ["PauseFor(1)"]
    assert names(run, "Drone1") == [
        "Arm()",
        "Takeoff(3)",
        "TurnOnCamera()",  # If: then
        "FlyByY(1)",  # RepeatFor(2)
        "FlyByY(1)",
        "FlyToXYZ(0, 0, 3)",
        "FlyByX(2)",  # DoUntil: the third move is interrupted, Exit runs
        "FlyByX(2)",
        "FlyByX(2)",
        "PauseFor(1)",
        "FlyToXYZ(0, 0, 3)",
        "FlyByY(4)",  # PauseWhile until Drone2 is east
        "FlyToXYZ(0, 0, 3)",
        "Land()",
        "Disarm()",
    ]
    assert [r for *_, r in run.actions("Drone1")][6:9] == ["ok", "ok", "cancelled"]
    assert names(run, "Drone2") == [
        "Arm()",
        "Takeoff(5)",
        "TurnOnCamera()",  # If: else
        "FlyByY(2)",  # RepeatUntil Y > 3: two steps
        "FlyByY(2)",
        "FlyToXYZ(0, 0, 5)",
        "FlyByX(1)",  # RepeatWhile X < 1.5: two steps
        "FlyByX(1)",
        "FlyToXYZ(0, 0, 5)",
        "FlyByZ(-1)",  # DoWhile: Body completes, Exit (Land) skipped
        "FlyByY(4)",  # WaitUntil
        "FlyToXYZ(0, 0, 4)",  # WaitWhile
        "Land()",
        "Disarm()",
    ]
    # The ground station's pause comes first: nothing flies before it ends.
    (pause,) = run.drones["GCS"].actions
    assert pause.end == pytest.approx(1.0) and run.drones["Drone1"].actions[0].start >= pause.end


def test_experiment_b_happens_before_in_virtual_time():
    run = run_virtual(compile_file(MISSIONS / "experiment_b.go").programs)
    d1, d2 = run.drones["Drone1"].actions, run.drones["Drone2"].actions
    assert (
        [a.action for a in d1]
        == [a.action for a in d2]
        == [
            "Arm",
            "Takeoff",
            "FlyByX",
            "FlyByY",
            "FlyByX",
            "FlyByY",
            "FlyByZ",
            "Land",
            "Disarm",
        ]
    )
    assert d1[0].end <= d2[0].start
    assert d1[1].start < d2[1].end and d2[1].start < d1[1].end
    for side in range(2, 6):
        assert max(d1[side].end, d2[side].end) <= min(d1[side + 1].start, d2[side + 1].start)
    assert d1[6].end <= d2[6].start
    for outcome in (run.drones["Drone1"], run.drones["Drone2"]):
        final = outcome.final
        assert abs(final.x_m) < 0.2 and abs(final.y_m) < 0.2 and not final.armed


def test_experiment_d_pilot_ends_the_loops_and_lands_outside():
    run = run_virtual(
        compile_file(MISSIONS / "experiment_d.go").programs, sim_vehicles(pilot_settings())
    )
    assert run.ok
    for drone in ("D1", "D2"):
        moves = {args[0] for a, args, _ in run.actions(drone) if a == "FlyByX"}
        assert moves == {0.2, -0.2}, drone
    assert run.drones["D3"].final.x_m == pytest.approx(40.0, abs=0.5)
    assert run.actions("D3")[-1][0] == "Land"


@pytest.mark.parametrize(("battery", "expected"), [(80.0, "TurnOnCamera()"), (20.0, "Land()")])
def test_if_takes_one_branch_and_joins(battery, expected):
    run = run_source(
        """
func SEQ_Main() {
    D1.TurnOn()
    If(D1.Battery() > 50, SEQ_Then, SEQ_Else)
    D1.Calibrate()
}
func SEQ_Then() { D1.TurnOnCamera() }
func SEQ_Else() { D1.Land() }""",
        {"D1": SimSettings(battery_pct=battery)},
    )
    assert run.ok and names(run, "D1") == ["TurnOn()", expected, "Calibrate()"]


def test_repeat_for_runs_body_n_times_with_distinct_iterations():
    run = run_source(
        """
func SEQ_Main() {
    RepeatFor(3, SEQ_Body)
    D1.Calibrate()
}
func SEQ_Body() {
    D1.TurnOn()
    D2.TurnOn()
}"""
    )
    assert [a.iteration for a in run.drones["D1"].actions] == [(0,), (1,), (2,), ()]
    assert [a.iteration for a in run.drones["D2"].actions] == [(0,), (1,), (2,)]


def test_do_interrupt_reaches_other_drones_and_cancels_their_actions():
    run = run_source(
        """
func SEQ_Main() {
    PAR_Arm()
    PAR_Up()
    DoWhile(D1.Z() < 3, PAR_Body)
    D2.Land()
}
func PAR_Arm() {
    D1.Arm()
    D2.Arm()
}
func PAR_Up() {
    D1.Takeoff(1)
    D2.Takeoff(1)
}
func PAR_Body() {
    D1.FlyByZ(5)
    SEQ_Far()
}
func SEQ_Far() {
    D2.FlyByX(50)
    D2.FlyByY(50)
}"""
    )
    assert run.ok
    assert [(a, r) for a, _, r in run.actions("D1")][-1] == ("FlyByZ", "cancelled")
    assert [(a, r) for a, _, r in run.actions("D2")][2:] == [
        ("FlyByX", "cancelled"),
        ("Land", "ok"),
    ]


INDEPENDENT = """
func PAR_Main() {
    SEQ_One()
    SEQ_Two()
}
func SEQ_One() {
    D1.Arm()
    D1.Takeoff(1)
    D1.FlyByX(1)
}
func SEQ_Two() {
    D2.Arm()
    D2.Takeoff(1)
    D2.Land()
}"""


def test_failed_action_blocks_dependents_but_not_independent_drones():
    run = run_source(INDEPENDENT, {"D1": SimSettings(reject_actions=("Takeoff",))})
    d1, d2 = run.drones["D1"], run.drones["D2"]
    assert [(a.action, a.result) for a in d1.actions] == [("Arm", "ok"), ("Takeoff", "failed")]
    assert "rejected" in d1.actions[-1].reason
    assert d1.all_resolved and not d1.ok and d1.blocked
    assert d2.ok and [a.result for a in d2.actions] == ["ok"] * 3
    assert not run.ok and not run.timed_out


def test_time_limit_says_which_nodes_still_wait_and_for_what():
    started = time.process_time()
    run = run_source(
        "func SEQ_M() {\n D1.TurnOn()\n D1.PauseUntil(D1.Z() > 100)\n D1.Calibrate()\n}",
        time_limit_s=60.0,
    )
    assert time.process_time() - started < CPU_BUDGET_S
    assert run.timed_out and not run.ok
    assert run.duration_s == pytest.approx(60.0)
    assert names(run, "D1") == ["TurnOn()"]
    waiting = {w.label: w.why for w in run.waiting if w.drone == "D1"}
    assert "D1.Z() > 100" in waiting["PauseUntil D1.Z() > 100"]
    assert waiting["Calibrate()"] == "never triggered" or "waits for" in waiting["Calibrate()"]


def test_a_ground_station_only_mission_jumps_to_its_pause_end():
    run = run_source("func SEQ_M() { PauseFor(30) }")
    assert run.ok and run.steps == 1 and run.duration_s == pytest.approx(30.0)


def test_runs_are_deterministic():
    programs = compile_file(EVERY_STRUCTURE).programs
    assert run_virtual(programs) == run_virtual(programs)


def test_a_mission_runs_once():
    mission = VirtualMission(compile_mission("func SEQ_M() { D1.TurnOn() }", "t.go").programs)
    mission.run()
    with pytest.raises(RuntimeError, match="runs once"):
        mission.run()


class InstantVehicle:
    """A vehicle of our own: every action ends ok at the next step; it jumps to targets."""

    def __init__(self, drone: str, clock) -> None:
        self.drone = drone
        self.clock = clock
        self.z = 0.0
        self.queue: list[tuple[Command, Any]] = []
        self.commands: list[str] = []

    def sample(self) -> Telemetry:
        return Telemetry(self.drone, self.clock(), 0.0, 0.0, self.z, 0.0, 0.0, self.z, 90.0, True)

    def start(self) -> Telemetry:
        return self.sample()

    def run(self, command: Command, done) -> ActionHandle:
        self.queue.append((command, done))
        return ActionHandle(command.action, command.args)

    def cancel(self, handle: ActionHandle) -> None:
        pass

    def abort(self) -> None:
        pass

    def step(self):
        finished = []
        for command, done in self.queue:
            self.commands.append(command.action)
            if command.action == "Takeoff":
                self.z = command.args[0]
            finished.append((done, ActionResult("ok")))
        self.queue.clear()
        return finished, ([self.sample()] if finished else [])

    def state(self) -> float:
        return self.z


def test_vehicles_are_injectable():
    made: dict[str, InstantVehicle] = {}

    def factory(drone: str, clock) -> InstantVehicle:
        made[drone] = InstantVehicle(drone, clock)
        return made[drone]

    source = (
        "func SEQ_M() {\n D1.Takeoff(4)\n WaitUntil(D1.Z() > 3, SEQ_Go)\n}\n"
        "func SEQ_Go() { D2.TurnOn() }"
    )
    run = run_virtual(compile_mission(source, "t.go").programs, factory)
    assert run.ok
    assert made["D1"].commands == ["Takeoff"] and made["D2"].commands == ["TurnOn"]
    assert run.drones["D1"].final == 4.0
    assert run.duration_s == pytest.approx(2 * STEP_S)


@settings(max_examples=15, deadline=None)
@given(st.integers(min_value=0, max_value=4), st.integers(min_value=0, max_value=3))
def test_nested_repeat_for_runs_the_product_of_counts(outer, inner):
    run = run_source(
        f"func SEQ_M() {{\n RepeatFor({outer}, SEQ_Outer)\n D1.Calibrate()\n}}\n"
        f"func SEQ_Outer() {{\n D2.TurnOn()\n RepeatFor({inner}, SEQ_Inner)\n}}\n"
        "func SEQ_Inner() { D1.TurnOnCamera() }"
    )
    assert run.ok
    assert [a.iteration for a in run.drones["D2"].actions] == [(i,) for i in range(outer)]
    cams = [a.iteration for a in run.drones["D1"].actions if a.action == "TurnOnCamera"]
    assert cams == [(i, j) for i in range(outer) for j in range(inner)]


def test_a_decide_hook_takes_a_condition_the_other_way():
    source = """
var Drone1 Quadcopter
func SEQ_Main() {
    Drone1.Arm()
    If(Drone1.Battery() > 50, SEQ_Full, SEQ_Low)
    Drone1.Disarm()
}
func SEQ_Full() { Drone1.TurnOnCamera() }
func SEQ_Low() { Drone1.Calibrate() }
"""
    programs = compile_mission(source, "t.go").programs
    asked: list[tuple[str, str, bool]] = []

    def flip(drone, logic, act, purpose, value):
        asked.append((drone, purpose, value))
        return not value

    run = VirtualMission(programs, decide=flip).run()
    assert asked == [("Drone1", "if", True)]
    assert names(run, "Drone1") == ["Arm()", "Calibrate()", "Disarm()"]
    assert names(run_virtual(programs), "Drone1") == ["Arm()", "TurnOnCamera()", "Disarm()"]
