"""Per-drone JSON-lines logs (paper Table 5): mission, uniform and adapter logs.

Loggers are built per runtime with :func:`structlog.wrap_logger` instead of
structlog's global configuration, so two drone runtimes in one process (as in
tests) write to their own files.  The schema is documented in ``docs/logs.md``.
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from collections.abc import MutableMapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import structlog

LOG_NAMES = ("mission", "uniform", "adapter")


def _add_time(_: Any, __: str, event: MutableMapping[str, Any]) -> MutableMapping[str, Any]:
    event.setdefault("ts", round(time.time(), 6))
    return event


class _LockedFile:
    """A line-buffered file shared by threads; one write per event keeps lines whole.

    A write error (a full disk, a vanished folder) is never raised into the
    thread that logged: logging must not stop a flight.  The lost lines are
    counted (:attr:`write_errors`) and the first error is told once on stderr,
    naming the file.
    """

    def __init__(self, stream: IO[str], path: Path | None = None) -> None:
        self._stream = stream
        self._lock = threading.Lock()
        self.path = path
        self.write_errors = 0
        self.first_error: OSError | None = None

    def msg(self, message: str) -> None:
        with self._lock:
            if self._stream.closed:
                return
            try:
                self._stream.write(message + "\n")
                self._stream.flush()
            except OSError as exc:
                self._failed(exc)

    log = debug = info = warn = warning = error = critical = exception = msg

    def _failed(self, exc: OSError) -> None:
        """Count a lost line; tell the first error once (lock held)."""
        self.write_errors += 1
        if self.first_error is not None:
            return
        self.first_error = exc
        report_write_error(self.path, exc, "log lines are dropped and counted")

    def close(self) -> None:
        with self._lock:
            try:
                self._stream.close()
            except OSError as exc:  # the last buffered line could not be written
                self._failed(exc)


def report_write_error(path: Path | None, exc: OSError, consequence: str) -> None:
    """Tell stderr, once per caller, that ``path`` could not be written; never raises.

    stderr itself may be a file on the full disk (a node's ``node.out``): then
    there is nowhere left to tell, and the count in the report must do.
    """
    reason = exc.strerror or repr(exc)
    try:
        print(f"eamos: cannot write {path or 'a log'}: {reason} ({consequence})", file=sys.stderr)
    except (OSError, ValueError):
        pass


def write_errors(logger: Any) -> int:
    """How many lines the file behind a :func:`make_logger` logger could not write."""
    sink = getattr(logger, "_logger", None)
    return int(getattr(sink, "write_errors", 0))


class _Discard:
    def msg(self, message: str) -> None:
        pass

    log = debug = info = warn = warning = error = critical = exception = msg

    def close(self) -> None:
        pass


def make_logger(
    path: Path | None, level: int = logging.INFO, **context: Any
) -> structlog.typing.FilteringBoundLogger:
    """A JSON-lines logger writing to ``path`` (or discarding, when ``path`` is None).

    ``level`` filters before any rendering happens: debug events (every internal
    trigger) cost nothing unless asked for with ``level=logging.DEBUG``.
    """
    sink: _LockedFile | _Discard
    if path is None:
        sink = _Discard()
    else:
        path.parent.mkdir(parents=True, exist_ok=True)
        sink = _LockedFile(path.open("a", encoding="utf-8"), path)
    logger = structlog.wrap_logger(
        sink,
        processors=[
            structlog.contextvars.merge_contextvars,
            structlog.processors.add_log_level,
            _add_time,
            structlog.processors.format_exc_info,
            structlog.processors.JSONRenderer(sort_keys=False, default=str),
        ],
        wrapper_class=structlog.make_filtering_bound_logger(level),
        cache_logger_on_first_use=False,
    )
    return logger.bind(**context)  # type: ignore[no-any-return]


def close_logger(logger: Any) -> None:
    """Close the file behind a logger made by :func:`make_logger`."""
    sink = getattr(logger, "_logger", None)
    if sink is not None and hasattr(sink, "close"):
        sink.close()


@dataclass
class DroneLogs:
    """The three logs of one drone (paper Table 5)."""

    mission: Any
    uniform: Any
    adapter: Any

    @classmethod
    def open(cls, log_dir: Path | None, drone: str) -> DroneLogs:
        """Open ``mission.log``, ``uniform.log`` and ``adapter.log`` in ``log_dir``."""

        def one(name: str) -> Any:
            return make_logger(None if log_dir is None else log_dir / f"{name}.log", drone=drone)

        return cls(one("mission"), one("uniform"), one("adapter"))

    def close(self) -> None:
        for logger in (self.mission, self.uniform, self.adapter):
            close_logger(logger)

    def write_errors(self) -> int:
        """Log lines of the three logs that could not be written (a full disk)."""
        return sum(write_errors(x) for x in (self.mission, self.uniform, self.adapter))


def read_log(path: Path) -> list[dict[str, Any]]:
    """Read a JSON-lines log back (for tests, reports and notebooks)."""
    import json

    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line]
