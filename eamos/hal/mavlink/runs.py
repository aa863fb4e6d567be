"""The MAVLink adapter's running actions: which may start, and the one end of each.

Everything here is read and written under the vehicle's condition
(:attr:`~eamos.hal.mavlink.vehicle.MavlinkVehicle.cond`), except that a run's
``done`` is called outside it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from eamos.hal.api import ActionResult
from eamos.hal.mavlink.waits import Run
from eamos.program.uniform import PauseFor, Payload

if TYPE_CHECKING:
    from eamos.hal.mavlink.vehicle import MavlinkVehicle
    from eamos.logs import EventLog


class ActionBook:
    """The actions an adapter runs: one motion at a time, and exactly one end each.

    :meth:`admit` records a run and says whether it ends at once (a plugin without a
    ``"mavlink"`` implementation, a vehicle a pilot took, a payload action
    acknowledged, not started, aborting, busy); :meth:`finish` ends a run once: its end logged
    (``adapter.action.end``, with where the vehicle is), the state it ended in
    published, then its ``done`` called outside the condition.
    """

    def __init__(self, vehicle: MavlinkVehicle, log: EventLog, publish: Callable[[], None]) -> None:
        self.vehicle = vehicle
        self._cond = vehicle.cond
        self._log = log
        self._publish = publish
        self._runs: dict[int, Run] = {}
        self._motion: Run | None = None

    def admit(
        self, run: Run, started: bool, aborting: bool, refused: str | None
    ) -> ActionResult | None:
        """Record ``run`` (condition held); the result it ends with at once, if any.

        ``refused``: why it fails at once (a plugin action without a "mavlink"
        implementation; a vehicle a pilot has taken over).
        """
        handle, command = run.handle, run.command
        assert handle is not None
        self._runs[handle.id] = run
        self._log.info(
            "adapter.action.start",
            action=handle.action,
            args=list(handle.args),
            handle=handle.id,
        )
        if refused is not None:
            return ActionResult("failed", refused)
        if isinstance(command, Payload):
            self._log.info(
                "adapter.payload",
                action=handle.action,
                note="no payload on this vehicle: acknowledged",
            )
            return ActionResult("ok")
        if not started:
            return ActionResult("failed", "adapter not started")
        if aborting and not isinstance(command, PauseFor):
            return ActionResult("failed", "aborting")
        if run.kind == "motion":
            if self._motion is not None:
                return ActionResult("failed", "busy")
            self._motion = run
        return None

    def running(self, handle_id: int) -> Run | None:
        """The run of the action ``handle_id`` while it runs (condition held)."""
        return self._runs.get(handle_id)

    def all_running(self) -> list[Run]:
        """Every run not finished yet (condition held)."""
        return list(self._runs.values())

    def finish(self, run: Run, result: ActionResult) -> bool:
        """Finish ``run`` once; call its done callback outside the condition."""
        with self._cond:
            if run.finished:
                return False
            run.finished = True
            if run.handle is not None:
                self._runs.pop(run.handle.id, None)
            if self._motion is run:
                self._motion = None
            self._cond.notify_all()
            known = self.vehicle.state.local is not None
            pos = self.vehicle.mission_position() if known else (math.nan,) * 3
        if run.handle is not None:
            self._log.info(
                "adapter.action.end",
                action=run.handle.action,
                args=list(run.handle.args),
                handle=run.handle.id,
                status=result.status,
                reason=result.reason,
                duration_s=round(time.monotonic() - run.started, 3),
                x_m=round(pos[0], 3),
                y_m=round(pos[1], 3),
                z_m=round(pos[2], 3),
            )
        if run.done is not None:
            # Publish the state the action ended in before anyone reacts to its end
            # (a mission that completes right after Disarm reports that sample).
            self._publish()
            try:
                run.done(result)
            except Exception as exc:
                self._log.exception("adapter.callback_error", error=repr(exc))
        return True


__all__ = ["ActionBook"]
