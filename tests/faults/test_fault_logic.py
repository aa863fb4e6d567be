"""The pure and in-process parts of the fault handling (issue 17), without sockets.

When a drone ends on its own (stranded, no Complete), logging and summaries
that never stop a flight, land always reachable, the simulator's error path,
the operator's lines, and the ground station's stop and second stop.
"""

from __future__ import annotations

import io
import os
import signal
import threading
import time
from pathlib import Path
from typing import Any

import pykka
import pytest

from eamos.actors.failure import FailurePolicy
from eamos.actors.runtime import land_now
from eamos.actors.stranded import Activity, activity_matters, end_on_own, silent_since
from eamos.ground.display import format_event
from eamos.ground.flight import Limits, StopRequest, fly, install_stop_handler
from eamos.ground.station import ParticipantFailed
from eamos.ground.summary import RunSummary
from eamos.hal.api import ActionResult
from eamos.hal.sim.adapter import SimAdapter
from eamos.hal.sim.settings import SimSettings
from eamos.logs import make_logger, write_errors
from eamos.program.uniform import GROUND_STATION, PauseFor
from tests.ground.test_fly import DRONES, ready, station_and_fleet

LIMIT = 10.0
BUSY = Activity(resolved=False, idle_since=None)


def idle(since: float) -> Activity:
    return Activity(resolved=False, idle_since=since)


# -- when a drone ends on its own -------------------------------------------------------


@pytest.mark.parametrize(
    ("now", "activity", "silent", "expected"),
    [
        # Idle, waiting for a lost source: after the limit, not before.
        (100.0, idle(50.0), {"Drone1": 80.0}, "stranded"),
        (100.0, idle(50.0), {"Drone1": 95.0}, None),
        # The wait counts from when both hold: lost long ago, idle only since 95 s.
        (100.0, idle(95.0), {"Drone1": 10.0}, None),
        (106.0, idle(95.0), {"Drone1": 10.0}, "stranded"),
        # Busy flying its own part: never stranded.
        (100.0, BUSY, {"Drone1": 10.0}, None),
        # A silent peer it does not wait for changes nothing.
        (100.0, idle(50.0), {"Drone3": 10.0}, None),
        # Resolved: only the ground station's silence matters (no Complete will come).
        (100.0, Activity(True, 50.0), {GROUND_STATION: 80.0}, "no_complete"),
        (100.0, Activity(True, 50.0), {GROUND_STATION: 95.0}, None),
        (100.0, Activity(True, 50.0), {"Drone1": 10.0}, None),
        # Not resolved and the ground station is silent: stranded like any source.
        (100.0, idle(50.0), {GROUND_STATION: 80.0}, "stranded"),
        # Held by the operator, its action suspended (not idle): only the ground station
        # can resume it; after the limit of its silence, stranded, not before.
        (100.0, Activity(False, None, held=True), {GROUND_STATION: 80.0}, "stranded"),
        (100.0, Activity(False, None, held=True), {GROUND_STATION: 95.0}, None),
        (100.0, Activity(False, None, held=True), {"Drone1": 10.0}, None),
    ],
)
def test_end_on_own(
    now: float, activity: Activity, silent: dict[str, float], expected: str | None
) -> None:
    ending = end_on_own(now, activity, silent, {"Drone1", GROUND_STATION}, LIMIT)
    assert (ending.kind if ending else None) == expected
    if ending is not None:
        assert f"peer_wait_limit_s = {LIMIT:g}" in ending.reason


@pytest.mark.parametrize(
    "activity",
    [
        idle(0.0),
        BUSY,
        Activity(True, 0.0),
        Activity(False, None, held=True),
        Activity(True, None, held=True),
    ],
)
def test_with_no_peer_silent_the_activity_need_not_be_asked(activity: Activity) -> None:
    # Nothing ends on its own while every peer is heard, whatever the executive says:
    # the drone's thread asks it only when a peer is silent, or once its part resolved.
    for now in (0.0, 100.0, 1e6):
        assert end_on_own(now, activity, {}, {"Drone1", GROUND_STATION}, LIMIT) is None
    assert not activity_matters({}, resolved=False, checked=False)
    assert activity_matters({}, resolved=True, checked=False)
    assert not activity_matters({}, resolved=True, checked=True)
    assert activity_matters({"Drone1": 10.0}, resolved=False, checked=True)


