"""The monitor's pure state model: events in, ordered patches out; no threads, no clocks."""

from __future__ import annotations

import copy

import pytest

from eamos.actors.report import ActionEntry, DroneReport, FinalState
from eamos.ground.summary import DroneResult, RunSummary
from eamos.monitor.hub import Hub
from eamos.monitor.setup import MissionSetup, NodeInfo, ParticipantSetup
from eamos.monitor.state import (
    MIN_INTERVAL_S,
    MonitorState,
    apply_patches,
    final_node_states,
)
from eamos.net import wire
from eamos.net.link import PeerStatus

MID = "m1"


def setup() -> MissionSetup:
    d1 = ParticipantSetup(
        "D1",
        "#ffe066",
        (0.0, 0.0),
        (
            NodeInfo("n2", "action", "Arm()", "D1", "Arm"),
            NodeInfo("n4@D1", "fork", "PAR", "D1"),
            NodeInfo("n5", "action", "Takeoff(1)", "D1", "Takeoff"),
            NodeInfo("n9", "action", "Land()", "D1", "Land"),
        ),
        "",
    )
    d2 = ParticipantSetup(
        "D2", "#8ce99a", (5.0, 0.0), (NodeInfo("n3", "action", "Arm()", "D2", "Arm"),), ""
    )
    gcs = ParticipantSetup(
        "GCS", "#c8c8c8", (0.0, 0.0), (NodeInfo("n0", "init", "INIT", "GCS"),), ""
    )
    preds = {"n2": ("n0",), "n3": ("n2",), "n4@D1": ("n2",), "n5": ("n4@D1",), "n9": ("n5", "n3")}
    return MissionSetup("demo", MID, (d1, d2, gcs), preds)


def tel(sender: str, x: float, z: float = 1.0, armed: bool = True) -> wire.TelemetrySample:
    return wire.TelemetrySample(
        mission=MID, sender=sender, time_s=0.0, x_m=x, y_m=0.0, z_m=z, lat_deg=0.0,
        lon_deg=0.0, alt_m=z, battery_pct=90.0, armed=armed, landed=False,
    )  # fmt: skip


def progress(sender: str, state: str, node: str, action: str, it=()) -> wire.Progress:
    return wire.Progress(
        mission=MID, sender=sender, state=state, node=node, action=action,
        detail={"iteration": list(it), "detail": "", "finished": 0},
    )  # fmt: skip


def report(actions, resolved=True, blocked=(), final=(1.0, 0.0, 0.0)) -> DroneReport:
    return DroneReport(
        ok=resolved and not blocked, resolved=resolved, aborted=not resolved, abort_reason="",
        triggers_sent=3, triggers_received=2, external_out=3, external_in=2, mdg={},
        blocked_nodes=tuple(blocked), actions=tuple(actions),
        final=FinalState(final[0], final[1], final[2], False, 80.0),
    )  # fmt: skip


def entry(node: str, action: str, start: float, end: float, result: str = "ok") -> ActionEntry:
    return ActionEntry(node, action, (), (), start, end, result)


def test_telemetry_is_coalesced_to_ten_per_second_and_nothing_is_lost():
    state = MonitorState(setup(), 0.0)
    start = copy.deepcopy(state.snapshot())
    patches = []
    for i in range(100):  # 100 samples in one second, 5 cm apart
        patches += state.apply("D1", tel("D1", i * 0.05), 100.0 + i * 0.01)
    drone_patches = [p for p in patches if p["k"] == "drone"]
    assert 9 <= len(drone_patches) <= 10
    times = [100.0 + i * 0.01 for i in range(100)]
    assert state.coalesced >= 75  # updates merged into a later patch
    patches += state.tick(times[-1] + MIN_INTERVAL_S)  # the held last update
    last = [p for p in patches if p["k"] == "drone"][-1]
    assert last["x"] == pytest.approx(99 * 0.05)
    apply_patches(start, patches)
    assert start["drones"]["D1"]["trail"] == state.snapshot()["drones"]["D1"]["trail"]
    assert len(state.drones["D1"].trail) == 100  # every 5 cm step kept
    assert state.drones["D1"].heading_deg == 0.0  # flying along +x


