"""When is a move done?  Tolerances scaled for short moves, and a settle window after the command.

A move is done when the vehicle, averaged over the settle window, is within a tolerance
of its target and slow.  The tolerance is the autopilot's (or the settings') but never
more than :data:`SHORT_MOVE_FRACTION` of the move itself, nor less than
:data:`MIN_TOLERANCE_M`: with a fixed 0.6 m a 0.5 m move was "done" before it started,
and a 1.5 m take-off at 0.97 m.  The window must also lie wholly after the command went
out (:meth:`Arrival.window_start`), so a move shorter than its tolerance is still flown
and watched for a whole window, never judged on samples from before it.

Pure: no clock, no threads; the vehicle (:meth:`~eamos.hal.mavlink.vehicle.MavlinkVehicle.
arrived`) supplies the window's mean position and speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from eamos.hal.mavlink.frames import Vector

#: A move's tolerance is at most this fraction of its length...
SHORT_MOVE_FRACTION = 0.4
#: ...and at least this (m; an autopilot may need more: its estimate's noise decides
#: below that, not the flight, Autopilot.min_tolerance_m).
MIN_TOLERANCE_M = 0.05


def move_tolerance(base_m: float, move_m: float, floor_m: float = MIN_TOLERANCE_M) -> float:
    """The tolerance of a move of ``move_m`` metres (the autopilot's ``base_m``, scaled
    down to :data:`SHORT_MOVE_FRACTION` of the move, never below ``floor_m``)."""
    return max(floor_m, min(base_m, SHORT_MOVE_FRACTION * abs(move_m)))


@dataclass(frozen=True)
class Arrival:
    """What "arrived" means for one move: the target, its tolerance, and since when."""

    target: Vector
    tolerance_m: float
    #: When the command went out (time.monotonic()): the window starts no earlier.
    since: float
    #: Only the height counts (a take-off may drift a little sideways).
    vertical: bool = False

    @classmethod
    def of_move(
        cls,
        start: Vector,
        target: Vector,
        base_m: float,
        since: float,
        vertical: bool = False,
        floor_m: float = MIN_TOLERANCE_M,
    ) -> Arrival:
        """The arrival of a move from ``start`` (where it was meant to begin) to ``target``."""
        length = abs(target[2] - start[2]) if vertical else math.dist(start, target)
        return cls(target, move_tolerance(base_m, length, floor_m), since, vertical)

    def window_start(self, now: float, window_s: float) -> float | None:
        """Start of the settle window ending ``now``; None while it would reach back
        before the command."""
        start = now - window_s
        return start if start >= self.since else None

    def error_m(self, position: Vector) -> float:
        """How far ``position`` is from the target (its height only if ``vertical``)."""
        if self.vertical:
            return abs(position[2] - self.target[2])
        return math.dist(position, self.target)

    def reached(self, position: Vector, speed_mps: float, settle_speed_mps: float) -> bool:
        """The window's mean ``position`` within tolerance and its mean speed slow."""
        return speed_mps <= settle_speed_mps and self.error_m(position) <= self.tolerance_m


__all__ = ["MIN_TOLERANCE_M", "SHORT_MOVE_FRACTION", "Arrival", "move_tolerance"]