def test_a_held_drone_without_its_ground_station_says_why_it_ends() -> None:
    held = Activity(False, None, held=True)
    ending = end_on_own(100.0, held, {GROUND_STATION: 80.0}, set(), LIMIT)
    assert ending is not None and ending.peer is None
    assert ending.reason.startswith("stranded: held by the operator, and the ground station")


def test_a_held_drone_whose_part_a_peer_failed_still_names_the_hold() -> None:
    # Two drones held, the ground station gone: the one whose limit came first ends,
    # and its failed triggers resolve the other's part a moment before its own check.
    held_and_resolved = Activity(True, None, held=True)
    ending = end_on_own(100.0, held_and_resolved, {GROUND_STATION: 80.0}, set(), LIMIT)
    assert ending is not None
    assert ending.reason.startswith("stranded: held by the operator, and the ground station")


def test_the_reason_names_the_peer_and_the_wait() -> None:
    ending = end_on_own(100.0, idle(50.0), {"Drone1": 80.0}, {"Drone1"}, LIMIT)
    assert ending is not None
    assert ending.reason == "stranded: waited 20 s for Drone1, whose link is lost " + (
        "(peer_wait_limit_s = 10)"
    )


def test_silent_since_follows_the_latest_event_of_each_peer() -> None:
    events = [
        {"peer": "Drone1", "state": "lost", "silent_s": 3.0, "t": 1000.0},
        {"peer": "Drone2", "state": "lost", "silent_s": 3.0, "t": 1001.0},
        {"peer": "Drone2", "state": "back", "silent_s": 4.0, "t": 1002.0},
        {"peer": "GCS", "state": "left", "silent_s": 0.0, "t": 1004.0},
    ]
    # Wall 1010 is monotonic 500: Drone1 went silent at wall 997, 13 s ago.
    assert silent_since(events, 1010.0, 500.0) == {"Drone1": 487.0, "GCS": 494.0}


# -- logs and summaries that never stop a flight ------------------------------------------


def test_a_log_that_cannot_be_written_counts_and_tells_once(
    capsys: pytest.CaptureFixture[str],
) -> None:
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full")
    log = make_logger(Path("/dev/full"))
    for i in range(5):
        log.info("event", i=i)  # never raises
    assert write_errors(log) == 5
    err = capsys.readouterr().err
    assert err.count("cannot write /dev/full: No space left on device") == 1


def test_a_summary_that_cannot_be_written_is_named_and_the_next_copy_still_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full")
    summary = RunSummary("m", "m-1", "ok", 0.0, 1.0, str(tmp_path), {}, None)
    assert summary.write(Path("/dev/full")) is False
    assert summary.write(tmp_path / "copy" / "summary.json") is True
    assert RunSummary.read(tmp_path / "copy" / "summary.json") == summary
    assert "cannot write /dev/full: No space left on device" in capsys.readouterr().err


# -- land is always reachable -------------------------------------------------------------


class RecordingAdapter:
    """The HAL seam: records what the runtime asks of the vehicle."""

    drone = "Drone1"

    def __init__(self) -> None:
        self.calls: list[str] = []

    def abort(self) -> None:
        self.calls.append("abort")

    def close(self) -> None:
        self.calls.append("close")


class Dead(pykka.ThreadingActor):
    pass


def test_land_goes_to_the_adapter_when_the_uniform_api_actor_is_dead() -> None:
    ref = Dead.start()
    ref.stop()
    adapter = RecordingAdapter()
    land_now(ref, adapter, make_logger(None))  # type: ignore[arg-type]
    assert adapter.calls == ["abort"]


def test_land_goes_through_a_live_uniform_api_actor() -> None:
    told: list[Any] = []

    class Live(pykka.ThreadingActor):
        def on_receive(self, message: Any) -> None:
            told.append(message)

    ref = Live.start()
    adapter = RecordingAdapter()
    try:
        land_now(ref, adapter, make_logger(None))  # type: ignore[arg-type]
        ref.ask("sync", timeout=10)
    finally:
        ref.stop()
    assert adapter.calls == [] and type(told[0]).__name__ == "Abort"


