"""The ground station's run loop (paper VI-G), wherever the drones are.

:func:`fly` is the one loop of ``eamos run`` (drones as local processes),
``eamos start`` (drones over SSH) and ``eamos-node`` in the ground role:
wait until every drone is ready (else abort: no start trigger is sent), send
the start trigger, wait until every participant resolved (or the operator
stops, or the timeout), then complete or abort, and wait for the reports of
the drones still there.  What differs between them (how drones are started
and watched, where the summary goes) stays with the caller.
"""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import Any

from eamos.actors.drone import REPORT_ACK_TIMEOUT_S
from eamos.actors.runtime import DroneRuntime, NetSettings
from eamos.config import LookAheadSettings
from eamos.hal import make_adapter
from eamos.logs import make_logger
from eamos.net import wire
from eamos.program.format import DroneProgram
from eamos.program.uniform import GROUND_STATION

from .display import Display
from .lookahead import Forecast, LookAheadLoop
from .operator import OperatorDesk, PauseClock, desk_handler, snapshot
from .station import GroundStation

#: How long the drones have to send their final report after the mission ends: as long
#: as a drone offers it (a lossy network may hold it back for seconds).
REPORT_WAIT_OK_S = REPORT_ACK_TIMEOUT_S
#: ... after an abort (they land first).
REPORT_WAIT_ABORTED_S = 180.0


@dataclass(frozen=True)
class Limits:
    """How long the ground station waits for each phase (seconds)."""

    ready_timeout_s: float = 60.0
    timeout_s: float = 600.0  # the mission, from the start trigger
    report_ok_s: float = REPORT_WAIT_OK_S
    report_aborted_s: float = REPORT_WAIT_ABORTED_S


@dataclass(frozen=True)
class Flight:
    """How the run loop ended."""

    outcome: str  # "ok", "not ready: ...", "aborted by the operator", "timed out after ..."
    started: float  # wall-clock time of the start trigger (of the attempt when never started)
    ready_s: float | None  # how long the drones took to become ready (None: they did not)
    missing_reports: tuple[str, ...] = ()  # drones expected to report that did not (not lost)

    @property
    def ok(self) -> bool:
        """The mission ran to completion (the drones' own results aside)."""
        return self.outcome == "ok"


def fly(
    station: GroundStation,
    display: Display,
    stop: threading.Event,
    limits: Limits,
    *,
    alive: Callable[[], list[str]] | None = None,
    on_ready: Callable[[float], None] | None = None,
    clock: Callable[[], float] = time.monotonic,
    wall: Callable[[], float] = time.time,
    control: Path | None = None,
    forecast: Forecast | None = None,
    look_ahead: LookAheadSettings | None = None,
) -> Flight:
    """Run the ground station's phases on ``station`` (already attached to its runtime).

    ``alive()`` names the drones whose process is known to run (default: all);
    the others are not waited for.  ``on_ready`` is told how long the drones
    took to become ready, before the start trigger.  Lost drones (dead, or
    given up after a long silence) are waited for neither to resolve nor to
    report.  ``control``: the run folder whose operator's socket takes the operator's
    commands (:mod:`.operator`: pause, resume, a drone's hold, land ...) while it runs.
    ``forecast`` with ``look_ahead.period_s`` above 0 (and ``control``): the live
    look-ahead re-simulates the rest of the mission that often (:mod:`.lookahead`).
    """
    desk = None
    pauses = PauseClock()  # the operator's pauses do not count against the timeout
    if control is not None:
        desk = OperatorDesk(control, desk_handler(station, control, pauses, clock))
        why = desk.open()
        if why:
            display.say(f"no operator commands for this run: {why}")
    ahead = None
    if forecast is not None and look_ahead is not None and look_ahead.period_s > 0 and control:
        ahead = LookAheadLoop(
            station, control, forecast, look_ahead, display.say, shown=display.forecast
        )
        ahead.start()
    try:
        return _fly(station, display, stop, limits, alive, on_ready, clock, wall, pauses)
    finally:
        if ahead is not None:
            ahead.stop()
        if desk is not None:
            desk.close()
        if control is not None:  # the mission's state at its end (snapshot.json)
            snapshot(station, control, "end")


