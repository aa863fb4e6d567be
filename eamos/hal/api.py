"""The seam between the uniform API and the adapters (paper Figures 4 and 5).

An *adapter* drives one vehicle (a simulated quadcopter, a MAVLink autopilot,
a fake for unit tests).  The uniform API (:mod:`eamos.actors.uniform_api`) owns
exactly one adapter and is the only caller of these methods.  An adapter that
may block (MAVLink, the ground adapter) is called from the uniform-API actor's
own thread only; one that answers at once (``answers_at_once = True``, or the
``"sim"`` family: the simulator and the fake) is called directly by the node
actors, from any worker thread, so it must be thread-safe (both lock).
Adapters call back from any thread they like.

Contract every adapter keeps:

* ``start(on_telemetry)`` connects and begins calling ``on_telemetry`` with a
  fresh :class:`Telemetry` whenever the vehicle state changes (and at most at
  the adapter's telemetry rate).  It raises :class:`AdapterError` if the
  vehicle cannot be reached.
* ``run(command, done)`` starts one uniform action, already decoded into a
  typed :class:`~eamos.program.uniform.Command` (the uniform-API actor decodes
  every action once), and returns at once with an :class:`ActionHandle`.
  Adapters dispatch on the command's class, never on action names.
  ``done`` is called exactly once with an :class:`ActionResult`, from any
  thread.  An action completes on real criteria (position within tolerance,
  landed, armed flag seen), never on a timer alone, and fails with a reason
  after its own timeout.
* ``cancel(handle)`` interrupts a running action: the vehicle holds its
  position and ``done`` is called with status ``"cancelled"``.  Cancelling a
  finished action does nothing.
* ``abort()`` cancels every running action and lands the vehicle.
* ``close()`` releases threads and sockets; it is idempotent.

Every adapter logs its position (``adapter.position``) at
:data:`POSITION_LOG_HZ` of vehicle time while the position or the
armed/landed flags change, so reports draw tracks from dense data.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal, Protocol

from eamos.program.plugins import PluginRegistry
from eamos.program.uniform import Command

ActionStatus = Literal["ok", "failed", "cancelled"]

#: The rate of ``adapter.position`` lines while the vehicle moves (docs/logs.md).
POSITION_LOG_HZ = 5.0


class AdapterError(Exception):
    """The vehicle behind an adapter cannot be used (unreachable, bad settings)."""


@dataclass(frozen=True)
class Telemetry:
    """One sample of a vehicle's state in the mission frame (X north, Y east, Z up)."""

    drone: str
    time_s: float  # wall clock (epoch seconds) when the sample was taken
    x_m: float
    y_m: float
    z_m: float
    lat_deg: float
    lon_deg: float
    alt_m: float
    battery_pct: float
    armed: bool
    landed: bool = True

    def state(self) -> tuple[float | bool, ...]:
        """The sample without its timestamp: two samples with equal states carry no news."""
        return (
            self.x_m,
            self.y_m,
            self.z_m,
            self.lat_deg,
            self.lon_deg,
            self.alt_m,
            self.battery_pct,
            self.armed,
            self.landed,
        )

    def value(self, field_name: str) -> float | bool:
        """The value of one telemetry field by name (see ``uniform.PROPERTY_FIELDS``)."""
        return getattr(self, field_name)  # type: ignore[no-any-return]


@dataclass(frozen=True)
class ActionResult:
    """How an action ended; ``reason`` says why when it did not end ``"ok"``."""

    status: ActionStatus
    reason: str = ""

    @property
    def ok(self) -> bool:
        return self.status == "ok"


_handle_ids = itertools.count(1)


@dataclass(frozen=True)
class ActionHandle:
    """Identifies one running action of one adapter."""

    action: str
    args: tuple[float, ...]
    id: int = field(default_factory=lambda: next(_handle_ids))

    @classmethod
    def of(cls, command: Command) -> ActionHandle:
        """A fresh handle for one run of ``command``."""
        return cls(command.action, command.args)


TelemetryCallback = Callable[[Telemetry], None]
DoneCallback = Callable[[ActionResult], None]


class Adapter(Protocol):
    """What the uniform-API actor needs from a vehicle driver (see module docstring).

    ``family`` names the adapter family plugin actions are implemented for
    (``"sim"``, ``"mavlink"``, ``"ground"``); ``plugins`` are the action plugins it
    was built with (docs/plugins.md): it runs the uniform actions and those.
    """

    drone: str
    family: str
    plugins: PluginRegistry

    def start(self, on_telemetry: TelemetryCallback) -> None: ...

    def run(self, command: Command, done: DoneCallback) -> ActionHandle: ...

    def cancel(self, handle: ActionHandle) -> None: ...

    def abort(self) -> None: ...

    def close(self) -> None: ...
