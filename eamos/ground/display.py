"""What the ground station shows while a mission flies: one event formatter, two displays.

:func:`format_event` turns a message the ground station received into one
line (or nothing): action progress, ready/resolved, and link changes
(:class:`~eamos.net.link.PeerStatus`: a drone went silent, came back, left).
Every display uses it, so ``eamos run``, ``eamos start`` and ``eamos-node``
(ground role) print the same lines.

:class:`PlainDisplay` prints those lines; :class:`LiveDisplay` draws a table
(rich) on a terminal and prints the link changes above it.  Both are
context managers with ``event``, ``refresh`` and ``say``; :func:`make_display`
picks one.  :class:`HeldLines` is the plain display's ordering, pure.
"""

from __future__ import annotations

import heapq
import importlib.util
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, Protocol, TextIO

from eamos.net import wire
from eamos.net.effects import PeerStatus

from .station import DroneView, GroundStation, ParticipantFailed

#: Node states worth a line (``Progress.state``): every change of an action, a
#: wait and its condition, a branch decision, a blocked or skipped node, a
#: stranded drone, a node stopped by a signal, a vehicle a pilot took over and an
#: adapter's warning (a MAVLink link whose telemetry stays slower than it needs).
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
    "taken_over",
    "warning",
    "stopped",
)
#: Progress states the live table also prints as a line: the operator must read them.
OPERATOR_STATES = ("taken_over", "warning", "stranded")
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
    if isinstance(msg, wire.Progress) and msg.state == "taken_over":
        reason = msg.detail.get("detail") if isinstance(msg.detail, dict) else ""
        return f"{head} TAKEN OVER: {reason or msg.action}"
    if isinstance(msg, wire.Progress) and msg.action.startswith("operator: "):
        reason = msg.detail.get("detail") if isinstance(msg.detail, dict) else ""
        return f"{head} OPERATOR: {reason or msg.state}"
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


class HeldLines:
    """Lines held :data:`HOLD_S` and let out in the order things happened; pure, not thread-safe.

    A line's place is the time of its event (:func:`event_time`): a drone's
    clock for its progress, the ground station's for the rest (ready,
    resolved, link changes).  Lines of *one* participant also keep the order
    the ground station was told them in, whatever the clocks say: a drone's
    messages arrive in the order it sent them (one connection, one receive
    thread), so its goodbye ("link left") or its "resolved" never comes out
    before the progress it sent earlier, even when its clock runs ahead of
    the ground station's.  Times are passed in (``now``: monotonic seconds).
    """

    def __init__(self, hold_s: float = HOLD_S) -> None:
        self.hold_s = hold_s
        # (place, arrival order, due monotonic time, line): a heap, earliest place first.
        self._heap: list[tuple[float, int, float, str]] = []
        self._order = 0
        self._last: dict[str, float] = {}  # participant -> place of its latest line

    def __len__(self) -> int:
        return len(self._heap)

    def add(self, at: float, line: str, now: float, who: str = "") -> None:
        """Hold ``line`` (it happened at wall-clock ``at``; ``who``: whose line, "" for none)."""
        if who:
            at = max(at, self._last.get(who, at))
            self._last[who] = at
        self._order += 1
        heapq.heappush(self._heap, (at, self._order, now + self.hold_s, line))

    def next_due(self) -> float | None:
        """When the first line may come out (monotonic); None when nothing is held."""
        return self._heap[0][2] if self._heap else None

    def due(self, now: float) -> list[str]:
        """The lines that may come out at ``now``, in order (and no longer held)."""
        out = []
        while self._heap and self._heap[0][2] <= now:
            out.append(heapq.heappop(self._heap)[3])
        return out

    def drain(self) -> list[str]:
        """Every held line, in order (the display closes)."""
        out = [line for _, _, _, line in sorted(self._heap)]
        self._heap = []
        return out


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

    def forecast(self, record: dict[str, Any]) -> None:
        """The live look-ahead's latest cycle (:mod:`.lookahead`); the monitor draws it."""


