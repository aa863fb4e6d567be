"""The UniformAPI actor with the FakeAdapter and with the SimAdapter."""

from __future__ import annotations

import math
import queue
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pykka
import pytest

from eamos.actors.uniform_api import (
    Abort,
    ActionFinished,
    CancelAction,
    RunAction,
    UniformAPI,
)
from eamos.hal import ActionResult, AdapterError, Telemetry
from eamos.hal.api import ActionHandle, Adapter
from eamos.hal.fake import FakeAdapter
from eamos.hal.station_adapter import GroundAdapter, GroundSettings
from eamos.logs import DroneLogs, make_logger, read_log
from tests.hal.hal_helpers import WAIT_S, Collector, TelemetrySink, next_message
from tests.support.sim_fixtures import SimFactory

# Generous for a loaded 2-core machine; a healthy run takes seconds.
pytestmark = pytest.mark.timeout(180)


class Rig:
    """A UniformAPI actor, its adapter, a reply_to collector and the drone's logs."""

    def __init__(self, adapter: Adapter, log_dir: Path, **kwargs: Any) -> None:
        self.adapter = adapter
        self.logs = DroneLogs.open(log_dir, adapter.drone)
        self.log_dir = log_dir
        self.telemetry = TelemetrySink()
        self.inbox: queue.Queue[Any] = queue.Queue()
        self.collector = Collector.start(self.inbox)
        self.ref = UniformAPI.start(adapter, self.logs.uniform, self.telemetry, **kwargs)

    def run(self, token: Any, action: str, *args: float) -> None:
        self.ref.tell(RunAction(token, action, tuple(args), self.collector))

    def finished(self, timeout: float = WAIT_S) -> ActionFinished:
        message = next_message(self.inbox, timeout)
        assert isinstance(message, ActionFinished), message
        return message

    def call(self, token: Any, action: str, *args: float) -> ActionFinished:
        self.run(token, action, *args)
        reply = self.finished()
        assert reply.token == token
        return reply

    def stop(self) -> None:
        for ref in (self.ref, self.collector):
            if ref.is_alive():
                ref.stop(timeout=WAIT_S)
        self.logs.close()


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[Callable[..., Rig]]:
    made: list[Rig] = []

    def factory(adapter: Adapter, **kwargs: Any) -> Rig:
        made.append(Rig(adapter, tmp_path / adapter.drone, **kwargs))
        return made[-1]

    yield factory
    for r in made:
        r.stop()


def test_run_action_replies_action_finished(rig: Callable[..., Rig]) -> None:
    fake = FakeAdapter("D1")
    r = rig(fake)
    r.run("t1", "Takeoff", 5)
    handle = fake.wait_started("Takeoff", WAIT_S)
    assert handle.args == (5.0,)
    assert r.inbox.empty()
    fake.finish(handle, ActionResult("ok"))
    reply = r.finished()
    assert (reply.token, reply.action, reply.args, reply.result) == (
        "t1",
        "Takeoff",
        (5,),
        ActionResult("ok"),
    )
    assert 0 < reply.start_s <= reply.end_s


def test_failures_are_relayed(rig: Callable[..., Rig]) -> None:
    fake = FakeAdapter("D1", auto=True, results={"Land": ActionResult("failed", "gusts")})
    r = rig(fake)
    assert r.call(1, "Land").result == ActionResult("failed", "gusts")
    assert r.call(2, "Arm").result.ok


def test_cancel_action(rig: Callable[..., Rig]) -> None:
    fake = FakeAdapter("D1")
    r = rig(fake)
    r.run("fly", "FlyByX", 10)
    handle = fake.wait_started("FlyByX", WAIT_S)
    r.ref.tell(CancelAction("fly"))
    reply = r.finished()
    assert reply.token == "fly" and reply.result.status == "cancelled"
    assert [c.handle for c in fake.calls_of("cancel")] == [handle]


