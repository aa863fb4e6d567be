"""Fly it before it flies: the pre-flight check of a compiled mission (``eamos check``).

Public names: :func:`check_mission` (compiled mission + fleet file -> :class:`CheckReport`),
:func:`check_amendment` (an amendment to a flying mission -> :class:`AmendmentReport`),
the report's parts :class:`Finding`, :class:`Place`, :class:`RunSummary`, and the
tracks and separation geometry (:class:`Track`, :func:`pair_conflicts`).
"""

from .amendment import AmendmentReport, FlyingMission, Refusal, check_amendment
from .explore import CHECK_TIME_LIMIT_S, MAX_RUNS, MIN_SEPARATION_M, check_mission
from .findings import CheckReport, Finding, Place, RunSummary
from .separation import Conflict, conflicts, pair_conflicts
from .tracks import Track, TrackPoint, TrackRecorder

__all__ = [
    "CHECK_TIME_LIMIT_S",
    "MAX_RUNS",
    "MIN_SEPARATION_M",
    "AmendmentReport",
    "CheckReport",
    "Conflict",
    "Finding",
    "FlyingMission",
    "Place",
    "Refusal",
    "RunSummary",
    "Track",
    "TrackPoint",
    "TrackRecorder",
    "check_amendment",
    "check_mission",
    "conflicts",
    "pair_conflicts",
]