def _fly(
    station: GroundStation,
    display: Display,
    stop: threading.Event,
    limits: Limits,
    alive: Callable[[], list[str]] | None,
    on_ready: Callable[[float], None] | None,
    clock: Callable[[], float],
    wall: Callable[[], float],
    pauses: PauseClock,
) -> Flight:
    outcome = "ok"
    started = wall()
    t0 = clock()
    ready_s = None
    if not station.wait_ready(limits.ready_timeout_s, stop):
        outcome = _not_started(station, stop)
        station.abort(outcome)
    else:
        ready_s = clock() - t0
        if on_ready is not None:
            on_ready(ready_s)
        display.say("all drones ready: start")
        started = wall()
        station.start()
        outcome = _watch(station, display, stop, limits.timeout_s, clock, pauses)
        if outcome == "ok":
            # Everyone still there resolved; a participant that died makes it a failure
            # (one only silent may still report: the summary's ok decides for it).
            station.complete()
            if station.dead:
                outcome = "failed: " + "; ".join(station.dead)
        else:
            display.say(f"aborting: {outcome}: every drone lands")
            station.abort(outcome)
    # A drone that never became ready sends no report (eamos-node gives up first).
    views = station.snapshot()
    running = station.drones() if alive is None else alive()
    waiting = [n for n in running if views[n].ready]
    patience = limits.report_ok_s if outcome == "ok" else limits.report_aborted_s
    missing: list[str] = []
    if not station.wait_reports(waiting, patience, hurry_event(stop)):
        missing = station.missing_reports(waiting)
        if hurried(stop):
            display.say("stopped waiting (second Ctrl-C); no report from: " + ", ".join(missing))
        else:
            display.say("some drones sent no report: " + ", ".join(missing))
    display.refresh()
    return Flight(outcome, started, ready_s, tuple(missing))


def _not_started(station: GroundStation, stop: threading.Event) -> str:
    """Why the start trigger was not sent, truthfully: who was ready and who was not."""
    if stop.is_set():
        views = station.snapshot()
        ready = [d for d in station.drones() if views[d].ready]
        waiting = [d for d in station.drones() if not views[d].ready]
        return (
            "stopped by the operator before the start (ready: "
            + (", ".join(ready) or "none")
            + "; not ready: "
            + (", ".join(waiting) or "none")
            + ")"
        )
    return "not ready: " + (
        ", ".join(station.failures) or "waiting for " + ", ".join(station.not_ready())
    )


def _watch(
    station: GroundStation,
    display: Display,
    stop: threading.Event,
    timeout_s: float,
    clock: Callable[[], float],
    pauses: PauseClock | None = None,
) -> str:
    """Wait until every participant resolved; the outcome ("ok" or why not).  The
    operator's pauses (``pauses``) do not count against ``timeout_s``."""
    deadline = clock() + timeout_s
    while not station.wait_resolved(display.refresh_s, stop):
        display.refresh()
        if stop.is_set():
            return "aborted by the operator"
        now = clock()
        if now - (pauses.paused_s(now) if pauses is not None else 0.0) > deadline:
            return (
                f"timed out after {timeout_s:g} s (unresolved: {', '.join(station.unresolved())})"
            )
    return "ok"


def ground_runtime(
    program: DroneProgram,
    station: GroundStation,
    net: NetSettings,
    log_dir: Path | None,
    hal: Mapping[str, Any] | None = None,
) -> DroneRuntime:
    """The ground station's own runtime: its program on the ground adapter, feeding ``station``.

    Not started yet; it receives every drone's telemetry too (for the live
    table).  ``hal`` is the ground adapter's settings (default: plain
    ``{"adapter": "ground"}``).
    """
    settings = dict(hal) if hal and hal.get("adapter") == "ground" else {"adapter": "ground"}
    adapter_log = make_logger(
        None if log_dir is None else log_dir / "adapter.log", drone=GROUND_STATION
    )
    drones = [n for n in station.drones()]
    return DroneRuntime(
        program,
        make_adapter(GROUND_STATION, settings, adapter_log),
        net,
        log_dir,
        ground_handler=station.handle,
        extra_topics=tuple(wire.topic_telemetry(d) for d in drones),
    )


class StopRequest(threading.Event):
    """The operator's stop: set by the first Ctrl-C; :attr:`hurry` by the second.

    A plain :class:`threading.Event` works as the stop too; this one lets the
    second Ctrl-C stop the waiting (for reports, for landing) while the
    summary is still written: the caller then exits with 130.
    """

    def __init__(self) -> None:
        super().__init__()
        self.hurry = threading.Event()


def hurry_event(stop: threading.Event) -> threading.Event | None:
    """The second Ctrl-C's event, if ``stop`` is a :class:`StopRequest`."""
    return stop.hurry if isinstance(stop, StopRequest) else None


def hurried(stop: threading.Event) -> bool:
    """The operator pressed Ctrl-C twice."""
    return isinstance(stop, StopRequest) and stop.hurry.is_set()


def install_stop_handler(stop: threading.Event) -> None:
    """Ctrl-C / SIGTERM set ``stop``: the run aborts, every drone lands, then it exits.

    A second Ctrl-C stops waiting: with a :class:`StopRequest` it sets
    ``stop.hurry`` (the waits end, the summary is still written); with a plain
    event it raises ``KeyboardInterrupt``.
    """

    def handler(signum: int, frame: FrameType | None) -> None:
        if not stop.is_set():
            stop.set()
        elif isinstance(stop, StopRequest):
            stop.hurry.set()
        else:
            raise KeyboardInterrupt

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
