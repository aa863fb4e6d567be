"""The runtime's parts and public names; the pure wiring read from a program."""

from __future__ import annotations

import importlib

from eamos.actors.wiring import destinations, released_arcs, subscriptions, watched_peers
from eamos.compiler import compile_mission
from eamos.program.uniform import GROUND_STATION

MISSION = """
func SEQ_Main() {
    D1.Arm()
    PAR_Both()
    RepeatWhile(D1.Battery() > 200, SEQ_Again, SEQ_Done)
    D2.Land()
}
func PAR_Both() {
    D1.Takeoff(1)
    D2.Takeoff(1)
}
func SEQ_Again() {
    D1.TurnOn()
    D2.TurnOn()
}
func SEQ_Done() {
    D1.TurnOn()
}
"""


def test_the_public_names_are_importable_from_the_package_and_the_old_paths() -> None:
    actors = importlib.import_module("eamos.actors")
    for name in actors.__all__:
        assert getattr(actors, name) is not None, name
    runtime = importlib.import_module("eamos.actors.runtime")
    for name in (
        "DroneRuntime",
        "DroneRuntimeError",
        "NetSettings",
        "TelemetryBoard",
        "Outbox",
        "DroneExecutive",
        "telemetry_values",
        "stale_values",
        "PROGRESS_INTERVAL_S",
    ):
        assert hasattr(runtime, name), name
    assert actors.DroneRuntime is runtime.DroneRuntime


def test_wiring_names_who_a_drone_talks_to() -> None:
    programs = compile_mission(MISSION, "m.go").programs
    d1, d2, gcs = programs["D1"], programs["D2"], programs[GROUND_STATION]
    assert destinations(d1) == sorted({"D2", GROUND_STATION})
    assert GROUND_STATION in destinations(d2)
    assert watched_peers(gcs, whole_fleet=True) is None
    peers = watched_peers(d2, whole_fleet=False)
    assert peers is not None and "D1" in peers and "D2" not in peers
    topics = subscriptions(d1, (b"extra",))
    assert topics[-1] == b"extra" and len(set(topics)) == len(topics)


def test_released_arcs_are_the_outgoing_external_arcs_outside_loops() -> None:
    programs = compile_mission(MISSION, "m.go").programs
    for program in programs.values():
        native = {n.key for n in program.native_nodes()}
        node_of = {n.key: n for n in program.nodes}
        released = released_arcs(program)
        for dest, src, dst in released:
            assert src in native and dst not in native
            assert node_of[dst].drone == dest != program.drone
            assert not node_of[src].loops and not node_of[dst].loops
    # D1's arcs out of the loop body are not released; those before the loop are.
    d1 = programs["D1"]
    node_of = {n.key: n for n in d1.nodes}
    body = [a for a in d1.arcs if a.external and node_of[a.src].native and node_of[a.src].loops]
    assert body, "the mission has a loop with cross-drone arcs"
    assert released_arcs(d1)
    assert not {(a.src, a.dst) for a in body} & {(s, d) for _, s, d in released_arcs(d1)}