def test_tick_sends_nothing_before_its_time_and_homes_shift_positions():
    state = MonitorState(setup(), 0.0)
    assert [p["k"] for p in state.apply("D2", tel("D2", 1.0), 10.0)] == ["drone"]
    assert state.apply("D2", tel("D2", 2.0), 10.05) == []
    assert state.tick(10.08) == []
    (patch,) = state.tick(10.1)
    assert patch["x"] == 7.0  # home (5, 0) + 2 m


def test_progress_lights_nodes_in_order_and_opens_and_closes_bars():
    state = MonitorState(setup(), 0.0)
    out = state.apply("D1", wire.Ready(mission=MID, sender="D1", program_checksum="c"), 1.0)
    assert not [p for p in out if p["k"] == "mission"]  # D2 not ready yet
    out = state.apply("D2", wire.Ready(mission=MID, sender="D2", program_checksum="c"), 1.5)
    assert next(p for p in out if p["k"] == "mission")["state"] == "running"
    assert state.node_states()["n0"] == "done"  # the start trigger: the initial node fired
    out = state.apply("D1", progress("D1", "running", "n2", "Arm"), 2.0)
    assert [(p["k"], p.get("state")) for p in out][:2] == [("node", "running"), ("bar", None)]
    out = state.apply("D1", progress("D1", "ok", "n2", "Arm"), 3.0)
    node = next(p for p in out if p["k"] == "node")
    assert (node["node"], node["state"], node["count"]) == ("n2", "done", 1)
    bar = next(p for p in out if p["k"] == "bar")
    assert (bar["i"], bar["start"], bar["end"], bar["result"]) == (0, 2.0, 3.0, "ok")
    # An "ok" whose "running" never came still gets its bar.
    out = state.apply("D1", progress("D1", "ok", "n5", "Takeoff"), 4.0)
    assert [p["i"] for p in out if p["k"] == "bar"] == [1]
    assert state.node_states()["n5"] == "done"


def test_loop_iterations_count_activations():
    state = MonitorState(setup(), 0.0)
    for i in range(3):
        state.apply("D1", progress("D1", "running", "n5", "Takeoff", (i,)), 1.0 + i)
        state.apply("D1", progress("D1", "ok", "n5", "Takeoff", (i,)), 1.5 + i)
    assert state.nodes["n5"]["count"] == 3
    assert state.nodes["n5"]["iteration"] == [2]


def test_report_decides_every_final_state():
    s = setup()
    rep = report([entry("n2", "Arm", 1, 2), entry("n5", "Takeoff", 2, 3, "failed")], blocked=["n9"])
    assert final_node_states(s, "D1", rep) == {
        "n2": "done",
        "n4@D1": "done",
        "n5": "failed",
        "n9": "failed",
    }
    aborted = report([entry("n2", "Arm", 1, 2)], resolved=False)
    assert final_node_states(s, "D1", aborted)["n9"] == "cancelled"
    skipped = report([entry("n2", "Arm", 1, 2)])
    assert final_node_states(s, "D1", skipped)["n9"] == "skipped"
    assert final_node_states(s, "D1", None) == {}


def summary(outcome="ok", ok=True) -> RunSummary:
    acts = [entry("n2", "Arm", 10, 11), entry("n5", "Takeoff", 11, 12), entry("n9", "Land", 12, 13)]
    return RunSummary(
        mission="demo", mission_id=MID, outcome=outcome, started=10.0, duration_s=5.0,
        run_dir="/x", drones={"D1": DroneResult(report(acts, resolved=ok)),
                              "D2": DroneResult(report([entry("n3", "Arm", 10, 11)]))},
        ground_station=report([]), links={"D1": "up", "D2": "left"},
    )  # fmt: skip


def test_finish_applies_the_summary_and_one_outcome_word():
    state = MonitorState(setup(), 0.0)
    state.apply("D1", progress("D1", "running", "n2", "Arm"), 10.2)
    out = state.finish(summary(), 20.0)
    assert set(state.node_states().values()) == {"done"}
    mission = [p for p in out if p["k"] == "mission"][-1]
    assert (mission["state"], mission["started"], mission["ended"]) == ("finished", 10.0, 15.0)
    assert [b["start"] for b in state.bars if b["drone"] == "D1"] == [10, 11, 12]
    assert state.drones["D2"].link == "left"
    assert state.drones["D1"].x == 1.0 and state.drones["D2"].x == 6.0  # final + home


