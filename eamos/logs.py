"""Per-drone JSON-lines logs (paper Table 5): mission, uniform and adapter logs.

Loggers are built per runtime with :func:`structlog.wrap_logger` instead of
structlog's global configuration, so two drone runtimes in one process (as in
tests) write to their own files.  The schema is documented in ``docs/logs.md``.
"""

from __future__ import annotations

import atexit
import json
import json.encoder
import logging
import sys
import threading
import time
from collections.abc import Callable, MutableMapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, Protocol

import structlog

LOG_NAMES = ("mission", "uniform", "adapter")


#: Method names that are not their level's name (as structlog's ``add_log_level``).
_LEVEL_OF = {"warn": "warning", "exception": "error"}


def _line_encoder() -> Callable[[Any], str]:
    """``json.dumps(obj, default=str)``, with its C encoder built once, not per line.

    Without cycle checks: a log line's fields are plain values the runtime made.
    """
    c_make_encoder = getattr(json.encoder, "c_make_encoder", None)
    if c_make_encoder is None:  # a Python without the C accelerator
        return json.JSONEncoder(default=str).encode
    chunks = c_make_encoder(
        None, str, json.encoder.encode_basestring_ascii, None, ": ", ", ", False, False, True
    )
    return lambda obj: "".join(chunks(obj, 0))


_ENCODE = _line_encoder()


def _render_line(
    logger: Any, method: str, event: MutableMapping[str, Any], at: float | None = None
) -> str:
    """structlog's ``add_log_level``, the ``ts`` stamp, ``format_exc_info`` and
    ``JSONRenderer(sort_keys=False, default=str)`` in one step: same line, same key
    order, a quarter of the calls (every trigger writes several lines).  ``at``:
    the stamp of a line written after the moment it tells of (default now)."""
    event["level"] = _LEVEL_OF.get(method, method)
    if "ts" not in event:
        event["ts"] = round(time.time() if at is None else at, 6)
    if "exc_info" in event:
        event = structlog.processors.format_exc_info(logger, method, event)
    return _ENCODE(event)


def _event_dict(bound: Any, event: str, fields: dict[str, Any]) -> dict[str, Any]:
    """What structlog hands its processors: the bound context, the fields, ``event``."""
    event_dict: dict[str, Any] = bound._context.copy()
    event_dict.update(fields)
    event_dict["event"] = event
    return event_dict


def _fast_method(name: str, slow: Callable[..., Any]) -> Callable[..., Any]:
    """A bound logger's ``name`` method: :func:`_render_line` called directly.

    What structlog's own method does when the processor chain is ``[_render_line]``
    (the context, the keywords, then ``event``; the sink's method of that name gets
    the line), without its generic chain: that took half the cost of a line, and
    every trigger writes several.  Positional arguments (``%`` interpolation) take
    structlog's way (``slow``).
    """

    def method(self: Any, event: str, *args: Any, **kw: Any) -> Any:
        if args:
            return slow(self, event, *args, **kw)
        sink = self._logger
        return getattr(sink, name)(_render_line(sink, name, _event_dict(self, event, kw)))

    return method


def _fast_wrapper(level: int) -> type[Any]:
    """structlog's filtering bound logger for ``level``, its enabled methods made direct."""
    base = structlog.make_filtering_bound_logger(level)
    methods: dict[str, Any] = {}
    for name, value in _LEVELS.items():
        if value >= level:
            methods[name] = _fast_method(name, getattr(base, name))
    for alias, name in (("warn", "warning"), ("fatal", "critical"), ("msg", "info")):
        if name in methods:
            methods[alias] = methods[name]
    return type(f"Direct{base.__name__}", (base,), methods)


_LEVELS = {
    "debug": logging.DEBUG,
    "info": logging.INFO,
    "warning": logging.WARNING,
    "error": logging.ERROR,
    "critical": logging.CRITICAL,
}
#: Level -> bound-logger class of :func:`make_logger` (built once, for the named levels).
_WRAPPERS: dict[int, type[Any]] = {value: _fast_wrapper(value) for value in _LEVELS.values()}


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
        self._queue: list[tuple[_LockedFile, str]] = []
        self._queued = threading.Event()  # the queue is not empty
        self._hurry = threading.Event()  # write now (full batch, flush, close)
        self._closed = False
        self._thread: threading.Thread | None = None
        atexit.register(self.close)

    def put(self, sink: _LockedFile, line: str) -> None:
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
    def _write(batch: list[tuple[_LockedFile, str]]) -> None:
        per_file: dict[_LockedFile, list[str]] = {}
        for sink, line in batch:
            per_file.setdefault(sink, []).append(line)
        for sink, lines in per_file.items():
            sink.write_lines(lines)


class _BatchedFile:
    """A logger sink that hands its lines to a :class:`LogWriter` (errors: written at once)."""

    def __init__(self, file: _LockedFile, writer: LogWriter) -> None:
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

    error = critical = exception = urgent

    def close(self) -> None:
        self._writer.flush()
        self._file.close()


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
    """
    sink: _LockedFile | _BatchedFile | _Discard
    if path is None:
        sink = _Discard()
    else:
        path.parent.mkdir(parents=True, exist_ok=True)
        sink = _LockedFile(path.open("a", encoding="utf-8"), path)
        if writer is not None:
            sink = _BatchedFile(sink, writer)
    logger = structlog.wrap_logger(
        sink,
        processors=[
            # No contextvars merge: no part of EAMOS binds context variables, and
            # the copy of the context it makes per line is a cost on every trigger.
            _render_line,
        ],
        # The processors are [_render_line] only: the direct methods do the same.
        wrapper_class=_WRAPPERS.get(level) or structlog.make_filtering_bound_logger(level),
        cache_logger_on_first_use=False,
    )
    return logger.bind(**context)  # type: ignore[no-any-return]


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
    enabled = getattr(logger, "is_enabled_for", None)  # None: not one of make_logger's
    if enabled is None or method not in _LEVELS or "exc_info" in fields:
        getattr(logger, method)(event, **fields)  # a traceback is rendered where it is
        return
    if not enabled(_LEVELS[method]):
        return
    sink = logger._logger
    getattr(sink, method)(_render_line(sink, method, _event_dict(logger, event, fields), at))


def close_logger(logger: Any) -> None:
    """Close the file behind a logger made by :func:`make_logger`."""
    sink = getattr(logger, "_logger", None)
    if sink is not None and hasattr(sink, "close"):
        sink.close()


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
