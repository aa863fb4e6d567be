"""What the ground station shows while a mission flies: one event formatter, two displays.

:func:`format_event` turns a message the ground station received into one
line (or nothing): action progress, ready/resolved, and link changes
(:class:`~eamos.net.link.PeerStatus`: a drone went silent, came back, left).
Every display uses it, so ``eamos run``, ``eamos start`` and ``eamos-node``
(ground role) print the same lines.

:class:`PlainDisplay` prints those lines; :class:`LiveDisplay` draws a table
(rich) on a terminal and prints the link changes above it.  Both are
context managers with ``event``, ``refresh`` and ``say``; :func:`make_display`
picks one.
"""

from __future__ import annotations

import heapq
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, Protocol, TextIO

from eamos.net import wire
from eamos.net.link import PeerStatus

from .station import DroneView, GroundStation, ParticipantFailed

#: Node states worth a line (``Progress.state``): every change of an action, a
#: wait and its condition, a branch decision, a blocked or skipped node, a
#: stranded drone.
SHOWN_STATES = (
    "running",
    "ok",
    "failed",
    "caught",
    "cancelled",
    "waiting",
    "decided",
    "blocked",
    "skipped",
    "stranded",
)
#: Lines are held this long and printed in the order things happened on the
#: drones (progress batches arrive up to PROGRESS_INTERVAL_S late).
HOLD_S = 0.3
#: After this long without a line, a line says what every drone is doing.
QUIET_S = 10.0


def stamp(at: float) -> str:
    """``[HH:MM:SS]`` of wall-clock time ``at`` (local time, as people read clocks)."""
    return time.strftime("[%H:%M:%S]", time.localtime(at))


def event_time(msg: Any, arrived: float) -> float:
    """When ``msg``'s change happened: a progress event's ``at``, else when it arrived."""
    if isinstance(msg, wire.Progress):
        at = msg.detail.get("at")
        if isinstance(at, int | float) and not isinstance(at, bool):
            return float(at)
    return arrived


def format_event(name: str, msg: Any, at: float) -> str | None:
    """The line shown for ``msg`` from participant ``name`` at wall-clock ``at``; None: no line.

    Pure.  A wait shows what it waits for, a decision which way it went.
    """
    head = f"{stamp(at)} {name:>8}"
    if isinstance(msg, wire.Progress) and msg.state in SHOWN_STATES:
        line = f"{head} {msg.state:<9} {msg.action}"
        reason = msg.detail.get("detail") if isinstance(msg.detail, dict) else ""
        if reason and msg.state != "running" and str(reason) not in msg.action:
            line += f"  ({reason})"
        return line
    if isinstance(msg, wire.Ready | wire.Resolved):
        return f"{head} {type(msg).__name__.lower()}"
    if isinstance(msg, ParticipantFailed):
        return f"{head} FAILED: {msg.reason}"
    if isinstance(msg, PeerStatus):
        silent = f" (silent {msg.silent_s:.1f} s)" if msg.state in ("lost", "back") else ""
        return f"{head} link {msg.state}{silent}"
    return None


def quiet_line(views: dict[str, DroneView], now: float, quiet_s: float) -> str:
    """What every drone is doing, after ``quiet_s`` seconds without a line (pure)."""
    parts = []
    for name, v in views.items():
        since = v.events[-1].get("t") if v.events else None
        how_long = f" for {now - since:.0f} s" if isinstance(since, int | float) else ""
        doing = f"{v.state} {v.action}".strip() if v.action else v.state
        parts.append(f"{name} {doing}{how_long}")
    return f"{stamp(now)} no change for {quiet_s:.0f} s: " + "; ".join(parts)


class Display(Protocol):
    """What the run loop (:func:`eamos.ground.fly`) needs from a display."""

    #: How often (seconds) the run loop wakes up to refresh the display.
    refresh_s: float

    def __enter__(self) -> Display: ...

    def __exit__(self, *exc: object) -> None: ...

    def watch(self, station: GroundStation) -> None:
        """Show ``station``'s views (the live table draws them)."""

    def event(self, name: str, view: DroneView, msg: Any) -> None:
        """A message from participant ``name`` arrived (the station's ``on_change``)."""

    def refresh(self) -> None:
        """Redraw (a live table); nothing for plain lines."""

    def say(self, text: str) -> None:
        """Tell the operator something."""


