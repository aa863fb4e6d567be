"""Per-drone JSON-lines logs (paper Table 5): mission, uniform and adapter logs.

structlog is used as its documentation describes, per runtime rather than through
its global configuration, so that two drone runtimes in one process (as in tests)
write to their own files.  :func:`make_logger` wraps a *logger* in structlog's sense
(an object with one method per level, handed the rendered line): a :class:`LogFile`,
or a :class:`BatchedLogFile` from a :class:`LogWriter` (a logger factory), with
:func:`structlog.wrap_logger`, a bound logger class from
:func:`structlog.make_filtering_bound_logger` and the processors :data:`PROCESSORS`.
The schema is documented in ``docs/logs.md``.
"""

from __future__ import annotations

import atexit
import json
import logging
import sys
import threading
import time
from collections.abc import MutableMapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, Protocol

import structlog

LOG_NAMES = ("mission", "uniform", "adapter")

#: A field :func:`log_line` passes: when what the line tells of happened (epoch seconds).
#: :func:`render_line` takes it out of the line and makes it the line's ``ts``.
HAPPENED_AT = "_happened_at"
#: The context key of the file behind a :func:`make_logger` logger (for
#: :func:`close_logger` and :func:`write_errors`); never written.
LOG_FILE = "_log_file"


#: ``json.dumps(line, default=str)``, its encoder made once rather than per line.  No
#: cycle check: a line's fields are plain values the runtime made.
_ENCODE = json.JSONEncoder(default=str, check_circular=False).encode
_add_log_level = structlog.processors.add_log_level
_format_exc_info = structlog.processors.format_exc_info


def render_line(logger: Any, method: str, event: MutableMapping[str, Any]) -> str:
    """The one structlog processor of a :func:`make_logger` logger: the line.

    What structlog's ``add_log_level``, a ``ts`` stamp, ``format_exc_info`` and
    ``JSONRenderer(default=str)`` write, in one step: the context, the fields,
    ``event``, ``level`` (``warn`` is ``warning``, ``exception`` is ``error``), ``ts``
    (epoch seconds to the microsecond; kept if the caller gave one), and ``exception``
    (a traceback), one JSON object; a value JSON does not know is written as its
    ``str``.  One processor rather than four: every trigger writes several lines
    (``scripts/bench_logs.py`` times both).  :data:`HAPPENED_AT` (from
    :func:`log_line`) is taken out and becomes ``ts``; the bound :data:`LOG_FILE` is
    not written.
    """
    event.pop(LOG_FILE, None)
    at = event.pop(HAPPENED_AT, None)
    event = _add_log_level(logger, method, event)
    if "ts" not in event:
        event["ts"] = round(time.time() if at is None else at, 6)
    if "exc_info" in event:
        event = _format_exc_info(logger, method, event)
    return _ENCODE(event)