def test_cancel_unknown_or_finished_token_is_a_noop(rig: Callable[..., Rig]) -> None:
    fake = FakeAdapter("D1", auto=True)
    r = rig(fake)
    r.ref.tell(CancelAction("nobody"))
    assert r.call("a", "Arm").result.ok
    r.ref.tell(CancelAction("a"))
    assert r.call("b", "PauseFor", 1).result.ok  # the actor is alive and well
    assert fake.calls_of("cancel") == []
    assert r.inbox.empty()


def test_unknown_action_and_bad_args_fail_without_calling_the_adapter(
    rig: Callable[..., Rig],
) -> None:
    fake = FakeAdapter("D1", auto=True)
    r = rig(fake)
    assert r.call(1, "Fly", 1).result == ActionResult("failed", "unknown action 'Fly'")
    assert "takes 1 argument" in r.call(2, "Takeoff").result.reason
    assert "finite" in r.call(3, "Takeoff", float("nan")).result.reason
    r.ref.tell(RunAction(4, "Takeoff", ("high",), r.collector))  # type: ignore[arg-type]
    # The vocabulary's decoder names the parameter (it used to say "finite number").
    assert r.finished().result == ActionResult(
        "failed", "Takeoff: height_m must be a number, got 'high'"
    )
    assert fake.calls_of("run") == []


def test_adapter_exception_fails_the_action_not_the_actor(rig: Callable[..., Rig]) -> None:
    fake = FakeAdapter("D1", auto=True, run_errors={"Calibrate": RuntimeError("IMU on fire")})
    r = rig(fake)
    result = r.call(1, "Calibrate").result
    assert result.status == "failed" and "IMU on fire" in result.reason
    assert r.call(2, "Arm").result.ok


def test_adapter_exception_is_logged_once_with_its_traceback(rig: Callable[..., Rig]) -> None:
    fake = FakeAdapter("D1", auto=True, run_errors={"Calibrate": RuntimeError("IMU on fire")})
    r = rig(fake)
    result = r.call(1, "Calibrate").result
    assert result == ActionResult(
        "failed", "internal error in the adapter: RuntimeError('IMU on fire')"
    )
    r.stop()
    errors = [
        e for e in read_log(r.log_dir / "uniform.log") if e["event"] == "uniform.adapter_error"
    ]
    assert len(errors) == 1
    assert errors[0]["call"] == "Calibrate" and "Traceback" in errors[0]["exception"]


class _CancelFails(FakeAdapter):
    """A fake whose cancel raises (an adapter bug)."""

    def cancel(self, handle: ActionHandle) -> None:
        raise RuntimeError("cancel exploded")


def test_adapter_exception_in_cancel_fails_the_action_and_the_actor_serves_on(
    rig: Callable[..., Rig],
) -> None:
    fake = _CancelFails("D1")
    r = rig(fake)
    r.run("fly", "FlyByX", 10)
    handle = fake.wait_started("FlyByX", WAIT_S)
    r.ref.tell(CancelAction("fly"))
    reply = r.finished()
    assert reply.token == "fly"
    assert reply.result == ActionResult(
        "failed", "internal error in the adapter: RuntimeError('cancel exploded')"
    )
    fake.finish(handle)  # a late done from the adapter is dropped, not answered twice
    r.run("next", "Arm")
    fake.finish(fake.wait_started("Arm", WAIT_S))
    assert r.finished().token == "next"
    assert r.inbox.empty()
    r.stop()
    log = read_log(r.log_dir / "uniform.log")
    errors = [e for e in log if e["event"] == "uniform.adapter_error"]
    assert len(errors) == 1 and errors[0]["call"] == "cancel"
    assert "Traceback" in errors[0]["exception"]


def test_duplicate_token_is_refused(rig: Callable[..., Rig]) -> None:
    fake = FakeAdapter("D1")
    r = rig(fake)
    r.run("x", "PauseFor", 5)
    fake.wait_started("PauseFor", WAIT_S)
    r.run("x", "PauseFor", 6)
    assert r.finished().result == ActionResult("failed", "duplicate token")
    fake.finish("PauseFor")
    assert r.finished().result.ok
    # Once finished, the token may be used again.
    r.run("x", "Arm")
    fake.finish(fake.wait_started("Arm", WAIT_S))
    reply = r.finished()
    assert (reply.token, reply.action, reply.result.ok) == ("x", "Arm", True)


