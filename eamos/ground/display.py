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

import sys
import threading
import time
from collections.abc import Callable
from typing import Any, Protocol, TextIO

from eamos.net import wire
from eamos.net.link import PeerStatus

from .station import DroneView, GroundStation, ParticipantFailed

#: Action states worth a line (``Progress.state``).
SHOWN_STATES = ("running", "ok", "failed", "cancelled", "stranded")


def stamp(at: float) -> str:
    """``[HH:MM:SS]`` of wall-clock time ``at`` (local time, as people read clocks)."""
    return time.strftime("[%H:%M:%S]", time.localtime(at))


def format_event(name: str, msg: Any, at: float) -> str | None:
    """The line shown for ``msg`` from participant ``name`` received at ``at``; None: no line.

    Pure: ``at`` is the wall-clock time to print.
    """
    head = f"{stamp(at)} {name:>8}"
    if isinstance(msg, wire.Progress) and msg.state in SHOWN_STATES:
        line = f"{head} {msg.state:<9} {msg.action}"
        reason = msg.detail.get("detail") if isinstance(msg.detail, dict) else ""
        if reason and msg.state != "running":
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
    """One line per event worth seeing, on ``stream`` (stdout by default)."""

    refresh_s = 5.0

    def __init__(
        self, stream: TextIO | None = None, clock: Callable[[], float] = time.time
    ) -> None:
        self.stream = stream or sys.stdout
        self.clock = clock
        self._lock = threading.Lock()  # events come from the network threads
        self.lost_lines = 0  # lines the stream refused (a full disk)

    def __enter__(self) -> PlainDisplay:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def watch(self, station: GroundStation) -> None:
        """Plain lines need no views: events are enough."""

    def event(self, name: str, view: DroneView, msg: Any) -> None:
        """Print the event's line, if it has one."""
        line = format_event(name, msg, self.clock())
        if line is not None:
            self.say(line)

    def refresh(self) -> None:
        """Plain lines need no redraw."""

    def say(self, text: str) -> None:
        """Print ``text`` on its own line; a stream that cannot be written loses the line only.

        (``eamos-node``'s stdout is ``node.out`` in the run folder: a full disk
        must not stop the ground station's run loop.)
        """
        with self._lock:
            try:
                print(text, file=self.stream, flush=True)
            except (OSError, ValueError):
                self.lost_lines += 1


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
