"""The live look-ahead: the rest of a flying mission, simulated from where it is now.

While a mission flies, the ground station (:mod:`eamos.ground.lookahead`) takes the
mission's state every few seconds (the snapshot it writes for the operator,
:mod:`eamos.ground.snapshot`) and hands it to :func:`look_ahead`, which continues it
in virtual time on every branch still open, as ``eamos check --from`` does, with two
differences: a drone that has been seen flying slower than its type says
(``cruise_mps`` in the snapshot: the fastest horizontal speed it held over two
telemetry intervals) is simulated at that speed, and a drone whose battery was seen
draining faster in the air than its model says over the same flight (``flown`` in the
snapshot: seconds, metres, climb and battery used, :mod:`eamos.ground.flown`) drains that
many times faster.  A disturbance the pre-flight check cannot know (wind, a weak motor,
a cold battery) then shows as what it leads to: a separation conflict in 40 s, a battery
below the reserve, a geofence exit, a deadlock, and the time the mission is now
expected to end.

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
from ..hal.sim import MAX_DRAIN_FACTOR
from ..virtual import continuation
from .explore import check_mission, sim_settings
from .findings import Finding

__all__ = [
    "LOOK_AHEAD_MAX_RUNS",
    "LookAhead",
    "Prediction",
    "look_ahead",
    "measured_drains",
    "measured_speeds",
]

#: Branches simulated per cycle at most (each a whole rest of the mission).
LOOK_AHEAD_MAX_RUNS = 16
#: How far ahead each drone's predicted track is given (s), one point a second.
TRACK_AHEAD_S = 60
#: Below this a drone has not been seen cruising: its model's speed is kept (m/s).
MIN_CRUISE_MPS = 0.3
#: Seen holding less than this fraction of its type's speed, a drone is flown at what it
#: held; above, at its model's (a sample's timing moves the measure by a few per cent).
SLOWER = 0.95
#: Below this much battery its model would have used over the flight seen, a drone's drain
#: is not measured (percent; the telemetry shows the battery to a tenth of a percent).
MIN_MODELLED_USE_PCT = 1.0
#: Seen draining more than this many times its model, a drone drains at what was seen.
FASTER = 1.05
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
    #: The keys of the nodes whose actions it names (the monitor outlines them).
    nodes: tuple[str, ...] = ()

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
            "nodes": list(self.nodes),
        }


@dataclass(frozen=True)
class LookAhead:
    """One cycle's outcome: what it predicts, when the mission should end, what it cost."""

    predictions: tuple[Prediction, ...]
    end_in_s: float | None  # the longest branch's remaining time (None: none ended)
    runs: int  # branches simulated
    cpu_s: float  # CPU seconds this cycle took
    speeds: Mapping[str, float]  # measured horizontal speeds it flew drones at (m/s)
    # How many times faster than its model each drone's battery was seen to drain.
    drains: Mapping[str, float] = field(default_factory=dict)
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
            "drain_factors": {d: round(v, 2) for d, v in self.drains.items()},
            "ahead": {d: [[round(v, 2) for v in p] for p in pts] for d, pts in self.ahead.items()},
        }


def _measured(doc: Mapping[str, Any], drones: list[str], name: str) -> list[tuple[str, Any]]:
    """Each of ``drones`` the snapshot has a part for, with that part's ``name`` field."""
    participants = doc.get("participants") or {}
    parts = [(d, participants.get(d)) for d in drones]
    return [(d, part.get(name)) for d, part in parts if isinstance(part, dict)]


def measured_speeds(
    doc: Mapping[str, Any],
    fleet: FleetConfig,
    drones: list[str],
    speedups: Mapping[str, float] | None = None,
) -> dict[str, float]:
    """The drones seen cruising slower than their model: drone -> the speed it held (m/s
    of vehicle time: the wall-clock measure divided by the drone's speed-up)."""
    out: dict[str, float] = {}
    for drone, cruise in _measured(doc, drones, "cruise_mps"):
        if not isinstance(cruise, int | float):
            continue
        cruise = cruise / (speedups or {}).get(drone, 1.0)
        if cruise < MIN_CRUISE_MPS:
            continue
        declared = sim_settings(fleet, drone)[0].horizontal_speed_mps
        if cruise < SLOWER * declared:
            out[drone] = float(cruise)
    return out


def measured_drains(
    doc: Mapping[str, Any],
    fleet: FleetConfig,
    drones: list[str],
    speedups: Mapping[str, float] | None = None,
) -> dict[str, float]:
    """The drones seen draining their battery faster in the air than their model says:
    drone -> how many times faster (the battery used over the flight seen, against what
    the model would have used over the same seconds of vehicle time, metres and climb)."""
    out: dict[str, float] = {}
    for drone, flown in _measured(doc, drones, "flown"):
        if not isinstance(flown, dict):
            continue
        try:
            seconds = float(flown["s"]) * (speedups or {}).get(drone, 1.0)
            metres = float(flown["m"])
            climbed, used = float(flown["climbed_m"]), float(flown["battery_used_pct"])
        except (KeyError, TypeError, ValueError):
            continue
        model = sim_settings(fleet, drone)[0]
        modelled = (
            model.drain_airborne_pct_per_min * seconds
            + model.drain_per_mps_pct_per_min * metres
            + model.drain_climb_per_mps_pct_per_min * climbed
        ) / 60.0
        if modelled < MIN_MODELLED_USE_PCT:
            continue
        factor = used / modelled
        if factor > FASTER:
            out[drone] = min(factor, MAX_DRAIN_FACTOR)
    return out


def look_ahead(
    compiled: CompiledMission,
    fleet: FleetConfig,
    doc: Mapping[str, Any],
    *,
    time_limit_s: float = 3600.0,
    max_runs: int = LOOK_AHEAD_MAX_RUNS,
    speedups: Mapping[str, float] | None = None,
) -> LookAhead:
    """Continue the snapshot ``doc`` of ``compiled`` in virtual time on every branch.

    ``speedups``: each drone's simulation speed-up (1 when absent), which turns the
    snapshot's wall-clock measures of speed and drain into vehicle time.

    Raises :class:`~eamos.virtual.SnapshotError` for a snapshot of another mission and
    :class:`~eamos.config.ConfigError` for fleet settings the model cannot use.
    """
    started = time.process_time()
    fleet = fleet.for_mission(compiled.programs, compiled.mission.types)
    drones = [d for d in compiled.programs if d in (doc.get("participants") or {})]
    speeds = measured_speeds(doc, fleet, drones, speedups)
    drains = measured_drains(doc, fleet, drones, speedups)
    report = check_mission(
        compiled,
        fleet,
        time_limit_s=time_limit_s,
        max_runs=max_runs,
        continuation=continuation(dict(doc), "look-ahead"),
        speeds=speeds,
        drains=drains,
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
        drains,
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
    nodes = tuple(dict.fromkeys(p.node for p in finding.places if p.node))
    return Prediction(
        finding.check,
        finding.severity,
        finding.message,
        finding.time_s,
        drones,
        lines,
        where,
        nodes,
    )