def test_abort_cancels_running_actions(rig: Callable[..., Rig]) -> None:
    fake = FakeAdapter("D1")
    r = rig(fake)
    r.run("a", "FlyByX", 3)
    r.run("b", "PauseFor", 9)
    fake.wait_started("PauseFor", WAIT_S)
    r.ref.tell(Abort())
    replies = {reply.token: reply.result for reply in (r.finished(), r.finished())}
    assert replies == {
        "a": ActionResult("cancelled", "aborted"),
        "b": ActionResult("cancelled", "aborted"),
    }
    assert len(fake.calls_of("abort")) == 1


def test_telemetry_reaches_the_callback(rig: Callable[..., Rig]) -> None:
    fake = FakeAdapter("D4")
    r = rig(fake)
    first = r.telemetry.wait_for(1)[0]
    assert isinstance(first, Telemetry) and first.drone == "D4"
    fake.wait_for(lambda f: bool(f.calls_of("start")), WAIT_S)
    fake.push_telemetry(z_m=2.5)
    assert r.telemetry.wait_for(2)[-1].z_m == 2.5


def test_start_error_is_reported_and_stops_the_actor(rig: Callable[..., Rig]) -> None:
    fake = FakeAdapter("D1", start_error=AdapterError("D1: no heartbeat on udp:14550"))
    errors: list[AdapterError] = []
    reported = threading.Event()

    def on_start_error(exc: AdapterError) -> None:
        errors.append(exc)
        reported.set()

    r = rig(fake, on_start_error=on_start_error)
    assert reported.wait(WAIT_S)
    assert str(errors[0]) == "D1: no heartbeat on udp:14550"
    fake.wait_for(lambda f: f.closed, WAIT_S)
    with pytest.raises(pykka.ActorDeadError):
        r.ref.ask(Abort(), timeout=WAIT_S)
    log = read_log(r.log_dir / "uniform.log")
    assert any(e["event"] == "uniform.start_failed" and "no heartbeat" in e["error"] for e in log)


def test_stop_closes_the_adapter_and_answers_running_actions(rig: Callable[..., Rig]) -> None:
    fake = FakeAdapter("D1")
    r = rig(fake)
    r.run("p", "PauseFor", 100)
    fake.wait_started("PauseFor", WAIT_S)
    r.ref.stop(timeout=WAIT_S)
    assert fake.closed
    assert r.finished().result == ActionResult("cancelled", "uniform API stopped")


def test_uniform_log_is_json_lines(rig: Callable[..., Rig]) -> None:
    fake = FakeAdapter("D1", auto=True)
    r = rig(fake)
    r.call(7, "TakeOff", 1)
    r.call(8, "Takeoff", 3)
    r.stop()
    log = read_log(r.log_dir / "uniform.log")
    calls = [e for e in log if e["event"] == "uniform.call"]
    results = [e for e in log if e["event"] == "uniform.result"]
    assert [(e["token"], e["action"], e["args"]) for e in calls] == [
        (7, "TakeOff", [1]),
        (8, "Takeoff", [3]),
    ]
    assert [(e["token"], e["status"]) for e in results] == [(7, "failed"), (8, "ok")]
    assert all(e["drone"] == "D1" and "ts" in e for e in log)


# -- with the simulator ------------------------------------------------------


