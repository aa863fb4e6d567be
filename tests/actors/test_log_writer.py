"""One log writer per process: lines written in batches, in order, never lost at close.

Real files and the writer's real thread; every wait is on the file's content with a
deadline (the writer's delay is what is tested, not slept on).
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import MutableMapping
from pathlib import Path
from typing import Any

import pytest
import structlog

from eamos.logs import DroneLogs, LogWriter, make_logger, read_log, write_errors

WAIT_S = 30.0


def lines(path: Path) -> list[dict]:
    return read_log(path)


def wait_lines(path: Path, count: int) -> list[dict]:
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        got = lines(path)
        if len(got) >= count:
            return got
        time.sleep(0.01)  # test side only: polling a file another thread writes
    raise AssertionError(f"{path}: {len(lines(path))} lines, expected {count}")


def test_lines_reach_the_file_within_the_delay_in_order(tmp_path: Path) -> None:
    writer = LogWriter(delay_s=0.05)
    a = make_logger(tmp_path / "a.log", writer=writer, drone="D1")
    b = make_logger(tmp_path / "b.log", writer=writer, drone="D2")
    for i in range(300):
        a.info("x.a", i=i)
        b.warning("x.b", i=i)
    got_a = wait_lines(tmp_path / "a.log", 300)
    got_b = wait_lines(tmp_path / "b.log", 300)
    assert [x["i"] for x in got_a] == list(range(300))
    assert [x["i"] for x in got_b] == list(range(300))
    assert got_b[0]["level"] == "warning" and got_b[0]["drone"] == "D2"
    writer.close()


def test_nothing_queued_is_lost_at_close(tmp_path: Path) -> None:
    writer = LogWriter(delay_s=3600.0)  # only close can write these
    log = make_logger(tmp_path / "m.log", writer=writer, drone="D1")
    for i in range(50):
        log.info("x", i=i)
    writer.close()
    assert [x["i"] for x in lines(tmp_path / "m.log")] == list(range(50))
    log.info("late", i=50)  # after close: written at once, not dropped
    assert lines(tmp_path / "m.log")[-1]["event"] == "late"


def test_an_error_line_is_on_disk_before_the_call_returns(tmp_path: Path) -> None:
    writer = LogWriter(delay_s=3600.0)
    log = make_logger(tmp_path / "m.log", writer=writer, drone="D1")
    log.info("before")
    try:
        raise ValueError("boom")
    except ValueError:
        log.exception("crashed")
    got = lines(tmp_path / "m.log")  # no wait: already written, with what came before
    assert [x["event"] for x in got] == ["before", "crashed"]
    assert "ValueError: boom" in got[1]["exception"] and got[1]["level"] == "error"
    writer.close()


def test_drone_logs_share_a_process_writer_and_close_their_files(tmp_path: Path) -> None:
    writer = LogWriter(delay_s=3600.0)
    one = DroneLogs.open(tmp_path / "D1", "D1", writer)
    two = DroneLogs.open(tmp_path / "D2", "D2", writer)
    one.mission.info("mission.ready")
    two.uniform.info("uniform.start")
    one.close()  # writes what is queued; the shared writer lives on for D2
    assert lines(tmp_path / "D1" / "mission.log")[0]["event"] == "mission.ready"
    two.mission.info("mission.ready")
    two.close()
    assert [x["event"] for x in lines(tmp_path / "D2" / "uniform.log")] == ["uniform.start"]
    assert len(lines(tmp_path / "D2" / "mission.log")) == 1
    writer.close()


def test_the_line_is_the_one_structlog_json_renderer_writes(tmp_path: Path) -> None:
    """The one-step renderer writes what add_log_level + ts + format_exc_info + JSONRenderer did."""

    class Lines:
        def __init__(self) -> None:
            self.got: list[str] = []

        def msg(self, message: str) -> None:
            self.got.append(message)

        info = warning = error = exception = msg

    def stamp(_: Any, __: str, event: MutableMapping[str, Any]) -> MutableMapping[str, Any]:
        event.setdefault("ts", 1795392555.790144)
        return event

    before = Lines()
    reference = structlog.wrap_logger(
        before,
        processors=[
            structlog.processors.add_log_level,
            stamp,
            structlog.processors.format_exc_info,
            structlog.processors.JSONRenderer(sort_keys=False, default=str),
        ],
        wrapper_class=structlog.make_filtering_bound_logger(logging.INFO),
    ).bind(drone="D1")
    log = make_logger(tmp_path / "m.log", drone="D1")
    for logger in (reference, log):
        bound = logger.bind(node="n5")
        bound.info("mission.node.finished", iteration=[1, 2], status="done", ts=1.25)
        bound.warn("x", value=float("nan"), path=Path("p"), n={1: (2, 3)}, ts=2.5, s="é\n")
        try:
            raise ValueError("boom")
        except ValueError:
            bound.exception("crashed", ts=3.5)
    written = (tmp_path / "m.log").read_text().splitlines()
    assert written == before.got
    keys = ["drone", "node", "iteration", "status", "ts", "event", "level"]
    assert list(json.loads(written[0])) == keys
    assert "ValueError: boom" in json.loads(written[2])["exception"]


def test_lost_lines_are_counted_when_the_disk_is_full() -> None:
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full")
    writer = LogWriter(delay_s=3600.0)
    log = make_logger(Path("/dev/full"), writer=writer)
    for _ in range(5):
        log.info("x")
    assert write_errors(log) == 5
    writer.close()


def test_threads_that_flush_on_errors_keep_each_ones_lines_in_order(tmp_path: Path) -> None:
    writer = LogWriter(delay_s=0.01)
    log = make_logger(tmp_path / "m.log", writer=writer)

    def one(name: str) -> None:
        for i in range(200):
            (log.error if i % 10 == 0 else log.info)("x", who=name, i=i)

    threads = [threading.Thread(target=one, args=(f"t{k}",)) for k in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(WAIT_S)
    writer.close()
    got = lines(tmp_path / "m.log")
    assert len(got) == 800
    for k in range(4):
        assert [x["i"] for x in got if x["who"] == f"t{k}"] == list(range(200))
