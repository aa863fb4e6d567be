"""The uniform API's log: ``uniform.result`` lines that may be held back a little.

Split from :mod:`.uniform_api` (which re-exports :class:`UniformLog`): what the log
writes, and in which order, is its own concern.
"""

from __future__ import annotations

import threading
from collections.abc import Hashable
from typing import Any, Protocol

from eamos.hal.api import ActionResult
from eamos.logs import EventLog, log_line


class ActionFinished(Protocol):
    """What the log reads of an action's end (:class:`.uniform_api.ActionFinished`)."""

    @property
    def token(self) -> Hashable: ...
    @property
    def action(self) -> str: ...
    @property
    def args(self) -> tuple[float, ...]: ...
    @property
    def result(self) -> ActionResult: ...
    @property
    def start_s(self) -> float: ...
    @property
    def end_s(self) -> float: ...


__all__ = ["UniformLog", "jsonable", "result_fields"]


class UniformLog:
    """A drone's uniform log whose ``uniform.result`` lines may be held back a little.

    :meth:`hold` keeps the result line of an action answered inline; :meth:`write_held`
    writes the held lines.  Every other line written through this object writes the
    held ones first, under one lock, so the file's order is the order in which the
    lines were logged or held: a line an action's end caused (the next action's
    ``uniform.call``) never comes before that end's ``uniform.result``.
    """

    def __init__(self, log: EventLog) -> None:
        self.log = log
        self._lock = threading.Lock()
        self._held: list[ActionFinished] = []

    def hold(self, finished: ActionFinished) -> None:
        """Keep ``finished``'s ``uniform.result`` line until :meth:`write_held` or another line."""
        with self._lock:
            self._held.append(finished)

    def write_held(self) -> None:
        """Write the held result lines, oldest first."""
        with self._lock:
            self._write_held()

    def _write_held(self) -> None:
        held, self._held = self._held, []
        for finished in held:
            # Stamped when the action ended, as if written then.
            log_line(self.log, "info", "uniform.result", result_fields(finished), finished.end_s)

    def _line(self, method: str, event: str, fields: dict[str, Any]) -> None:
        with self._lock:
            if self._held:
                self._write_held()
            getattr(self.log, method)(event, **fields)

    def debug(self, event: str, **fields: Any) -> None:
        """Log at debug level (held result lines first)."""
        self._line("debug", event, fields)

    def info(self, event: str, **fields: Any) -> None:
        """Log at info level (held result lines first)."""
        self._line("info", event, fields)

    def warning(self, event: str, **fields: Any) -> None:
        """Log at warning level (held result lines first)."""
        self._line("warning", event, fields)

    def error(self, event: str, **fields: Any) -> None:
        """Log at error level (held result lines first)."""
        self._line("error", event, fields)

    def exception(self, event: str, **fields: Any) -> None:
        """Log at error level with the exception being handled (held result lines first)."""
        self._line("exception", event, fields)


def result_fields(finished: ActionFinished) -> dict[str, Any]:
    """The fields of an action's ``uniform.result`` line (docs/logs.md)."""
    start_s, end_s, result = finished.start_s, finished.end_s, finished.result
    return {
        "token": jsonable(finished.token),
        "action": finished.action,
        "args": list(finished.args),
        "status": result.status,
        "reason": result.reason,
        "start_s": round(start_s, 6),
        "end_s": round(end_s, 6),
        "duration_s": round(end_s - start_s, 6),
    }


def jsonable(token: Hashable) -> str | int | float:
    """Tokens go into JSON logs; keep simple ones as they are, stringify the rest."""
    return token if isinstance(token, str | int | float) else repr(token)
