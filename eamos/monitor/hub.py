"""The one place the ground station's threads and the web server meet: a bounded patch log.

:class:`Hub` owns the :class:`~.state.MonitorState` behind one lock.  The
ground station's threads call :meth:`Hub.event` (never blocking on a
browser: it applies the event, appends the patches to a bounded log and
returns, without waking anything); each browser connection reads the log from
its own position with :meth:`Hub.since`.  A connection that fell further behind than the log keeps
(a slow or stalled browser) gets the whole state again instead
(:meth:`Hub.resync`), and the patches it missed are counted as dropped
frames.  The server sends what is new on its own timer (every 0.1 s), so a
burst of events costs one message per page per tick and no thread switch per
event; ``wake`` (the server's) is called only for what should not wait for
the next tick: the run's end and an abort request.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from eamos.ground.summary import RunSummary

from .setup import MissionSetup
from .state import MonitorState

#: Patches the log keeps (a connection further behind than this resynchronises).
LOG_CAPACITY = 5000


class Hub:
    """Thread-safe: the state, a bounded log of numbered patches, and counters."""

    def __init__(
        self,
        setup: MissionSetup,
        clock: Callable[[], float] = time.time,
        capacity: int = LOG_CAPACITY,
    ) -> None:
        self.clock = clock
        self.state = MonitorState(setup, clock())
        self._lock = threading.Lock()
        self._log: deque[tuple[int, dict[str, Any]]] = deque(maxlen=capacity)
        self._seq = 0  # number of the last patch appended
        self.dropped = 0  # patches a connection never received (it resynchronised)
        self.events = 0
        self.wake: Callable[[], None] = lambda: None
        self.aborts: list[dict[str, Any]] = []  # every abort request: origin, accepted, time

    def _publish(self, patches: list[dict[str, Any]]) -> None:
        for patch in patches:
            self._seq += 1
            self._log.append((self._seq, patch))

    def event(self, name: str, msg: Any) -> None:
        """A message from participant ``name`` reached the ground station (any thread)."""
        with self._lock:
            self.events += 1
            self._publish(self.state.apply(name, msg, self.clock()))

    def tick(self) -> None:
        """Publish the coalesced drone updates that are due (the server calls it every 0.1 s,
        then sends the new patches to its pages)."""
        with self._lock:
            self._publish(self.state.tick(self.clock()))

    def finish(self, summary: RunSummary) -> None:
        """The run ended with ``summary``: final states and the outcome word."""
        with self._lock:
            self._publish(self.state.finish(summary, self.clock()))
        self.wake()

    def forecast(self, record: dict[str, Any]) -> None:
        """The live look-ahead's latest cycle (any thread)."""
        with self._lock:
            self._publish(self.state.forecast(record))
        self.wake()

    def amended(self, setup: MissionSetup, drones: list[str]) -> None:
        """An amendment was applied to ``drones``: the mission's setup as it flies now."""
        with self._lock:
            self._publish(self.state.amended(setup, drones))
        self.wake()

    def abort_request(self, origin: str, accepted: bool) -> None:
        """Record an abort request (and show ``aborting`` when it was accepted)."""
        with self._lock:
            self.aborts.append({"origin": origin, "accepted": accepted, "t": self.clock()})
            if accepted:
                self._publish(self.state.abort_requested(origin))
        self.wake()

    @property
    def seq(self) -> int:
        """The number of the last patch."""
        with self._lock:
            return self._seq

    def since(self, seq: int) -> tuple[int, list[dict[str, Any]]] | None:
        """The patches after number ``seq`` and the new position; None: too far behind."""
        with self._lock:
            if seq >= self._seq:
                return seq, []
            oldest = self._log[0][0] if self._log else self._seq + 1
            if seq + 1 < oldest:
                self.dropped += oldest - seq - 1
                return None
            start = seq + 1 - oldest
            return self._seq, [p for _, p in itertools.islice(self._log, start, None)]

    def resync(self) -> tuple[int, dict[str, Any]]:
        """The whole state and the number of the last patch it includes."""
        with self._lock:
            return self._seq, self._snapshot()

    def _snapshot(self) -> dict[str, Any]:
        snap = self.state.snapshot()
        snap["stats"] = self._stats()
        return snap

    def _stats(self) -> dict[str, Any]:
        return {
            "events": self.events,
            "patches": self._seq,
            "coalesced": self.state.coalesced,
            "dropped": self.dropped,
        }

    def stats(self) -> dict[str, Any]:
        """Counters: events in, patches out, coalesced updates, dropped frames."""
        with self._lock:
            return self._stats()