def test_an_exception_in_the_simulator_thread_fails_the_running_action() -> None:
    # Its log is on a full disk as well: the error path must not depend on logging.
    full = make_logger(Path("/dev/full")) if Path("/dev/full").exists() else None
    adapter = SimAdapter("Drone1", SimSettings(speedup=10.0), full)
    results: list[ActionResult] = []
    finished = threading.Event()

    def done(result: ActionResult) -> None:
        results.append(result)
        finished.set()

    adapter.start(lambda sample: None)
    try:
        broken = RuntimeError("a bug in the simulated vehicle")

        def step() -> Any:
            raise broken

        # A pause of 60 simulated seconds (6 s here) ends by itself only long after the
        # fault; a Takeoff without Arm failed "not armed" first on a loaded machine.
        adapter.run(PauseFor(60.0), done)
        adapter._core.step = step  # type: ignore[method-assign]  # the fault, injected
        assert finished.wait(30), "the running action was lost"
    finally:
        adapter.close()
    assert results[0].status == "failed" and "simulator error" in results[0].reason


def test_an_exception_in_a_runtime_part_is_told_on_stderr_once(
    capsys: pytest.CaptureFixture[str],
) -> None:
    reactions: list[Any] = []
    policy = FailurePolicy(make_logger(None), reactions.append, "Drone1")
    policy("executive", ValueError("boom"))
    policy("telemetry board", ValueError("again"))
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "eamos-node Drone1: internal error in the executive: ValueError('boom'): "
        "the drone aborts and lands (details in mission.log)"
    ]
    assert len(reactions) == 1


# -- what the operator sees -------------------------------------------------------------


def test_a_participant_that_fails_gets_a_line_at_once() -> None:
    line = format_event("Drone1", ParticipantFailed("Drone1", "process exited with code -9"), 0)
    assert line is not None and line.endswith("  Drone1 FAILED: process exited with code -9")


def test_the_station_tells_the_display_when_a_drone_dies() -> None:
    station, _, out = station_and_fleet({})
    station.fail("Drone2", "process exited with code -9")
    assert "  Drone2 FAILED: process exited with code -9" in out.getvalue()


def test_stopping_during_start_says_who_was_ready() -> None:
    station, fleet, _ = station_and_fleet({})
    ready(station, "Drone1")
    stop = threading.Event()
    stop.set()
    flight = fly(station, _quiet(), stop, Limits(5, 30, report_aborted_s=1))
    assert flight.outcome == (
        "stopped by the operator before the start (ready: Drone1; not ready: Drone2)"
    )
    assert [type(m).__name__ for m in fleet.sent] == ["Abort"]


def test_a_second_stop_ends_the_wait_for_reports() -> None:
    station, _, _ = station_and_fleet({"start": DRONES})  # nobody reports after the abort
    ready(station, *DRONES)
    stop = StopRequest()
    stop.set()
    stop.hurry.set()
    out = io.StringIO()
    from eamos.ground.display import PlainDisplay

    t0 = time.monotonic()
    flight = fly(station, PlainDisplay(out), stop, Limits(5, 30, report_aborted_s=120))
    assert time.monotonic() - t0 < 30  # not the 120 s report wait
    assert flight.missing_reports == tuple(DRONES)
    assert "stopped waiting (second Ctrl-C); no report from: Drone1, Drone2" in out.getvalue()


def test_the_second_ctrl_c_hurries_a_stop_request_and_interrupts_a_plain_event() -> None:
    old = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    try:
        request = StopRequest()
        install_stop_handler(request)
        os.kill(os.getpid(), signal.SIGINT)
        assert request.is_set() and not request.hurry.is_set()
        os.kill(os.getpid(), signal.SIGINT)
        assert request.hurry.is_set()
        plain = threading.Event()
        install_stop_handler(plain)
        os.kill(os.getpid(), signal.SIGINT)
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
    finally:
        signal.signal(signal.SIGINT, old[0])
        signal.signal(signal.SIGTERM, old[1])


def _quiet() -> Any:
    from eamos.ground.display import PlainDisplay

    return PlainDisplay(io.StringIO())