@pytest.mark.parametrize(
    "outcome, ok, word",
    [
        ("ok", True, "finished"),
        ("ok", False, "failed"),
        ("aborted by the operator", False, "aborted"),
        ("timed out after 5 s (unresolved: D1)", False, "timed out"),
        ("not ready: D1", False, "failed"),
    ],
)
def test_outcome_word(outcome, ok, word):
    assert summary(outcome, ok).word == word


def test_snapshot_plus_patches_equals_the_state():
    state = MonitorState(setup(), 0.0)
    page = copy.deepcopy(state.snapshot())
    patches = []
    for i in range(30):
        patches += state.apply("D1", tel("D1", i * 0.1), 1.0 + i * 0.03)
        patches += state.apply("D1", progress("D1", "running" if i % 2 else "ok", "n5", "T"), 1.0)
    patches += state.apply("D2", PeerStatus("D2", "lost", 3.0, 1), 2.0)
    patches += state.tick(5.0)
    patches += state.finish(summary(), 6.0)
    apply_patches(page, patches)
    assert page == state.snapshot()


def test_hub_counts_dropped_frames_and_resynchronises_a_slow_page():
    hub = Hub(setup(), clock=iter(range(1000)).__next__, capacity=5)
    woken = []
    hub.wake = lambda: woken.append(1)
    for i in range(12):  # one drone patch each (a second apart: nothing coalesced)
        hub.event("D1", tel("D1", float(i)))
    # Events never wake the server (its ticker sends them); the end and aborts do.
    assert hub.seq == 12 and woken == []
    assert hub.since(12) == (12, [])
    behind = hub.since(8)
    assert behind is not None
    seq, patches = behind
    assert seq == 12 and [p["x"] for p in patches] == [8.0, 9.0, 10.0, 11.0]
    assert hub.since(2) is None  # its next patches are gone: resynchronise
    assert hub.stats()["dropped"] == 5
    seq, snap = hub.resync()
    assert seq == 12 and snap["drones"]["D1"]["x"] == 11.0
    hub.abort_request("test 127.0.0.1", accepted=False)
    assert hub.state.mission["state"] == "waiting for drones"
    hub.abort_request("test 127.0.0.1", accepted=True)
    assert hub.state.mission["state"] == "aborting"
    assert len(woken) == 2
    assert [a["accepted"] for a in hub.aborts] == [False, True]


def test_a_node_that_ran_tells_that_its_only_predecessors_were_done():
    state = MonitorState(setup(), 0.0)
    out = state.apply("D1", progress("D1", "running", "n5", "Takeoff"), 1.0)
    assert [(p["node"], p["state"]) for p in out if p["k"] == "node"] == [
        ("n5", "running"),
        ("n4@D1", "done"),  # the fork before it
        ("n2", "done"),  # an action whose "ok" was not sent (latest-only progress)
        ("n0", "done"),
    ]
    # A join: which of its predecessors ran is unknown, so nothing is inferred.
    state.apply("D1", progress("D1", "running", "n9", "Land"), 2.0)
    assert state.node_states()["n3"] == "waiting"


def test_blocked_skipped_and_waiting_nodes():
    state = MonitorState(setup(), 0.0)
    out = state.apply("D1", progress("D1", "blocked", "n5", "Takeoff"), 1.0)
    assert [(p["k"], p.get("state")) for p in out if p["k"] != "drone"] == [("node", "failed")]
    assert state.node_states()["n4@D1"] == "waiting"  # blocked: it did not run
    out = state.apply("D1", progress("D1", "skipped", "n9", "Land"), 1.0)
    assert [(p["k"], p.get("state")) for p in out if p["k"] != "drone"] == [("node", "skipped")]
    out = state.apply("D1", progress("D1", "waiting", "n4@D1", "PAR"), 1.0)
    assert state.node_states()["n4@D1"] == "running"
    assert not state.bars  # the timeline holds actions only