class PlainDisplay:
    """One line per event worth seeing, on ``stream`` (stdout by default), in order.

    Inside ``with``, lines are held :data:`HOLD_S` and printed in the order
    the changes happened on the drones (their clocks; one machine's clock for
    ``eamos run``), not the order batches arrived; a quiet spell of
    :data:`QUIET_S` gets a line saying what every drone is doing.
    """

    refresh_s = 5.0

    def __init__(
        self, stream: TextIO | None = None, clock: Callable[[], float] = time.time
    ) -> None:
        self.stream = stream or sys.stdout
        self.clock = clock
        self._lock = threading.Lock()  # events come from the network threads
        self.lost_lines = 0  # lines the stream refused (a full disk)
        self._station: GroundStation | None = None
        self._last_line = clock()
        # Held lines: (event time, order, due monotonic time, line); None: print at once.
        self._held: list[tuple[float, int, float, str]] | None = None
        self._order = 0
        self._cond = threading.Condition(self._lock)
        self._printer: threading.Thread | None = None

    def __enter__(self) -> PlainDisplay:
        with self._cond:
            self._held = []
        self._printer = threading.Thread(target=self._print_held, name="plain-display", daemon=True)
        self._printer.start()
        return self

    def __exit__(self, *exc: object) -> None:
        with self._cond:
            held, self._held = self._held, None
            self._cond.notify_all()
        if self._printer is not None:
            self._printer.join()
            self._printer = None
        for _, _, _, line in sorted(held or []):
            self._write(line)

    def watch(self, station: GroundStation) -> None:
        """Keep ``station``: its views say what each drone does in a quiet spell."""
        self._station = station

    def event(self, name: str, view: DroneView, msg: Any) -> None:
        """Show the event's line (if it has one), in the order things happened."""
        arrived = self.clock()
        at = event_time(msg, arrived)
        line = format_event(name, msg, at)
        if line is not None:
            self._show(at, line)

    def _show(self, at: float, line: str) -> None:
        """Hold ``line`` (happened at ``at``) for ordered printing, or print it now."""
        with self._cond:
            if self._held is not None:
                self._order += 1
                heapq.heappush(self._held, (at, self._order, time.monotonic() + HOLD_S, line))
                self._cond.notify_all()
                return
        self._write(line)

    def _print_held(self) -> None:
        """The printer thread: the earliest event's line once it has been held long enough."""
        with self._cond:
            while self._held is not None:
                if not self._held:
                    self._cond.wait()
                    continue
                wait_s = self._held[0][2] - time.monotonic()
                if wait_s > 0:
                    self._cond.wait(wait_s)
                    continue
                line = heapq.heappop(self._held)[3]
                self._write_locked(line)

    def refresh(self) -> None:
        """After :data:`QUIET_S` without a line, say what every drone is doing."""
        now = self.clock()
        if self._station is None or now - self._last_line < QUIET_S:
            return
        self.say(quiet_line(self._station.snapshot(), now, QUIET_S))

    def say(self, text: str) -> None:
        """Print ``text`` on its own line, in order with the events around it."""
        self._show(self.clock(), text)

    def _write(self, text: str) -> None:
        with self._lock:
            self._write_locked(text)

    def _write_locked(self, text: str) -> None:
        # A stream that cannot be written loses the line only: ``eamos-node``'s
        # stdout is ``node.out`` in the run folder, and a full disk must not
        # stop the ground station's run loop.
        try:
            print(text, file=self.stream, flush=True)
        except (OSError, ValueError):
            self.lost_lines += 1
        self._last_line = self.clock()


class LiveDisplay:
    """A live table (rich) of every drone; link changes and messages print above it."""

    refresh_s = 1.0
    COLUMNS = ("drone", "state", "current action", "x, y, z (m)", "done", "link")

    def __init__(
        self,
        names: list[str],
        station: GroundStation | None = None,
        clock: Callable[[], float] = time.time,
    ) -> None:
        self.names = names
        self.station = station
        self.clock = clock
        self._live: Any = None

    def __enter__(self) -> LiveDisplay:
        from rich.live import Live

        self._live = Live(self._table(), refresh_per_second=4, transient=False)
        self._live.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._live is not None:
            self._live.update(self._table())
            self._live.__exit__(None, None, None)
            self._live = None

    def watch(self, station: GroundStation) -> None:
        """Draw ``station``'s views."""
        self.station = station

    def _table(self) -> Any:
        from rich.table import Table

        table = Table(title="EAMOS mission", expand=False)
        for col in self.COLUMNS:
            table.add_column(col)
        views = self.station.snapshot() if self.station else {}
        for name in self.names:
            v = views.get(name) or DroneView(name)
            pos = "" if v.position is None else "{:.1f}, {:.1f}, {:.1f}".format(*v.position)
            table.add_row(name, v.state, v.action, pos, str(v.done_actions), v.link)
        return table

    def event(self, name: str, view: DroneView, msg: Any) -> None:
        """Progress shows in the table; link changes and failures print as lines above it."""
        if isinstance(msg, PeerStatus | ParticipantFailed):
            line = format_event(name, msg, self.clock())
            if line is not None:
                self.say(line)

    def refresh(self) -> None:
        """Redraw the table."""
        if self._live is not None:
            self._live.update(self._table())

    def say(self, text: str) -> None:
        """Print ``text`` above the table."""
        if self._live is not None:
            self._live.console.print(text, highlight=False, markup=False)
        else:
            print(text, flush=True)


def make_display(live: bool | None, names: list[str]) -> PlainDisplay | LiveDisplay:
    """A live table if ``live`` (None: when stdout is a terminal), else plain lines.

    Call its ``watch(station)`` once the ground station is built.
    """
    if live is None:
        live = sys.stdout.isatty()
    return LiveDisplay(names) if live else PlainDisplay()
