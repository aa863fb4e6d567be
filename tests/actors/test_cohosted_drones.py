"""Several drones in one process (``eamos run``'s default grouping): one drone's failure is its own.

Two drone runtimes and the ground station's share one process, as the fleet harness
builds them (real ZeroMQ over ``inproc://``, real Pykka actors on each runtime's
dispatchers).  A ``SystemExit`` or ``KeyboardInterrupt`` raised inside one of drone
D1's actors (its adapter raises it while a node actor starts an action, or inside its
uniform-API actor) must not stop drone D2: D1 ends its part failed, lands and reports;
D2 finishes its mission and reports ok; nothing waits for a timeout.  Pykka itself
stops every actor of the process on such an exception (``ActorRegistry.stop_all``).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from eamos.actors.uniform_api import UniformSpace, start_uniform_api
from eamos.ground.station import DroneView
from eamos.hal.api import ActionResult
from eamos.hal.fake import FakeAdapter
from eamos.logs import make_logger, read_log

from .fleet_harness import Fleet, make_fleet

#: Well under a heartbeat timeout plus the actors' hops on a loaded machine.
PROMPT_S = 15.0

TWO_INDEPENDENT = """
func PAR_Fly() {
    SEQ_One()
    SEQ_Two()
}
func SEQ_One() {
    D1.Arm()
    D1.Takeoff(1)
    D1.FlyByX(1)
    D1.Land()
}
func SEQ_Two() {
    D2.Arm()
    D2.Takeoff(1)
    D2.FlyByX(2)
    D2.Land()
}
"""


@pytest.fixture
def fleet_of(tmp_path: Path) -> Iterator[Any]:
    made: list[Fleet] = []

    def build(adapters: dict[str, Any]) -> Fleet:
        fleet = make_fleet(TWO_INDEPENDENT, adapters, log_dir=tmp_path / f"fleet{len(made)}")
        made.append(fleet)
        return fleet

    yield build
    for fleet in made:
        started = time.monotonic()
        fleet.close()
        assert time.monotonic() - started < PROMPT_S, "stopping the runtimes hung"


def resolved_event(fleet: Fleet, drone: str) -> threading.Event:
    """Set once the ground station hears that ``drone`` resolved its part."""
    event = threading.Event()

    def on_change(name: str, view: DroneView, _msg: Any) -> None:
        if name == drone and view.resolved:
            event.set()

    fleet.station.on_change = on_change
    return event


def mission_events(fleet: Fleet, drone: str, event: str) -> list[dict[str, Any]]:
    runtime = fleet.runtimes[drone]
    assert runtime.log_dir is not None
    runtime.logs.close()  # flushed (closing twice is harmless)
    return [e for e in read_log(runtime.log_dir / "mission.log") if e["event"] == event]


@pytest.mark.parametrize("exit_exc", [SystemExit(3), KeyboardInterrupt()], ids=repr)
@pytest.mark.parametrize("where", ["node actor", "uniform-API actor"])
def test_a_base_exception_in_one_drone_fails_that_drone_only(
    fleet_of: Any, exit_exc: BaseException, where: str
) -> None:
    d1 = FakeAdapter("D1", auto=False, run_errors={"FlyByX": exit_exc})  # type: ignore[dict-item]
    if where == "uniform-API actor":
        # A MAVLink-like adapter: called from the drone's uniform-API actor (a Pykka
        # ThreadingActor), not from the node actors.
        d1.answers_at_once = False  # type: ignore[attr-defined]
    d2 = FakeAdapter("D2", auto=False)
    fleet = fleet_of({"D1": d1, "D2": d2})
    d1_resolved = resolved_event(fleet, "D1")
    fleet.start()
    d2.finish(d2.wait_started("Arm", timeout=PROMPT_S))
    d2.wait_started("Takeoff", timeout=PROMPT_S)
    # D2 is taking off when D1's FlyByX raises.
    d1.finish(d1.wait_started("Arm", timeout=PROMPT_S))
    d1.finish(d1.wait_started("Takeoff", timeout=PROMPT_S))
    assert d1_resolved.wait(PROMPT_S), "the ground station never heard D1 end its part"
    d1.wait_for(lambda fake: bool(fake.calls_of("abort")), PROMPT_S)  # D1 lands
    d1_report = fleet.runtimes["D1"].report()
    assert not d1_report["ok"]
    if where == "node actor":
        # The drone gave up its part, as for an exception in its executive.
        assert d1_report["aborted"]
        assert d1_report["abort_reason"].endswith(f"{exit_exc!r}")
        (failure,) = mission_events(fleet, "D1", "mission.failure")
        assert type(exit_exc).__name__ in failure["traceback"]
    else:
        # The uniform-API actor stopped (landing the vehicle): the action failed.
        (flyby,) = [a for a in d1_report["actions"] if a["action"] == "FlyByX"]
        assert flyby["result"] == "failed" and repr(exit_exc) in flyby["reason"]
    # D1's runtime stops while D2 still flies: D2's actors are not D1's.
    fleet.runtimes["D1"].stop()
    d2.finish("Takeoff")
    for action in ("FlyByX", "Land"):
        d2.finish(d2.wait_started(action, timeout=PROMPT_S))
    assert fleet.wait_resolved(PROMPT_S), f"unresolved: {fleet.station.unresolved()}"
    d2_report = fleet.runtimes["D2"].report()
    assert d2_report["ok"], d2_report
    assert [a["action"] for a in d2_report["actions"]] == ["Arm", "Takeoff", "FlyByX", "Land"]
    assert not d2.calls_of("abort")
    assert fleet.runtimes["GCS"].executive.is_alive()


def test_stopping_one_runtime_leaves_the_other_flying(fleet_of: Any) -> None:
    d1, d2 = FakeAdapter("D1", auto=False), FakeAdapter("D2", auto=False)
    fleet = fleet_of({"D1": d1, "D2": d2})
    d2_resolved = resolved_event(fleet, "D2")
    fleet.start()
    d1.finish(d1.wait_started("Arm", timeout=PROMPT_S))
    d2.finish(d2.wait_started("Arm", timeout=PROMPT_S))
    d1.wait_started("Takeoff", timeout=PROMPT_S)
    fleet.runtimes["D1"].stop()  # e.g. the operator stops one drone's part
    assert d1.closed
    d2.finish(d2.wait_started("Takeoff", timeout=PROMPT_S))
    d2.finish(d2.wait_started("FlyByX", timeout=PROMPT_S))
    d2.finish(d2.wait_started("Land", timeout=PROMPT_S), ActionResult("ok"))
    assert d2_resolved.wait(PROMPT_S), "the ground station never heard D2 finish"
    report = fleet.runtimes["D2"].report()
    assert report["ok"] and report["resolved"], report


@pytest.mark.parametrize("exit_exc", [SystemExit(3), KeyboardInterrupt()], ids=repr)
def test_an_adapter_that_exits_while_starting_fails_that_drones_start_at_once(
    exit_exc: BaseException,
) -> None:
    """The uniform-API actor is a Pykka ThreadingActor: a BaseException in its ``on_start``
    would end its thread with the actor never stopped, and the start would wait."""
    fake = FakeAdapter("D1", start_error=exit_exc)  # type: ignore[arg-type]
    started = time.monotonic()
    ref, error = start_uniform_api(UniformSpace(fake, make_logger(None)), lambda sample: None)
    assert time.monotonic() - started < PROMPT_S
    assert error is not None and repr(exit_exc) in str(error)
    assert not ref.is_alive() and fake.closed