class PlainDisplay:
    """One line per event worth seeing, on ``stream`` (stdout by default), in order.

    Inside ``with``, lines are held :data:`HOLD_S` and printed in the order
    the changes happened on the drones (their clocks; one machine's clock for
    ``eamos run``), not the order batches arrived, each drone's lines in the
    order it sent them (:class:`HeldLines`); what is still held when the
    ``with`` ends comes out before any line shown later.  A quiet spell of
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
        self._held: HeldLines | None = None  # None: print at once (outside ``with``)
        self._cond = threading.Condition(self._lock)
        self._printer: threading.Thread | None = None

    def __enter__(self) -> PlainDisplay:
        with self._cond:
            self._held = HeldLines()
        self._printer = threading.Thread(target=self._print_held, name="plain-display", daemon=True)
        self._printer.start()
        return self

    def __exit__(self, *exc: object) -> None:
        with self._cond:
            held, self._held = self._held, None
            # Written before the lock is let go: a line shown meanwhile (a drone's
            # goodbye, arriving on the receive thread as the run ends) waits and
            # comes after the held lines, not before them.
            for line in held.drain() if held is not None else ():
                self._write_locked(line)
            self._cond.notify_all()
        if self._printer is not None:
            self._printer.join()
            self._printer = None

    def watch(self, station: GroundStation) -> None:
        """Keep ``station``: its views say what each drone does in a quiet spell."""
        self._station = station

    def event(self, name: str, view: DroneView, msg: Any) -> None:
        """Show the event's line (if it has one), in the order things happened."""
        arrived = self.clock()
        at = event_time(msg, arrived)
        line = format_event(name, msg, at)
        if line is not None:
            self._show(at, line, name)

    def _show(self, at: float, line: str, who: str = "") -> None:
        """Hold ``line`` (``who``'s, happened at ``at``) for ordered printing, or print it now."""
        with self._cond:
            if self._held is not None:
                self._held.add(at, line, time.monotonic(), who)
                self._cond.notify_all()
            else:
                self._write_locked(line)

    def _print_held(self) -> None:
        """The printer thread: the earliest event's line once it has been held long enough."""
        with self._cond:
            while self._held is not None:
                due = self._held.next_due()
                if due is None:
                    self._cond.wait()
                    continue
                wait_s = due - time.monotonic()
                if wait_s > 0:
                    self._cond.wait(wait_s)
                    continue
                for line in self._held.due(time.monotonic()):
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

    def forecast(self, record: dict[str, Any]) -> None:
        """Nothing: the look-ahead says each new prediction itself."""

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
        """Progress shows in the table; link changes, failures, a pilot's takeover and
        adapter warnings print as lines above it."""
        operator = isinstance(msg, wire.Progress) and msg.state in OPERATOR_STATES
        if operator or isinstance(msg, PeerStatus | ParticipantFailed):
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

    def forecast(self, record: dict[str, Any]) -> None:
        """Nothing: the look-ahead says each new prediction itself."""


#: Said once when a terminal gets plain lines because rich is not installed.
NO_LIVE_TABLE = "eamos: plain progress lines (for a live table: pip install 'eamos[live]')"


def live_table_installed() -> bool:
    """True when rich, the live table's library (the ``live`` extra), is installed."""
    return importlib.util.find_spec("rich") is not None


def make_display(
    live: bool | None, names: list[str], installed: Callable[[], bool] = live_table_installed
) -> PlainDisplay | LiveDisplay:
    """A live table if ``live`` (None: when stdout is a terminal and rich is installed),
    else plain lines (a terminal without rich is told so once).

    Call its ``watch(station)`` once the ground station is built.
    """
    if live is None:
        live = sys.stdout.isatty()
        if live and not installed():
            print(NO_LIVE_TABLE, flush=True)
            live = False
    return LiveDisplay(names) if live else PlainDisplay()