class LogFile:
    """A structlog logger writing each line to a file shared by threads, at once.

    One write per event under a lock keeps lines whole.  A write error (a full
    disk, a vanished folder) is never raised into the thread that logged: logging
    must not stop a flight.  The lost lines are counted (:attr:`write_errors`) and
    the first error is told once on stderr, naming the file.
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

    log = debug = info = warn = warning = error = critical = exception = fatal = msg

    def write_lines(self, lines: list[str]) -> None:
        """Write ``lines`` (each without its newline) with one write and one flush."""
        with self._lock:
            if self._stream.closed:
                return
            try:
                self._stream.write("\n".join(lines) + "\n")
                self._stream.flush()
            except OSError as exc:
                self._failed(exc, len(lines))

    def _failed(self, exc: OSError, lost: int = 1) -> None:
        """Count lost lines; tell the first error once (lock held)."""
        self.write_errors += lost
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


#: The longest a log line waits in memory before the writer puts it in its file.
LOG_FLUSH_DELAY_S = 0.2
#: A batch this long is written at once, whatever the delay.
LOG_BATCH_MAX = 4096


class LogWriter:
    """Writes the lines of many log files in batches, from one thread (one per process).

    A logger factory in structlog's sense: ``writer(path)`` is a
    :class:`BatchedLogFile`, a logger whose lines this writer puts in ``path``.
    A line is rendered on the thread that logs it and queued here; the writer's
    thread writes every file's queued lines with one write and one flush each,
    at most :data:`LOG_FLUSH_DELAY_S` after the first of them was queued (it
    waits on an event: a full batch, :meth:`flush` or :meth:`close` end the
    wait early).  Nothing is lost at exit: :meth:`close` (called by
    :meth:`DroneLogs.close`, and at interpreter exit) writes what is queued,
    and a line at ``error`` level or above is written at once, with what was
    queued before it, so a crash's traceback is on disk before anything else
    happens.  Lines of one file keep their order.
    """

    def __init__(self, delay_s: float = LOG_FLUSH_DELAY_S) -> None:
        self.delay_s = delay_s
        self._lock = threading.Lock()  # guards the queue
        self._write_lock = threading.Lock()  # one batch at a time, taken and written in order
        self._queue: list[tuple[LogFile, str]] = []
        self._queued = threading.Event()  # the queue is not empty
        self._hurry = threading.Event()  # write now (full batch, flush, close)
        self._closed = False
        self._thread: threading.Thread | None = None
        atexit.register(self.close)

    def __call__(self, path: Path) -> BatchedLogFile:
        """A logger appending to ``path`` through this writer (its folder made)."""
        return BatchedLogFile(open_log_file(path), self)

    def put(self, sink: LogFile, line: str) -> None:
        """Queue one line for ``sink``'s file (written within the delay)."""
        with self._lock:
            if self._closed:
                sink.msg(line)  # after close (a late line at exit): written at once
                return
            self._queue.append((sink, line))
            if len(self._queue) == 1:
                self._queued.set()
                if self._thread is None:
                    self._thread = threading.Thread(
                        target=self._run, name="eamos-log-writer", daemon=True
                    )
                    self._thread.start()
            elif len(self._queue) >= LOG_BATCH_MAX:
                self._hurry.set()

    def flush(self) -> None:
        """Write every queued line now, on the calling thread."""
        # Taken and written under one lock: a later batch never overtakes an earlier one.
        with self._write_lock:
            with self._lock:
                batch, self._queue = self._queue, []
                self._queued.clear()
            self._write(batch)

    def close(self) -> None:
        """Write what is queued and stop the thread; later lines are written at once."""
        with self._lock:
            self._closed = True
        self._hurry.set()
        self._queued.set()
        self.flush()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(10.0)
        atexit.unregister(self.close)

    def _run(self) -> None:
        while True:
            self._queued.wait()
            # The batching delay: lines gather for at most delay_s (a full batch,
            # flush or close end it early).  Not a synchronisation: nothing waits on it.
            self._hurry.wait(self.delay_s)
            self._hurry.clear()
            self.flush()
            with self._lock:
                if self._closed and not self._queue:
                    return

    @staticmethod
    def _write(batch: list[tuple[LogFile, str]]) -> None:
        per_file: dict[LogFile, list[str]] = {}
        for sink, line in batch:
            per_file.setdefault(sink, []).append(line)
        for sink, lines in per_file.items():
            sink.write_lines(lines)


class BatchedLogFile:
    """A structlog logger handing its lines to a :class:`LogWriter` (errors: written at once)."""

    def __init__(self, file: LogFile, writer: LogWriter) -> None:
        self._file = file
        self._writer = writer
        self.path = file.path

    @property
    def write_errors(self) -> int:
        """Lines lost so far (what is queued is written first, so it counts)."""
        self._writer.flush()
        return self._file.write_errors

    def msg(self, message: str) -> None:
        self._writer.put(self._file, message)

    log = debug = info = warn = warning = msg

    def urgent(self, message: str) -> None:
        """An error: on disk before the caller goes on (it may be the last line)."""
        self._writer.put(self._file, message)
        self._writer.flush()

    error = critical = exception = fatal = urgent

    def close(self) -> None:
        self._writer.flush()
        self._file.close()


