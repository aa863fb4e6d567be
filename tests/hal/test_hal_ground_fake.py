"""GroundAdapter (PauseFor only) and FakeAdapter (the test double at the adapter seam)."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from eamos.hal.api import ActionHandle, ActionResult, AdapterError
from eamos.hal.fake import Call, FakeAdapter, fake_adapter_from_settings
from eamos.hal.station_adapter import GroundAdapter, GroundSettings
from eamos.logs import close_logger, make_logger, read_log

from .hal_helpers import WAIT_S, Done, TelemetrySink, cmd, do

# Generous for a loaded 2-core machine; a healthy run takes seconds.
pytestmark = pytest.mark.timeout(180)

# -- ground station ----------------------------------------------------------


@pytest.fixture
def ground(tmp_path: Path) -> Iterator[GroundAdapter]:
    log = make_logger(tmp_path / "adapter.log", drone="GCS")
    adapter = GroundAdapter("GCS", GroundSettings(speedup=10.0), log)
    yield adapter
    adapter.close()
    close_logger(log)


def test_ground_sends_one_static_sample(ground: GroundAdapter) -> None:
    sink = TelemetrySink()
    ground.start(sink)
    (sample,) = sink.snapshot()
    assert sample.drone == "GCS" and sample.landed and not sample.armed
    assert (sample.x_m, sample.y_m, sample.z_m) == (0.0, 0.0, 0.0)
    assert (sample.lat_deg, sample.lon_deg) == (46.6103, 14.2640)
    assert do(ground, "PauseFor", 1.0).ok
    assert sink.count() == 1


def test_ground_pause_honours_speedup(ground: GroundAdapter) -> None:
    ground.start(TelemetrySink())
    t0 = time.monotonic()
    assert do(ground, "PauseFor", 5.0).ok  # 0.5 s at speedup 10
    wall = time.monotonic() - t0
    assert 0.5 <= wall < 0.5 + 5.0


def test_ground_pauses_finish_in_deadline_order(ground: GroundAdapter) -> None:
    ground.start(TelemetrySink())
    order: list[float] = []
    lock = threading.Lock()
    dones = []
    for duration in (3.0, 1.0, 2.0, 0.0):
        done = Done()

        def record(result: ActionResult, d: float = duration, inner: Done = done) -> None:
            with lock:
                order.append(d)
            inner(result)

        ground.run(cmd("PauseFor", duration), record)
        dones.append(done)
    for done in dones:
        assert done.wait().ok
    assert order == [0.0, 1.0, 2.0, 3.0]


def test_ground_cannot_fly(ground: GroundAdapter) -> None:
    ground.start(TelemetrySink())
    assert do(ground, "Takeoff", 5.0) == ActionResult("failed", "the ground station cannot Takeoff")
    assert do(ground, "Arm").reason == "the ground station cannot Arm"
    assert "duration_s" in do(ground, "PauseFor", -1.0).reason


def test_ground_cancel_abort_close(ground: GroundAdapter, tmp_path: Path) -> None:
    ground.start(TelemetrySink())
    a, b, c = Done(), Done(), Done()
    handle = ground.run(cmd("PauseFor", 10_000.0), a)
    ground.run(cmd("PauseFor", 10_000.0), b)
    ground.cancel(handle)
    assert a.wait().status == "cancelled"
    ground.cancel(handle)  # finished: nothing happens
    ground.abort()
    assert b.wait() == ActionResult("cancelled", "aborted")
    ground.run(cmd("PauseFor", 10_000.0), c)
    ground.close()
    assert c.wait() == ActionResult("cancelled", "adapter closed")
    ground.close()
    assert a.calls == b.calls == c.calls == 1
    events = [e["event"] for e in read_log(tmp_path / "adapter.log")]
    assert events.count("adapter.action.start") == 3
    assert events.count("adapter.action.end") == 3


def test_ground_settings() -> None:
    assert GroundSettings.from_mapping({"adapter": "ground", "speedup": 4}).speedup == 4.0
    with pytest.raises(AdapterError, match=r"^hal\.speedup: must be > 0"):
        GroundSettings.from_mapping({"speedup": 0})
    with pytest.raises(AdapterError, match=r"^hal\.spedup: .*did you mean 'speedup'"):
        GroundSettings.from_mapping({"spedup": 4})


# -- fake --------------------------------------------------------------------


def test_fake_records_calls_and_finishes_on_demand() -> None:
    fake = FakeAdapter("D1")
    sink = TelemetrySink()
    fake.start(sink)
    assert sink.count() == 1
    done = Done()
    handle = fake.run(cmd("Takeoff", 5.0), done)
    assert fake.wait_started("Takeoff", WAIT_S) == handle
    assert fake.running == [handle] and not done.is_done
    fake.finish("Takeoff", ActionResult("failed", "wind"))
    assert done.wait() == ActionResult("failed", "wind")
    assert fake.result_of(handle) == ActionResult("failed", "wind")
    assert fake.running == []
    with pytest.raises(LookupError):
        fake.finish(handle)
    assert [c.method for c in fake.calls] == ["start", "run", "finish"]
    assert fake.calls_of("run") == [Call("run", "Takeoff", (5.0,), handle)]


def test_fake_auto_mode() -> None:
    fake = FakeAdapter("D1", auto=True, results={"Land": ActionResult("failed", "no")})
    fake.start(TelemetrySink())
    assert do(fake, "Arm").ok
    assert do(fake, "Land") == ActionResult("failed", "no")
    assert fake.wait_started("Arm", WAIT_S).action == "Arm"


def test_fake_cancel_and_abort() -> None:
    fake = FakeAdapter("D1")
    fake.start(TelemetrySink())
    a, b, c = Done(), Done(), Done()
    ha = fake.run(cmd("FlyByX", 1.0), a)
    fake.run(cmd("PauseFor", 9.0), b)
    fake.run(cmd("TurnOn"), c)
    fake.cancel(ha)
    assert a.wait() == ActionResult("cancelled", "cancelled")
    fake.cancel(ha)  # finished: recorded, nothing else
    fake.abort()
    assert b.wait().status == c.wait().status == "cancelled"
    assert a.calls == 1
    assert [c.method for c in fake.calls].count("cancel") == 2
    assert fake.calls_of("abort") == [Call("abort")]
    fake.close()
    fake.close()
    assert fake.closed


def test_fake_push_telemetry_keeps_other_fields() -> None:
    fake = FakeAdapter("D7")
    sink = TelemetrySink()
    fake.start(sink)
    fake.push_telemetry(z_m=3.0, armed=True)
    fake.push_telemetry(x_m=1.0)
    last = sink.snapshot()[-1]
    assert (last.drone, last.x_m, last.z_m, last.armed) == ("D7", 1.0, 3.0, True)


def test_fake_wait_started_across_threads() -> None:
    fake = FakeAdapter("D1")
    fake.start(TelemetrySink())
    worker = threading.Thread(target=lambda: [fake.run(cmd("Arm"), Done()) for _ in range(2)])
    worker.start()
    second = fake.wait_started("Arm", WAIT_S, count=2)
    worker.join(WAIT_S)
    assert [h.action for h in fake.running] == ["Arm", "Arm"] and second == fake.running[1]
    with pytest.raises(TimeoutError):
        fake.wait_started("Land", 0.05)
    fake.wait_for(lambda f: len(f.running) == 2, WAIT_S)


def test_fake_errors() -> None:
    fake = FakeAdapter("D1", start_error=AdapterError("no link"))
    with pytest.raises(AdapterError, match="no link"):
        fake.start(TelemetrySink())
    fake = FakeAdapter("D1", run_errors={"Arm": RuntimeError("boom")})
    fake.start(TelemetrySink())
    with pytest.raises(RuntimeError, match="boom"):
        fake.run(cmd("Arm"), Done())
    assert isinstance(fake.calls_of("run")[0].handle, ActionHandle)


def test_fake_from_settings() -> None:
    assert not fake_adapter_from_settings("D1", {"adapter": "fake", "auto": False}, None).auto
    with pytest.raises(AdapterError, match=r"^hal\.auto: "):
        fake_adapter_from_settings("D1", {"auto": "yes"}, None)
    with pytest.raises(AdapterError, match=r"^hal\.speedup: unknown"):
        fake_adapter_from_settings("D1", {"speedup": 2}, None)
