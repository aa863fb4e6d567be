"""The re-armable alarm, and the executive's progress batches on it (no thread per interval).

Real threads and the real monotonic clock; waits are on events with generous
timeouts, and the only timing asserted is a lower bound (a batch never goes
out before its interval) plus "it went out at all".
"""

from __future__ import annotations

import threading
import time
from typing import Any

from eamos.actors.alarm import Alarm
from eamos.actors.dispatch import Dispatcher
from eamos.actors.executive import PROGRESS_INTERVAL_S, DroneExecutive
from eamos.actors.messages import NodeEvent
from eamos.compiler import compile_mission
from eamos.logs import make_logger
from eamos.net import wire
from eamos.net.progress import progress_events

WAIT_S = 20.0


def test_an_alarm_fires_once_per_arm_on_one_thread() -> None:
    fired = threading.Event()
    calls: list[float] = []

    def fire() -> None:
        calls.append(time.monotonic())
        fired.set()

    alarm = Alarm(fire, name="test-alarm")
    assert alarm.thread is None and not alarm.armed
    threads: set[threading.Thread | None] = set()
    try:
        for _ in range(3):
            fired.clear()
            armed_at = time.monotonic()
            alarm.arm(0.02)
            assert fired.wait(WAIT_S)
            assert calls[-1] - armed_at >= 0.02 - 1e-3
            threads.add(alarm.thread)
        assert len(calls) == 3 and alarm.fired == 3
        assert len(threads) == 1  # the same thread every time
    finally:
        alarm.stop()
    assert alarm.thread is not None and not alarm.thread.is_alive()


def test_a_cancelled_or_stopped_alarm_does_not_fire_and_rearming_moves_the_deadline() -> None:
    fired = threading.Event()
    alarm = Alarm(fired.set, name="test-alarm")
    alarm.start()
    try:
        alarm.arm(0.05)
        alarm.cancel()
        assert not alarm.armed
        assert not fired.wait(0.2)
        # Armed far out, then sooner: the sooner deadline counts.
        alarm.arm(60.0)
        alarm.arm(0.01)
        assert fired.wait(WAIT_S)
        fired.clear()
        alarm.arm(0.05)
    finally:
        alarm.stop()
    assert not fired.wait(0.2)
    alarm.arm(0.0)  # after stop: nothing
    assert not fired.wait(0.1) and alarm.fired == 1


def test_an_alarm_survives_a_failing_callback() -> None:
    errors: list[BaseException] = []
    done = threading.Event()
    calls = 0

    def fire() -> None:
        nonlocal calls
        calls += 1
        if calls == 1:
            raise RuntimeError("boom")
        done.set()

    alarm = Alarm(fire, on_error=errors.append)
    try:
        alarm.arm(0.0)
        deadline = time.monotonic() + WAIT_S
        while alarm.fired < 1 and time.monotonic() < deadline:
            time.sleep(0.005)  # test-side polling of a counter, not product code
        alarm.arm(0.0)
        assert done.wait(WAIT_S)
    finally:
        alarm.stop()
    assert [str(e) for e in errors] == ["boom"]


MISSION = """
func SEQ_Main() {
    D1.Arm()
    D1.Disarm()
}
"""


class _Ground:
    """What the executive sends to the ground station, with an event per message."""

    def __init__(self) -> None:
        self.sent: list[tuple[float, Any]] = []
        self.cond = threading.Condition()

    def __call__(self, msg: Any) -> None:
        with self.cond:
            self.sent.append((time.monotonic(), msg))
            self.cond.notify_all()

    def progress(self) -> list[tuple[float, wire.Progress]]:
        with self.cond:
            return [(t, m) for t, m in self.sent if isinstance(m, wire.Progress)]

    def wait_progress(self, count: int) -> bool:
        with self.cond:
            return self.cond.wait_for(lambda: len(self.progress()) >= count, WAIT_S)


def _executive(tmp_path: Any, ground: _Ground) -> tuple[Dispatcher, Any]:
    program = compile_mission(MISSION, "m.go").programs["D1"]
    dispatcher = Dispatcher(workers=1, name="test-exec")
    log = make_logger(tmp_path / "mission.log")
    ref = DroneExecutive.start(dispatcher, program, {}, None, ground, log)
    return dispatcher, ref


def test_progress_goes_out_by_the_alarm_with_no_thread_per_interval(tmp_path: Any) -> None:
    ground = _Ground()
    dispatcher, ref = _executive(tmp_path, ground)
    try:
        ref.tell(NodeEvent("n1", "running", "Arm"))  # the first: sent at once
        assert ground.wait_progress(1)
        threads_before = threading.active_count()
        for i in range(3):
            previous = ground.progress()[-1][0]
            ref.tell(NodeEvent("n1", "waiting", "Arm", detail=f"a{i}"))
            ref.tell(NodeEvent("n1", "running", "Arm", detail=f"b{i}"))
            assert ground.wait_progress(2 + i)
            sent_at, batch = ground.progress()[-1]
            # Batched: both events in one message, not before the interval.
            assert [m.detail["detail"] for m in progress_events(batch)] == [f"a{i}", f"b{i}"]
            assert sent_at - previous >= PROGRESS_INTERVAL_S - 1e-3
            assert threading.active_count() == threads_before  # no Timer thread per interval
    finally:
        ref.stop()
        dispatcher.shutdown()


def test_pending_progress_is_sent_at_stop(tmp_path: Any) -> None:
    ground = _Ground()
    dispatcher, ref = _executive(tmp_path, ground)
    try:
        ref.tell(NodeEvent("n1", "running", "Arm"))  # sent at once
        ref.tell(NodeEvent("n1", "waiting", "Arm", detail="last"))  # waits for the interval
    finally:
        ref.stop()  # before the interval is over: the batch goes out now
        dispatcher.shutdown()
    progress = ground.progress()
    assert len(progress) == 2
    assert progress[-1][1].detail["detail"] == "last"
    assert not any(t.name.startswith("eamos-progress-") for t in threading.enumerate())
