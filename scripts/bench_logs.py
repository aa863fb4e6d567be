#!/usr/bin/env python3
"""What one log line costs the thread that logs it; prints JSON.

A node writes several ``info`` lines per trigger (``docs/logs.md``), on the
trigger's path.  Timed here, in the logging thread's own CPU time
(:func:`time.thread_time`, so the writer thread and other processes on a shared
machine count less), best of ``--repeat`` rounds of ``--lines`` lines, in µs per line:

* ``line``: ``log.info(event, **fields)`` on a :func:`eamos.logs.make_logger` logger
  writing through a :class:`~eamos.logs.LogWriter` (one processor,
  :func:`eamos.logs.render_line`);
* ``held_line``: the same line through :func:`eamos.logs.log_line` (a held line,
  stamped with the time it happened);
* ``line_four_processors``: the same line with structlog's own chain
  (``add_log_level``, a stamp, ``format_exc_info``, ``JSONRenderer(default=str)``),
  the same bound logger class and writer: what the one processor saves;
* ``filtered``: a ``debug`` line below the logger's level (never rendered).

Usage: ``python scripts/bench_logs.py [--lines 50000] [--repeat 5]``.
"""

from __future__ import annotations

import argparse
import json
import logging
import tempfile
import time
import timeit
from collections.abc import Callable, MutableMapping
from pathlib import Path
from typing import Any

import structlog

from eamos.logs import LogWriter, close_logger, log_line, make_logger

FIELDS = {"node": "n5", "iteration": [1, 2], "status": "done"}


def stamp(_: Any, __: str, event: MutableMapping[str, Any]) -> MutableMapping[str, Any]:
    """The ``ts`` of :func:`eamos.logs.render_line`, as a processor of its own."""
    event.setdefault("ts", round(time.time(), 6))
    return event


def per_line_us(call: Callable[[], object], lines: int, repeat: int) -> float:
    timer = timeit.Timer(call, timer=time.thread_time)
    return round(min(timer.repeat(number=lines, repeat=repeat)) / lines * 1e6, 2)


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--lines", type=int, default=50_000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_logs-") as tmp:
        writer = LogWriter()
        log = make_logger(Path(tmp) / "one.log", writer=writer, drone="D1")
        four = structlog.wrap_logger(
            writer(Path(tmp) / "four.log"),
            processors=[
                structlog.processors.add_log_level,
                stamp,
                structlog.processors.format_exc_info,
                structlog.processors.JSONRenderer(default=str),
            ],
            wrapper_class=structlog.make_filtering_bound_logger(logging.INFO),
        ).bind(drone="D1")
        calls: dict[str, Callable[[], object]] = {
            "line": lambda: log.info("mission.node.finished", **FIELDS),
            "held_line": lambda: log_line(log, "info", "mission.node.finished", FIELDS, 1.0),
            "line_four_processors": lambda: four.info("mission.node.finished", **FIELDS),
            "filtered": lambda: log.debug("mission.trigger.in", **FIELDS),
        }
        report = {name: per_line_us(call, args.lines, args.repeat) for name, call in calls.items()}
        writer.close()
        close_logger(log)
    print(json.dumps({"us_per_line": report, "lines": args.lines, "repeat": args.repeat}))


if __name__ == "__main__":
    main()
