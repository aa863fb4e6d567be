"""What a drone was seen to fly, from its telemetry: the live look-ahead's battery measure.

The ground station adds up, over each pair of consecutive samples in which the drone was
airborne (armed, not landed), the seconds, the horizontal metres, the metres climbed and
the battery percent used.  From them the look-ahead tells how much faster than its model
the drone's battery drains (:func:`eamos.check.lookahead.measured_drains`): the model's
drain over the same flight is ``(airborne x s + per-m/s x m + climb-per-m/s x climbed) / 60``.
Pure: samples in, a frozen record out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from eamos.net import wire

__all__ = ["Flown"]


@dataclass(frozen=True)
class Flown:
    """A drone's airborne flight so far, as its telemetry showed it."""

    seconds: float = 0.0
    metres: float = 0.0
    climbed_m: float = 0.0
    battery_used_pct: float = 0.0

    def after(self, a: wire.TelemetrySample, b: wire.TelemetrySample) -> Flown:
        """This tally with the stretch from sample ``a`` to the next one, ``b``, added
        when the drone was airborne through both (and time went forward)."""
        dt = b.time_s - a.time_s
        if dt <= 0 or not (a.armed and b.armed) or a.landed or b.landed:
            return self
        return Flown(
            self.seconds + dt,
            self.metres + math.hypot(b.x_m - a.x_m, b.y_m - a.y_m),
            self.climbed_m + max(0.0, b.z_m - a.z_m),
            self.battery_used_pct + max(0.0, a.battery_pct - b.battery_pct),
        )

    def to_json(self) -> dict[str, Any]:
        """As the snapshot carries it (``flown``)."""
        return {
            "s": round(self.seconds, 2),
            "m": round(self.metres, 2),
            "climbed_m": round(self.climbed_m, 2),
            "battery_used_pct": round(self.battery_used_pct, 2),
        }