def test_actor_flies_the_simulator(rig: Callable[..., Rig], make_sim: SimFactory) -> None:
    sim = make_sim("S1")
    r = rig(sim)
    assert r.call(1, "Arm").result.ok
    assert r.call(2, "Takeoff", 3).result.ok
    assert r.call(3, "FlyByY", 2).result.ok
    assert r.call(4, "Disarm").result == ActionResult("failed", "in the air")
    r.run(5, "FlyByX", 40)
    assert sim.wait_until(lambda s: s.x_m > 1.0, WAIT_S)
    r.ref.tell(CancelAction(5))
    assert r.finished().result.status == "cancelled"
    assert r.call(6, "Land").result.ok
    assert r.call(7, "Disarm").result.ok
    assert r.call(8, "Jump").result.reason == "unknown action 'Jump'"
    # Bad calls are decoded away by the actor; the simulator never sees them.
    assert r.call(9, "Fly", 1.0).result.reason == "unknown action 'Fly'"
    assert "takes 1 argument" in r.call(10, "FlyByX").result.reason
    assert "finite" in r.call(11, "FlyByX", math.nan).result.reason
    s = sim.state
    assert s.landed and not s.armed and s.y_m == pytest.approx(2.0, abs=0.1)
    assert r.telemetry.count() > 10
    r.stop()
    adapter_log = [e["event"] for e in read_log(r.log_dir.parent / "S1-adapter.log")]
    assert "adapter.close" in adapter_log  # on_stop closed the adapter
    assert adapter_log.count("adapter.action.start") == 7  # the bad calls never reached it


def test_ground_station_bad_calls_fail_at_the_actor(
    rig: Callable[..., Rig], tmp_path: Path
) -> None:
    ground = GroundAdapter("GCS", GroundSettings(speedup=10.0), make_logger(None))
    r = rig(ground)
    assert r.call(1, "Jump").result.reason == "unknown action 'Jump'"
    assert "argument" in r.call(2, "PauseFor").result.reason
    assert r.call(3, "Takeoff", 5.0).result == ActionResult(
        "failed", "the ground station cannot Takeoff"
    )
    assert r.call(4, "PauseFor", 0.5).result.ok


# -- the space node actors call directly (adapters that answer at once) ------------------


def test_direct_calls_answer_inline_or_later_once_each(rig: Callable[..., Rig]) -> None:
    from eamos.actors.uniform_api import answers_at_once

    fake = FakeAdapter("D1", results={"Land": ActionResult("failed", "gusts")})
    r = rig(fake)
    space = r.ref.proxy().space.get(timeout=WAIT_S)
    assert answers_at_once(fake) and not answers_at_once(GroundAdapter("GCS", GroundSettings()))
    fake.auto = True
    # Finished inside adapter.run on this thread: returned, nothing sent.
    inline = space.run(RunAction("a", "Arm", (), r.collector))
    assert inline is not None and inline.result.ok and r.inbox.empty()
    # Bad input never reaches the adapter, and is answered the same way.
    refused = space.run(RunAction("b", "Teleport", (), r.collector))
    assert refused is not None and refused.result.status == "failed"
    fake.auto = False
    # Finished later, on another thread: sent to reply_to, once.
    assert space.run(RunAction("c", "FlyByX", (3.0,), r.collector)) is None
    handle = fake.wait_started("FlyByX", WAIT_S)
    threading.Thread(target=fake.finish, args=(handle, ActionResult("ok"))).start()
    reply = r.finished()
    assert (reply.token, reply.result.status) == ("c", "ok")
    # A running one cancelled directly; a second cancel changes nothing.
    assert space.run(RunAction("d", "FlyByY", (3.0,), r.collector)) is None
    fake.wait_started("FlyByY", WAIT_S)
    space.cancel("d")
    space.cancel("d")
    assert r.finished().result.status == "cancelled"
    assert r.inbox.empty()


def test_stopping_answers_a_directly_started_action_and_refuses_new_ones(
    rig: Callable[..., Rig],
) -> None:
    fake = FakeAdapter("D1")
    r = rig(fake)
    space = r.ref.proxy().space.get(timeout=WAIT_S)
    assert space.run(RunAction("fly", "FlyByX", (5.0,), r.collector)) is None
    handle = fake.wait_started("FlyByX", WAIT_S)
    r.ref.stop(timeout=WAIT_S)
    assert r.finished().result == ActionResult("cancelled", "uniform API stopped")
    fake.finish(handle, ActionResult("ok"))  # late: dropped, the caller had its answer
    late = space.run(RunAction("late", "Arm", (), r.collector))
    assert late is not None and late.result.status == "cancelled"
    assert r.inbox.empty()
