"""Telemetry from a MAVLink vehicle to the mission: a sample whenever the state changed.

The link's ticker publishes at ``telemetry_hz`` of vehicle time (``speedup`` times as
often on the wall clock); a finishing action publishes once more
before its ``done``, so whoever reacts to the end already sees the state it ended in.
"""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING

from eamos.hal.api import TelemetryCallback

if TYPE_CHECKING:
    from eamos.hal.mavlink.vehicle import MavlinkVehicle
    from eamos.logs import EventLog


class TelemetryPublisher:
    """Hands the vehicle's sample to the mission when it differs from the last one handed.

    Serialized: the ticker and finishing actions both publish, and samples must reach
    the mission in the order they were taken.  Once the receiver is gone (the mission's
    actor stopped before the adapter closed), it publishes no more.
    """

    def __init__(self, vehicle: MavlinkVehicle, log: EventLog) -> None:
        self.vehicle = vehicle
        self._log = log
        self._lock = threading.Lock()
        self._last_key: tuple[float | bool, ...] | None = None
        self._on_telemetry: TelemetryCallback | None = None

    def connect(self, on_telemetry: TelemetryCallback) -> None:
        """From now on, samples go to ``on_telemetry``."""
        self._on_telemetry = on_telemetry

    def publish(self) -> None:
        """Send a telemetry sample if it differs from the last one sent."""
        with self._lock:
            with self.vehicle.cond:
                sample = self.vehicle.sample()
                if sample is None:
                    return
                key = sample.state()
                if key == self._last_key:
                    return
                self._last_key = key
            callback = self._on_telemetry
            if callback is not None:
                try:
                    callback(sample)
                except Exception as exc:
                    if type(exc).__name__ == "ActorDeadError":
                        # The node is shutting down before us: no one listens any more.
                        self._on_telemetry = None
                        self._log.info("adapter.telemetry_closed", reason=repr(exc))
                    else:
                        self._log.exception("adapter.telemetry_error", error=repr(exc))


__all__ = ["TelemetryPublisher"]
