"""The periodic jobs of one MAVLink link, on one thread: heartbeats, setpoints, telemetry.

The GCS heartbeat (1 Hz), the signing timestamp, PX4's setpoint stream, ArduPilot's
refreshed position target, the telemetry samples and the position log all run here,
each at its own period, paced by ``Event.wait`` on the link's stop event.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: ``on_event(name, fields)``: what the link reports (the vehicle logs it).
EventCallback = Callable[[str, dict[str, Any]], None]


@dataclass
class _Periodic:
    """One job of the ticker: what to run, how often, and when next (``time.monotonic()``)."""

    period_s: float
    job: Callable[[], None]
    name: str
    due: float = 0.0


class Ticker:
    """Runs every registered job at its period on one thread, until ``stop`` is set.

    Jobs keep their cadence; after a stall they start again from now instead of
    bursting.  A job that raises is reported (``link.job_error``) and the others go on.
    """

    def __init__(self, stop: threading.Event, on_event: EventCallback) -> None:
        self._stop = stop
        self._on_event = on_event
        self._jobs: list[_Periodic] = []

    def every(self, period_s: float, job: Callable[[], None], name: str) -> None:
        """Run ``job`` every ``period_s`` (register before the thread starts)."""
        self._jobs.append(_Periodic(period_s, job, name))

    def run(self) -> None:
        """The ticker thread: run each job when due until the stop event is set."""
        now = time.monotonic()
        for job in self._jobs:
            job.due = now
        while not self._stop.is_set():
            now = time.monotonic()
            for job in self._jobs:
                if now >= job.due:
                    try:
                        job.job()
                    except Exception as exc:  # a periodic job must not end the others
                        self._on_event("link.job_error", {"job": job.name, "error": repr(exc)})
                    # Keep the cadence; after a stall, restart from now instead of bursting.
                    job.due = max(job.due + job.period_s, now)
            wait = min(job.due for job in self._jobs) - time.monotonic()
            # The pacing wait of the periodic streams; close() ends it at once.
            if self._stop.wait(max(0.0, wait)):
                return


__all__ = ["EventCallback", "Ticker"]