def test_a_drone_waits_for_the_participants_it_receives_triggers_from() -> None:
    from eamos.actors.stranded import trigger_sources
    from eamos.compiler import compile_file
    from tests.support.runs import MISSIONS

    programs = compile_file(MISSIONS / "experiment_b.go").programs
    # Drone1 is started by the ground station's initial node; Drone2 only by Drone1.
    assert trigger_sources(programs["Drone1"]) == {"Drone2", GROUND_STATION}
    assert trigger_sources(programs["Drone2"]) == {"Drone1"}


def test_abort_lands_the_vehicle_when_the_node_and_uniform_api_actors_are_dead() -> None:
    from eamos.actors.runtime import DroneRuntime, NetSettings
    from eamos.compiler import compile_file
    from tests.support.runs import MISSIONS

    program = compile_file(MISSIONS / "experiment_a.go").programs["Drone1"]
    adapter = RecordingAdapter()
    runtime = DroneRuntime(program, adapter, NetSettings("inproc://d1", {}))  # type: ignore[arg-type]
    dead_node, dead_hal = Dead.start(), Dead.start()
    dead_node.stop()
    dead_hal.stop()
    runtime.nodes = {"n1": dead_node}  # type: ignore[dict-item]
    runtime.hal = dead_hal  # type: ignore[assignment]
    try:
        runtime.abort("a bug killed them")  # must not raise ActorDeadError
    finally:
        runtime.context.term()
        runtime.logs.close()
    assert adapter.calls == ["abort"] and runtime.aborted.is_set()


def test_a_display_on_a_full_disk_loses_lines_not_the_run() -> None:
    from eamos.ground.display import PlainDisplay

    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full")
    full = open("/dev/full", "w")  # noqa: SIM115  # closed below, where it raises too
    display = PlainDisplay(full)
    display.say("a line")
    display.say("another")
    with pytest.raises(OSError):
        full.close()  # what is still buffered cannot be written either
    assert display.lost_lines == 2


def test_the_wait_limit_and_end_policy_come_from_the_node_config(tmp_path) -> None:
    from eamos.actors.drone import end_policy, peer_wait_limit
    from eamos.actors.stranded import DEFAULT_PEER_WAIT_LIMIT_S
    from eamos.config import ConfigError, NodeConfig

    def config(extra: str) -> NodeConfig:
        path = tmp_path / "d.toml"
        path.write_text(
            f'drone = "D1"\nprogram = "p.json"\n{extra}\n'
            '[net]\nbind = "tcp://127.0.0.1:6001"\nplain = true\n'
        )
        return NodeConfig.load(path)

    bare = config("")
    assert peer_wait_limit(bare) == DEFAULT_PEER_WAIT_LIMIT_S == 20.0
    assert end_policy(bare) == "land"
    held = config('peer_wait_limit_s = 5\non_stranded = "hold"')
    assert peer_wait_limit(held) == 5.0 and end_policy(held) == "hold"
    held.path.write_text(held.to_toml())  # it round-trips
    assert NodeConfig.load(held.path) == held
    assert end_policy(config('on_stranded = "return"')) == "land"  # no path home yet
    with pytest.raises(ConfigError, match="on_stranded: must be one of land, hold, return"):
        config('on_stranded = "fly away"')
    with pytest.raises(ConfigError, match="peer_wait_limit_s"):
        config("peer_wait_limit_s = nan")


def test_a_crashing_uniform_api_actor_lands_the_vehicle_and_says_so(
    capfd: pytest.CaptureFixture[str],
) -> None:
    from eamos.actors.uniform_api import RunAction, UniformAPI

    class StartableAdapter(RecordingAdapter):
        def start(self, on_telemetry: Any) -> None:
            self.calls.append("start")

    adapter = StartableAdapter()
    ref = UniformAPI.start(adapter, make_logger(None), lambda sample: None)
    # A bug: a request nobody can be answered on (the reply raises in the actor).
    ref.tell(RunAction("t1", "Arm", (), None))  # type: ignore[arg-type]
    deadline = time.monotonic() + 30
    while ref.is_alive() and time.monotonic() < deadline:
        time.sleep(0.05)  # test side only: wait for the actor to die
    assert not ref.is_alive()
    assert adapter.calls[:2] == ["start", "abort"]  # landed, not merely closed
    assert "close" not in adapter.calls  # left open so the landing can finish
    assert "eamos-node Drone1: internal error in the uniform API:" in capfd.readouterr().err
