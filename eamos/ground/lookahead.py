"""The ground station's live look-ahead: the rest of the mission, re-simulated as it flies.

Every ``[look_ahead] period_s`` while the mission flies (started, not over, not
paused), :class:`LookAheadLoop` takes the mission's state as the operator's snapshot
has it (:func:`~.snapshot.mission_snapshot`: where each drone is, what ended, what
runs, the speed each drone was seen to hold) and hands it to the forecast it was
given (``eamos run`` and ``eamos start`` give :func:`eamos.check.lookahead.look_ahead`:
the continuation of that state in virtual time, on every open branch).  What the
forecast predicts is said once per new prediction (the terminal, the mission log's
``mission.lookahead.finding``), and every cycle's whole outcome is written to
``RUN_DIR/lookahead.json``.  With ``[look_ahead] hold_before_s``, the drones of a
separation conflict predicted within that many seconds are held, as the operator's
``eamos drone RUN_DIR NAME hold`` holds them (origin ``look-ahead``): the operator then
decides (resume, land, ...).

The forecast runs on this loop's own thread; whatever it raises stops the look-ahead
(said once), never the mission.  :func:`news` and :func:`to_hold` are the pure
decisions.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from eamos.config import LookAheadSettings

from .operator import command
from .snapshot import mission_snapshot, write_run_file

if TYPE_CHECKING:
    from .station import GroundStation

__all__ = ["LOOK_AHEAD_FILE", "Forecast", "LookAheadLoop", "news", "prediction_key", "to_hold"]

#: Every cycle's outcome, in the run folder.
LOOK_AHEAD_FILE = "lookahead.json"
#: A forecast: the snapshot document in, the look-ahead's JSON form out
#: (:meth:`eamos.check.lookahead.LookAhead.to_json`).
Forecast = Callable[[dict[str, Any]], dict[str, Any]]


def prediction_key(p: Mapping[str, Any]) -> str:
    """What makes a prediction the same from one cycle to the next."""
    drones = ",".join(str(d) for d in p.get("drones") or ())
    lines = ",".join(str(line) for line in p.get("lines") or ())
    return f"{p.get('check')}|{drones}|{lines}"


def news(said: set[str], predictions: Iterable[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    """The predictions not said before (``said`` grows by them)."""
    out: list[Mapping[str, Any]] = []
    for p in predictions:
        key = prediction_key(p)
        if key not in said:
            said.add(key)
            out.append(p)
    return out


def to_hold(
    predictions: Iterable[Mapping[str, Any]],
    hold_before_s: float,
    elapsed_s: float,
    held: set[str],
) -> list[tuple[str, Mapping[str, Any]]]:
    """(drone, prediction) to hold now: each drone of a separation conflict predicted
    within ``hold_before_s`` of now (the snapshot was ``elapsed_s`` ago), once."""
    out: list[tuple[str, Mapping[str, Any]]] = []
    if hold_before_s <= 0:
        return out
    for p in predictions:
        in_s = p.get("in_s")
        if p.get("check") != "separation" or not isinstance(in_s, int | float):
            continue
        if in_s - elapsed_s > hold_before_s:
            continue
        for drone in p.get("drones") or ():
            if drone not in held:
                held.add(drone)
                out.append((drone, p))
    return out


def said_line(p: Mapping[str, Any], elapsed_s: float) -> str:
    """The terminal's line for a new prediction."""
    in_s = p.get("in_s")
    when = f" in {max(0.0, in_s - elapsed_s):.0f} s" if isinstance(in_s, int | float) else ""
    return f"look-ahead: {p.get('severity')}{when}: {p.get('message')}"


class LookAheadLoop:
    """Re-simulates the rest of ``station``'s mission every ``settings.period_s``."""

    def __init__(
        self,
        station: GroundStation,
        run_dir: Path,
        forecast: Forecast,
        settings: LookAheadSettings,
        say: Callable[[str], None],
        clock: Callable[[], float] = time.monotonic,
        shown: Callable[[dict[str, Any]], None] | None = None,
    ) -> None:
        """``say``: a line for the operator; ``shown``: each cycle's record, for a page
        that draws it (the monitor)."""
        self.station = station
        self.run_dir = Path(run_dir)
        self.forecast = forecast
        self.settings = settings
        self.say = say
        self.clock = clock
        self.shown = shown
        self.said: set[str] = set()
        self.held: set[str] = set()
        self.cycles = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="eamos-look-ahead", daemon=True)

    def start(self) -> None:
        """Begin cycling (the first cycle one period from now)."""
        self._thread.start()

    def stop(self) -> None:
        """Stop cycling; a cycle under way finishes first."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()

    def _run(self) -> None:
        # A period, not a synchronisation: each wait also ends at once on stop().
        while not self._stop.wait(self.settings.period_s):
            station = self.station
            if not station.started or station.over or station.paused:
                continue
            try:
                self.cycle()
            except Exception as exc:  # the look-ahead stops; the mission flies on
                self.say(f"look-ahead stopped: {type(exc).__name__}: {exc}")
                self._log("error", "mission.lookahead.stopped", error=f"{exc}"[:300])
                return

    def cycle(self) -> dict[str, Any]:
        """One look-ahead: snapshot, forecast, say what is new, hold, write the file."""
        station = self.station
        doc = mission_snapshot(station.snapshot(), "look-ahead", station.mission_id, False)
        began = self.clock()
        outcome = self.forecast(doc)
        elapsed = self.clock() - began
        self.cycles += 1
        predictions = list(outcome.get("predictions") or ())
        for p in news(self.said, predictions):
            self.say(said_line(p, elapsed))
            self._log("warning", "mission.lookahead.finding", **dict(p))
        for drone, p in to_hold(predictions, self.settings.hold_before_s, elapsed, self.held):
            why = command(station, "hold", drone, "look-ahead")
            self.say(
                f"look-ahead: {drone} held ({p.get('check')} predicted in "
                f"{max(0.0, float(p.get('in_s') or 0.0) - elapsed):.0f} s)"
                + (f": refused: {why}" if why else "")
            )
        record = {**outcome, "t": doc["t"], "cycle_s": round(elapsed, 3), "cycle": self.cycles}
        write_run_file(self.run_dir / LOOK_AHEAD_FILE, record, "the look-ahead goes on")
        if self.shown is not None:
            self.shown(record)
        return record

    def _log(self, level: str, event: str, **fields: Any) -> None:
        runtime = self.station.runtime
        if runtime is not None:
            getattr(runtime.log, level)(event, **fields)