def test_the_report_keeps_a_final_state_a_non_action_node_showed():
    state = MonitorState(setup(), 0.0)
    state.apply("D1", progress("D1", "skipped", "n4@D1", "PAR"), 1.0)
    state.finish(summary(), 20.0)
    assert state.node_states()["n4@D1"] == "skipped"  # the report alone would say done
    assert state.node_states()["n2"] == "done"


def test_a_replay_played_forward_equals_one_built_from_scratch():
    from eamos.monitor.replay import NodeChange, Replay, ReplayEvent

    events = [ReplayEvent(10.0 + i * 0.05, "D1", tel("D1", i * 0.1)) for i in range(40)]
    events.append(ReplayEvent(10.5, "D1", NodeChange("n4@D1", "done", ())))
    events.append(ReplayEvent(10.6, "D1", progress("D1", "running", "n5", "Takeoff")))
    replay = Replay(setup(), summary(), events)
    forward = [replay.state_at(t) for t in (10.2, 10.55, 11.0, 12.0)]
    assert forward[1]["nodes"]["n4@D1"]["state"] == "done"
    assert forward[2]["nodes"]["n5"]["state"] == "running"
    for t, seen in zip((10.2, 10.55, 11.0, 12.0), forward, strict=True):
        assert seen == replay.model_at(t).snapshot()
    assert replay.state_at(10.0)["nodes"]["n4@D1"]["state"] == "waiting"  # back in time
    assert replay.state_at(replay.end)["mission"]["state"] == "finished"


def test_a_drone_a_pilot_took_over_says_so_whatever_its_telemetry_or_report():
    state = MonitorState(setup(), 0.0)
    words = "taken over by the pilot in LOITER at (1.00, 2.00, 1.50): no longer commanded"
    taken = wire.Progress(
        mission=MID,
        sender="D2",
        state="taken_over",
        node="",
        action="the pilot has the vehicle",
        detail={"detail": words},
    )
    patches = state.apply("D2", taken, 1.0)
    drone = [p for p in patches if p["k"] == "drone"][-1]
    assert drone["mode"] == "taken over (LOITER)" and drone["taken_over"] == words
    assert not [p for p in patches if p["k"] == "node"]  # about the vehicle, not a node
    state.apply("D2", tel("D2", 3.0), 2.0)
    assert state.drones["D2"].mode == "taken over (LOITER)"  # telemetry does not undo it
    # A replay (or a page that missed the line) learns it from the report at the end.
    late = MonitorState(setup(), 0.0)
    report = DroneReport(
        ok=False, resolved=True, aborted=False, abort_reason="", triggers_sent=0,
        triggers_received=0, external_out=0, external_in=0, mdg={}, blocked_nodes=(),
        actions=(), final=FinalState(1.0, 2.0, 1.5, True, 90.0, False),
        vehicle={"signed": True, "taken_over": {"mode": "POSCTL", "x_m": 1.0, "y_m": 2.0,
                                                "z_m": 1.5}},
    )  # fmt: skip
    late.apply("D2", wire.Report(mission=MID, sender="D2", report=report.to_json()), 5.0)
    assert late.drones["D2"].mode == "taken over (POSCTL)"
    assert "taken over by the pilot in POSCTL at (1.00, 2.00, 1.50)" in late.drones["D2"].taken_over


def test_a_look_ahead_cycle_is_one_patch_and_the_snapshot_holds_the_latest():
    state = MonitorState(setup(), 0.0)
    start = state.snapshot()
    assert start["forecast"] is None  # the look-ahead is off until a cycle comes
    conflict = {"check": "separation", "severity": "error", "in_s": 16.0, "drones": ["D1", "D2"]}
    cycles = [
        {
            "predictions": [],
            "end_in_s": 40.0,
            "ahead": {"D1": [[0, 0, 0, 1]]},
            "cycle": 1,
            "t": 5.0,
        },
        {"predictions": [conflict], "end_in_s": 38.0, "ahead": {}, "cycle": 2, "t": 7.0, "x": 1},
    ]
    patches = [p for c in cycles for p in state.forecast(c)]
    assert [p["k"] for p in patches] == ["forecast", "forecast"]
    apply_patches(start, patches)
    latest = state.snapshot()["forecast"]
    assert latest is not None and start["forecast"] == latest
    assert latest["predictions"] == [conflict] and "x" not in latest
