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

Two optional parts (an adapter without them has neither):

* ``taken_over``: None, or a :class:`TakenOver` once a pilot has taken the vehicle
  (a mode change that neither the adapter nor a documented failsafe made).  From
  then on the adapter never commands that vehicle again, and whoever drives it
  (the uniform API) asks nothing more of it: every action fails with
  :meth:`TakenOver.reason`, and neither an abort nor ``close()`` lands, disarms or
  restores a parameter.  :func:`taken_over` reads it.
* ``facts()``: what the adapter knows about its vehicle for the run's summary, as
  a small JSON object (whether its link was signed, where home is, a takeover);
  :func:`vehicle_facts` reads it.
* ``notices()``: what the operator must hear now, each :class:`AdapterNotice` once
  (a pilot took the vehicle; telemetry slower than the adapter needs);
  :func:`adapter_notices` reads them.

Every adapter logs its position (``adapter.position``) at
:data:`POSITION_LOG_HZ` of vehicle time while the position or the
armed/landed flags change, so reports draw tracks from dense data.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal, Protocol

import msgspec

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


class ActionResult(msgspec.Struct, frozen=True):
    """How an action ended; ``reason`` says why when it did not end ``"ok"``.

    A frozen msgspec Struct, as the runtime's messages are: one is made per action on
    the trigger path, and a frozen dataclass builds itself field by field through
    ``object.__setattr__`` (``docs/performance.md``)."""

    status: ActionStatus
    reason: str = ""

    @property
    def ok(self) -> bool:
        return self.status == "ok"


#: How the reason of an action ends that a pilot's takeover stopped (and every later one).
TAKEN_OVER_PREFIX = "taken over by the pilot"


@dataclass(frozen=True)
class TakenOver:
    """A pilot took the vehicle: the mode they chose and where it was (mission frame, m).

    ``mode`` is the autopilot's name for it (``LOITER``, ``POSCTL``); the position is
    None where the vehicle had not reported one.
    """

    mode: str
    x_m: float | None = None
    y_m: float | None = None
    z_m: float | None = None

    def reason(self) -> str:
        """Why actions of the vehicle fail from now on: ``taken over by the pilot (LOITER)``."""
        return f"{TAKEN_OVER_PREFIX} ({self.mode})"

    def where(self) -> str:
        """``at (1.00, 2.00, 1.50)`` (m from its home), or ``""`` when unknown."""
        if self.x_m is None or self.y_m is None or self.z_m is None:
            return ""
        return f"at ({self.x_m:.2f}, {self.y_m:.2f}, {self.z_m:.2f})"

    def describe(self) -> str:
        """``taken over by the pilot in LOITER at (1.00, 2.00, 1.50)``: the summary's words."""
        where = self.where()
        return f"{TAKEN_OVER_PREFIX} in {self.mode}" + (f" {where}" if where else "")

    def to_json(self) -> dict[str, Any]:
        return {"mode": self.mode, "x_m": self.x_m, "y_m": self.y_m, "z_m": self.z_m}

    @classmethod
    def from_json(cls, data: Any) -> TakenOver | None:
        """The takeover a JSON object records (None for anything else)."""
        if not isinstance(data, dict) or not isinstance(data.get("mode"), str):
            return None

        def number(key: str) -> float | None:
            value = data.get(key)
            if isinstance(value, bool) or not isinstance(value, int | float):
                return None
            return float(value)

        return cls(data["mode"], number("x_m"), number("y_m"), number("z_m"))


@dataclass(frozen=True)
class AdapterNotice:
    """Something the operator must hear while the mission flies (``kind``: ``taken_over``,
    ``warning``), in words."""

    kind: Literal["taken_over", "warning"]
    text: str


def adapter_notices(adapter: object) -> list[AdapterNotice]:
    """The adapter's new ``notices()`` ([] for an adapter without them)."""
    notices = getattr(adapter, "notices", None)
    if not callable(notices):
        return []
    return [n for n in notices() if isinstance(n, AdapterNotice)]


def taken_over(adapter: object) -> TakenOver | None:
    """The adapter's :class:`TakenOver` (None: no pilot has its vehicle, or it cannot tell)."""
    value = getattr(adapter, "taken_over", None)
    return value if isinstance(value, TakenOver) else None


def read_at_most(adapter: object, hz: float | None) -> None:
    """Tell ``adapter`` its samples are read at most ``hz`` times a second (None: as they
    come), for an adapter that paces what it sends by it (the simulated one at rest)."""
    tell = getattr(adapter, "read_at_most", None)
    if callable(tell):
        tell(hz)


def vehicle_facts(adapter: object) -> dict[str, Any]:
    """The adapter's ``facts()`` for the run's summary ({} for an adapter without them)."""
    facts = getattr(adapter, "facts", None)
    if not callable(facts):
        return {}
    value = facts()
    return dict(value) if isinstance(value, dict) else {}


_handle_ids = itertools.count(1)


class ActionHandle(msgspec.Struct, frozen=True):
    """Identifies one running action of one adapter (a frozen Struct: see ActionResult)."""

    action: str
    args: tuple[float, ...]
    id: int = msgspec.field(default_factory=lambda: next(_handle_ids))

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
