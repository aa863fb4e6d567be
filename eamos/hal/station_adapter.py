"""The ground station's adapter (``hal.adapter = "ground"``): it only waits (``PauseFor``).

The ground station is a participant without a vehicle: it flies nothing and sends one
static telemetry sample (its home).

One scheduler thread sleeps on a :class:`threading.Condition` until the
earliest pause deadline (monotonic clock), so pauses need no timer thread
each and cancel at once.  ``speedup`` shortens pauses like the simulator's.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from eamos.hal.api import (
    ActionHandle,
    ActionResult,
    AdapterError,
    DoneCallback,
    Telemetry,
    TelemetryCallback,
)
from eamos.hal.kinematics import GeoFrame
from eamos.hal.settings import COMMON_KEYS, check_keys, number, require_mapping
from eamos.logs import EventLog, make_logger
from eamos.program.plugins import EMPTY_PLUGINS, PluginRegistry
from eamos.program.uniform import Command, PauseFor


@dataclass(frozen=True)
class GroundSettings:
    """Settings of the ground station; build with :meth:`from_mapping`."""

    speedup: float = 1.0
    home_lat_deg: float = 46.6103
    home_lon_deg: float = 14.2640
    home_alt_m: float = 0.0

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], prefix: str = "hal") -> GroundSettings:
        """Validate the ground station's ``hal`` settings (errors name the field)."""
        mapping = require_mapping(mapping, prefix)
        check_keys(
            mapping, {"speedup", "home_lat_deg", "home_lon_deg", "home_alt_m"} | COMMON_KEYS, prefix
        )
        return cls(
            speedup=number(mapping, "speedup", cls.speedup, prefix, gt=0),
            home_lat_deg=number(mapping, "home_lat_deg", cls.home_lat_deg, prefix, ge=-90, le=90),
            home_lon_deg=number(mapping, "home_lon_deg", cls.home_lon_deg, prefix, ge=-180, le=180),
            home_alt_m=number(mapping, "home_alt_m", cls.home_alt_m, prefix),
        )


@dataclass(eq=False)
class _Pause:
    handle: ActionHandle
    done: DoneCallback
    deadline: float  # time.monotonic()


class GroundAdapter:
    """An :class:`~eamos.hal.api.Adapter` for the ground station: ``PauseFor`` only."""

    #: The adapter family plugins name implementations for: the station runs none.
    family = "ground"
    #: The plugin actions it runs: none (docs/plugins.md).
    plugins: PluginRegistry = EMPTY_PLUGINS

    def __init__(
        self,
        drone: str = "GCS",
        settings: GroundSettings | None = None,
        adapter_log: EventLog | None = None,
    ) -> None:
        self.drone = drone
        self.settings = settings or GroundSettings()
        self._log = adapter_log if adapter_log is not None else make_logger(None)
        self._cond = threading.Condition()
        self._pauses: dict[int, _Pause] = {}
        self._thread: threading.Thread | None = None
        self._closed = False

    def start(self, on_telemetry: TelemetryCallback) -> None:
        """Start the scheduler thread and send the station's one static sample."""
        with self._cond:
            if self._closed:
                raise AdapterError(f"{self.drone}: ground adapter already closed")
            if self._thread is not None:
                raise AdapterError(f"{self.drone}: ground adapter already started")
            self._thread = threading.Thread(
                target=self._loop, name=f"ground-{self.drone}", daemon=True
            )
            self._thread.start()
        s = self.settings
        self._log.info("adapter.start", adapter="ground", speedup=s.speedup)
        lat, lon, alt = GeoFrame(s.home_lat_deg, s.home_lon_deg, s.home_alt_m).to_lla(0, 0, 0)
        on_telemetry(
            Telemetry(
                drone=self.drone,
                time_s=time.time(),
                x_m=0.0,
                y_m=0.0,
                z_m=0.0,
                lat_deg=lat,
                lon_deg=lon,
                alt_m=alt,
                battery_pct=100.0,
                armed=False,
                landed=True,
            )
        )

    def run(self, command: Command, done: DoneCallback) -> ActionHandle:
        """Start a ``PauseFor``; any other action fails at once (the station cannot fly)."""
        handle = ActionHandle.of(command)
        self._log.info(
            "adapter.action.start", action=handle.action, args=list(handle.args), handle=handle.id
        )
        if not isinstance(command, PauseFor):
            # The station flies nothing and carries no payload: every motion, every
            # uniform action but PauseFor and every plugin action fail here, clearly.
            failure = f"the ground station cannot {command.action}"
            self._end(handle, done, ActionResult("failed", failure))
            return handle
        if not command.duration_s >= 0:
            failure = f"duration_s must be >= 0, got {command.duration_s!r}"
            self._end(handle, done, ActionResult("failed", failure))
            return handle
        deadline = time.monotonic() + command.duration_s / self.settings.speedup
        with self._cond:
            if self._closed:
                raise AdapterError(f"{self.drone}: ground adapter closed")
            self._pauses[handle.id] = _Pause(handle, done, deadline)
            self._cond.notify_all()
        return handle

    def cancel(self, handle: ActionHandle) -> None:
        """End a running pause ``cancelled``; a finished one is left alone."""
        with self._cond:
            pause = self._pauses.pop(handle.id, None)
        if pause is not None:
            self._end(pause.handle, pause.done, ActionResult("cancelled", "cancelled"))

    def abort(self) -> None:
        """End every running pause ``cancelled``."""
        self._log.info("adapter.abort")
        self._cancel_all("aborted")

    def close(self) -> None:
        """Stop the scheduler thread; running pauses end ``cancelled``. Idempotent."""
        with self._cond:
            if self._closed:
                return
            self._closed = True
            self._cond.notify_all()
            thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join()
        self._cancel_all("adapter closed")
        self._log.info("adapter.close")

    def _cancel_all(self, reason: str) -> None:
        with self._cond:
            pauses = list(self._pauses.values())
            self._pauses.clear()
        for pause in pauses:
            self._end(pause.handle, pause.done, ActionResult("cancelled", reason))

    def _end(self, handle: ActionHandle, done: DoneCallback, result: ActionResult) -> None:
        self._log.info(
            "adapter.action.end",
            action=handle.action,
            args=list(handle.args),
            handle=handle.id,
            status=result.status,
            reason=result.reason,
        )
        try:
            done(result)
        except Exception as exc:
            self._log.exception("adapter.callback_error", error=repr(exc))

    def _loop(self) -> None:
        while True:
            with self._cond:
                while True:
                    if self._closed:
                        return
                    now = time.monotonic()
                    due = [p for p in self._pauses.values() if p.deadline <= now]
                    if due:
                        for pause in due:
                            del self._pauses[pause.handle.id]
                        break
                    nxt = min((p.deadline for p in self._pauses.values()), default=None)
                    # Sleep until the earliest deadline, or until run/cancel/close notify.
                    self._cond.wait(None if nxt is None else nxt - now)
            for pause in sorted(due, key=lambda p: p.deadline):
                self._end(pause.handle, pause.done, ActionResult("ok"))


def ground_adapter_from_settings(
    drone: str, settings: Mapping[str, Any], adapter_log: EventLog | None = None
) -> GroundAdapter:
    """Build a :class:`GroundAdapter` from the ground station's ``hal`` settings."""
    return GroundAdapter(drone, GroundSettings.from_mapping(settings), adapter_log)
