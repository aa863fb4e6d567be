"""The live look-ahead: the rest of a flying mission, simulated from where it is now.

While a mission flies, the ground station (:mod:`eamos.ground.lookahead`) takes the
mission's state every few seconds (the snapshot it writes for the operator,
:mod:`eamos.ground.snapshot`) and hands it to :func:`look_ahead`, which continues it
in virtual time on every branch still open, as ``eamos check --from`` does, with one
difference: a drone that has been seen flying slower than its type says
(``cruise_mps`` in the snapshot: the fastest horizontal speed it held over two
telemetry intervals) is simulated at that speed.  A disturbance the pre-flight check
cannot know (wind, a weak motor) then shows as what it leads to: a separation conflict
in 40 s, a battery below the reserve, a geofence exit, a deadlock, and the time the
mission is now expected to end.

Pure but for the CPU time it measures: the snapshot and the compiled mission in, a
:class:`LookAhead` out.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ..compiler import CompiledMission
from ..config import FleetConfig
from ..virtual import continuation
from .explore import check_mission, sim_settings
from .findings import Finding

__all__ = ["LOOK_AHEAD_MAX_RUNS", "LookAhead", "Prediction", "look_ahead", "measured_speeds"]

#: Branches simulated per cycle at most (each a whole rest of the mission).
LOOK_AHEAD_MAX_RUNS = 16
#: How far ahead each drone's predicted track is given (s), one point a second.
TRACK_AHEAD_S = 60
#: Below this a drone has not been seen cruising: its model's speed is kept (m/s).
MIN_CRUISE_MPS = 0.3
#: Seen holding less than this fraction of its type's speed, a drone is flown at what it
#: held; above, at its model's (a sample's timing moves the measure by a few per cent).
SLOWER = 0.95
#: Findings about the mission's text or the model, not about what lies ahead.
_NOT_AHEAD = frozenset({"compile", "model"})


@dataclass(frozen=True)
class Prediction:
    """One thing the rest of the mission is heading into.

    ``in_s``: seconds after the snapshot (None: not tied to a moment); ``drones`` and
    ``lines`` (``file:line`` of each action involved) say who and where in the text.
    """

    check: str
    severity: str
    message: str
    in_s: float | None
    drones: tuple[str, ...]
    lines: tuple[str, ...]
    position: tuple[float, float, float] | None = None

    @property
    def key(self) -> str:
        """What makes it the same prediction from one cycle to the next."""
        return f"{self.check}|{','.join(self.drones)}|{','.join(self.lines)}"

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict."""
        return {
            "check": self.check,
            "severity": self.severity,
            "message": self.message,
            "in_s": None if self.in_s is None else round(self.in_s, 1),
            "drones": list(self.drones),
            "lines": list(self.lines),
            "position": None if self.position is None else [round(v, 2) for v in self.position],
        }


@dataclass(frozen=True)
class LookAhead:
    """One cycle's outcome: what it predicts, when the mission should end, what it cost."""

    predictions: tuple[Prediction, ...]
    end_in_s: float | None  # the longest branch's remaining time (None: none ended)
    runs: int  # branches simulated
    cpu_s: float  # CPU seconds this cycle took
    speeds: Mapping[str, float]  # measured horizontal speeds it flew drones at (m/s)
    # Each drone's predicted track on the first branch, fleet frame: (t from the snapshot,
    # north, east, up), one point a second for TRACK_AHEAD_S.
    ahead: Mapping[str, tuple[tuple[float, float, float, float], ...]] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict."""
        return {
            "predictions": [p.to_json() for p in self.predictions],
            "end_in_s": None if self.end_in_s is None else round(self.end_in_s, 1),
            "runs": self.runs,
            "cpu_s": round(self.cpu_s, 3),
            "speeds_mps": {d: round(v, 2) for d, v in self.speeds.items()},
            "ahead": {d: [[round(v, 2) for v in p] for p in pts] for d, pts in self.ahead.items()},
        }


def measured_speeds(
    doc: Mapping[str, Any], fleet: FleetConfig, drones: list[str]
) -> dict[str, float]:
    """The drones seen cruising slower than their model: drone -> the speed it held (m/s)."""
    out: dict[str, float] = {}
    participants = doc.get("participants") or {}
    for drone in drones:
        part = participants.get(drone)
        cruise = part.get("cruise_mps") if isinstance(part, dict) else None
        if not isinstance(cruise, int | float) or cruise < MIN_CRUISE_MPS:
            continue
        declared = sim_settings(fleet, drone)[0].horizontal_speed_mps
        if cruise < SLOWER * declared:
            out[drone] = float(cruise)
    return out


def look_ahead(
    compiled: CompiledMission,
    fleet: FleetConfig,
    doc: Mapping[str, Any],
    *,
    time_limit_s: float = 3600.0,
    max_runs: int = LOOK_AHEAD_MAX_RUNS,
) -> LookAhead:
    """Continue the snapshot ``doc`` of ``compiled`` in virtual time on every branch.

    Raises :class:`~eamos.virtual.SnapshotError` for a snapshot of another mission and
    :class:`~eamos.config.ConfigError` for fleet settings the model cannot use.
    """
    started = time.process_time()
    fleet = fleet.for_mission(compiled.programs, compiled.mission.types)
    drones = [d for d in compiled.programs if d in (doc.get("participants") or {})]
    speeds = measured_speeds(doc, fleet, drones)
    report = check_mission(
        compiled,
        fleet,
        time_limit_s=time_limit_s,
        max_runs=max_runs,
        continuation=continuation(dict(doc), "look-ahead"),
        speeds=speeds,
    )
    predictions = tuple(
        prediction(f, compiled.source_file) for f in report.findings if f.check not in _NOT_AHEAD
    )
    ended = [r.duration_s for r in report.runs if not r.timed_out]
    end = max(ended) if ended else None
    return LookAhead(
        predictions,
        end,
        len(report.runs),
        time.process_time() - started,
        speeds,
        tracks_ahead(report.tracks[0][1] if report.tracks else {}, end),
    )


def tracks_ahead(
    tracks: Mapping[str, Any], end_s: float | None
) -> dict[str, tuple[tuple[float, float, float, float], ...]]:
    """Each drone's track, one point a second, until the end or :data:`TRACK_AHEAD_S`."""
    last = min(TRACK_AHEAD_S, int(end_s) + 1 if end_s is not None else TRACK_AHEAD_S)
    return {
        drone: tuple((float(t), *track.at(float(t))) for t in range(last + 1))
        for drone, track in tracks.items()
    }


def prediction(finding: Finding, mission_file: str) -> Prediction:
    """A finding of the continued check as a prediction."""
    drones = tuple(dict.fromkeys(p.drone for p in finding.places if p.drone))
    lines = tuple(f"{p.file or mission_file}:{p.line}" for p in finding.places if p.line)
    where = finding.positions[0][1] if finding.positions else None
    return Prediction(
        finding.check, finding.severity, finding.message, finding.time_s, drones, lines, where
    )
