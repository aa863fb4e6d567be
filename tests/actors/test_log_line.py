"""A line its caller held back (log_line): the same line, with the time it happened."""

from __future__ import annotations

import json
import logging
from pathlib import Path

from eamos.logs import LogWriter, close_logger, log_line, make_logger


def test_a_held_line_is_the_line_with_the_time_of_what_it_says(tmp_path: Path) -> None:
    writer = LogWriter(delay_s=3600.0)
    batched = make_logger(tmp_path / "b.log", writer=writer, drone="D1").bind(node="n5")
    direct = make_logger(tmp_path / "d.log", drone="D1").bind(node="n5")
    for log in (batched, direct):
        fields = {"iteration": [1, 2], "status": "done", "s": "é\n", "x": float("nan")}
        log.info("mission.node.finished", ts=1.25, **fields)
        log_line(log, "info", "mission.node.finished", fields, at=1.25)
        log_line(log, "warning", "w", {"a": 1}, at=12.3456789)
        log_line(log, "error", "bad", {"a": 2}, at=13.0)  # an error: on disk at once
        log_line(log, "debug", "filtered", {"a": 3}, at=14.0)  # below the level: nothing
    writer.close()
    for name in ("b.log", "d.log"):
        text = (tmp_path / name).read_text().splitlines()
        got = [json.loads(line) for line in text]
        assert text[0].replace('"ts": 1.25, ', "").replace("}", ', "ts": 1.25}') == text[1]
        keys = ["drone", "node", "iteration", "status", "s", "x", "event", "level", "ts"]
        assert list(got[1]) == keys
        assert [(x["event"], x["level"], x["ts"]) for x in got[1:]] == [
            ("mission.node.finished", "info", 1.25),
            ("w", "warning", 12.345679),
            ("bad", "error", 13.0),
        ]
    close_logger(batched)
    close_logger(direct)


def test_without_a_time_it_is_now_and_a_traceback_goes_the_usual_way(tmp_path: Path) -> None:
    log = make_logger(tmp_path / "u.log", logging.DEBUG, drone="D1")
    log_line(log, "debug", "d", {"a": 1})
    try:
        raise ValueError("boom")
    except ValueError:
        log_line(log, "exception", "crashed", {"a": 2})
    got = [json.loads(line) for line in (tmp_path / "u.log").read_text().splitlines()]
    assert [(x["event"], x["level"]) for x in got] == [("d", "debug"), ("crashed", "error")]
    assert got[0]["ts"] > 1.7e9 and "ValueError: boom" in got[1]["exception"]
    close_logger(log)