def open_log_file(path: Path) -> LogFile:
    """A :class:`LogFile` appending to ``path`` (its folder made)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    return LogFile(path.open("a", encoding="utf-8"), path)


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


class _Discard:
    """A structlog logger that writes nothing (a :func:`make_logger` without a path)."""

    def msg(self, message: str) -> None:
        pass

    log = debug = info = warn = warning = error = critical = exception = fatal = msg


def make_logger(
    path: Path | None,
    level: int = logging.INFO,
    writer: LogWriter | None = None,
    **context: Any,
) -> structlog.typing.FilteringBoundLogger:
    """A JSON-lines logger writing to ``path`` (or discarding, when ``path`` is None).

    ``level`` filters before any rendering happens: debug events (every internal
    trigger) cost nothing unless asked for with ``level=logging.DEBUG``.  With a
    ``writer`` the lines are written in batches by it (see :class:`LogWriter`);
    without, each line is written and flushed by the thread that logs it.
    ``context`` is bound: every line carries it, first.
    """
    sink: LogFile | BatchedLogFile | _Discard
    if path is None:
        sink = _Discard()
    else:
        sink = open_log_file(path) if writer is None else writer(path)
        # Bound first (and dropped by the first processor), so that close_logger and
        # write_errors find the file of this logger and of every logger bound from it.
        context = {LOG_FILE: sink, **context}
    logger: structlog.typing.FilteringBoundLogger = structlog.wrap_logger(
        sink,
        # No contextvars merge: no part of EAMOS binds context variables.
        processors=[render_line],
        wrapper_class=structlog.make_filtering_bound_logger(level),
        cache_logger_on_first_use=False,
    )
    return logger.bind(**context)


def _log_file(logger: Any) -> LogFile | BatchedLogFile | None:
    """The file behind a :func:`make_logger` logger (None for any other logger)."""
    if not isinstance(logger, structlog.BoundLoggerBase):
        return None
    sink = structlog.get_context(logger).get(LOG_FILE)
    return sink if isinstance(sink, LogFile | BatchedLogFile) else None


def write_errors(logger: Any) -> int:
    """How many lines the file behind a :func:`make_logger` logger could not write."""
    sink = _log_file(logger)
    return 0 if sink is None else sink.write_errors


def close_logger(logger: Any) -> None:
    """Close the file behind a logger made by :func:`make_logger` (or bound from one)."""
    sink = _log_file(logger)
    if sink is not None:
        sink.close()


#: A log line held back by its caller: (logger, method, event, fields, its time.time()),
#: written with :func:`log_line`.
LogLine = tuple[Any, str, str, dict[str, Any], float]


def log_line(
    logger: Any, method: str, event: str, fields: dict[str, Any], at: float | None = None
) -> None:
    """``logger.<method>(event, **fields)`` for a line its caller held back: ``ts`` is ``at``.

    The same line (fields, key order, ``level``) as the call would write, stamped
    with ``at`` (``time.time()`` when what it says happened; default now) rather than
    with the time of writing: a node writes its turn's lines once its triggers to
    other drones went out (:mod:`eamos.actors.node`), each with its own time.
    """
    if at is None:
        getattr(logger, method)(event, **fields)
    else:
        getattr(logger, method)(event, **fields, **{HAPPENED_AT: at})


@dataclass
class DroneLogs:
    """The three logs of one drone (paper Table 5), written by one :class:`LogWriter`."""

    mission: Any
    uniform: Any
    adapter: Any
    writer: LogWriter | None = None
    owns_writer: bool = False

    @classmethod
    def open(cls, log_dir: Path | None, drone: str, writer: LogWriter | None = None) -> DroneLogs:
        """Open ``mission.log``, ``uniform.log`` and ``adapter.log`` in ``log_dir``.

        ``writer``: the process's writer, shared by the runtimes of one process;
        without one the logs get their own (closed with them).
        """
        owns = writer is None and log_dir is not None
        if owns:
            writer = LogWriter()

        def one(name: str) -> Any:
            path = None if log_dir is None else log_dir / f"{name}.log"
            return make_logger(path, writer=writer, drone=drone)

        return cls(one("mission"), one("uniform"), one("adapter"), writer, owns)

    def close(self) -> None:
        if self.writer is not None:
            self.writer.flush()
        for logger in (self.mission, self.uniform, self.adapter):
            close_logger(logger)
        if self.owns_writer and self.writer is not None:
            self.writer.close()

    def write_errors(self) -> int:
        """Log lines of the three logs that could not be written (a full disk)."""
        return sum(write_errors(x) for x in (self.mission, self.uniform, self.adapter))


def read_log(path: Path) -> list[dict[str, Any]]:
    """Read a JSON-lines log back (for tests, reports and notebooks)."""
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line]


class EventLog(Protocol):
    """What EAMOS code calls on a log: one method per level, an event name and its fields.

    A logger of :func:`make_logger` is one (any structlog bound logger is), and so is
    the uniform API's :class:`~eamos.actors.uniform_api.UniformLog`.  The fields are
    whatever the event carries: JSON-like values.
    """

    def debug(self, event: str, **fields: Any) -> None: ...

    def info(self, event: str, **fields: Any) -> None: ...

    def warning(self, event: str, **fields: Any) -> None: ...

    def error(self, event: str, **fields: Any) -> None: ...

    def exception(self, event: str, **fields: Any) -> None: ...
