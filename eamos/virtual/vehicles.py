"""The vehicles of a virtual run: simulated quadcopters stepped by the driver, ground pauses.

The driver only needs what :class:`Vehicle` lists; :func:`sim_vehicles` makes
the simulator's pure core (:class:`eamos.hal.sim.core.SimCore`) for every
drone, and tests or the pre-flight checker may pass their own factory.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from ..hal.api import ActionHandle, ActionResult, DoneCallback, Telemetry
from ..hal.kinematics import VehicleState
from ..hal.sim import SIM_DT_S, SimCore, SimSettings
from ..program.plugins import EMPTY_PLUGINS, PluginRegistry, discover_plugins
from ..program.uniform import Command

if TYPE_CHECKING:
    from eamos.logs import EventLog

#: A finished action: its done callback and its result.
Finished = tuple[DoneCallback, ActionResult]
Clock = Callable[[], float]


class Vehicle(Protocol):
    """A vehicle advanced step by step in virtual time (the shape of ``SimCore``)."""

    def start(self) -> Telemetry: ...

    def run(self, command: Command, done: DoneCallback) -> ActionHandle: ...

    def cancel(self, handle: ActionHandle) -> None: ...

    def abort(self) -> None: ...

    def step(self) -> tuple[list[Finished], list[Telemetry]]: ...

    def state(self) -> Any: ...


@runtime_checkable
class IdleVehicle(Vehicle, Protocol):
    """A vehicle that can say when nothing happens in its next steps, and skip them.

    The driver fast-forwards over steps every vehicle calls idle (a fleet
    standing on the ground or hovering through a long pause), so virtual time
    runs far faster than one step at a time; what the run shows is unchanged.
    """

    def idle_steps(self, limit: int) -> int: ...

    def skip(self, steps: int) -> None: ...


@runtime_checkable
class QuietVehicle(IdleVehicle, Protocol):
    """An :class:`IdleVehicle` that rests longer while nobody reads its telemetry.

    ``quiet_steps`` are its idle steps when no sample it sends is read (a
    hovering drone's battery then ends no rest); ``unsent()`` is the latest
    sample the steps it skipped so would have sent, for whoever starts reading.
    """

    def quiet_steps(self, limit: int) -> int: ...

    def unsent(self) -> Telemetry | None: ...


@runtime_checkable
class SettlingVehicle(Protocol):
    """A vehicle that still changes by itself once its actions are over.

    ``settling`` is true while it will (the simulator: a disarm after landing is
    due, as on PX4 and ArduCopter); the driver steps such vehicles on after the
    mission has ended, so the final state is the one a real autopilot is left in.
    """

    @property
    def settling(self) -> bool: ...


def settles(vehicle: object) -> SettlingVehicle | None:
    """``vehicle`` if it can say it is settling, else None (a protocol check: do it once)."""
    return vehicle if isinstance(vehicle, SettlingVehicle) else None


class LazyVehicle:
    """An :class:`IdleVehicle` stepped only when something can happen to it.

    After each real step it asks the vehicle how many coming steps are idle
    and sleeps through them; the skipped steps are applied in one
    :meth:`IdleVehicle.skip` when it wakes, or before anyone talks to it
    (run, cancel, abort, state), so what it does and shows is exactly what
    stepping it every time would give.  ``now()`` is the driver's step
    count, ``horizon()`` the steps left before the driver's time limit.
    ``woken(vehicle)``, if given, is called whenever :attr:`wake` changes (the
    driver keeps the wakes in a heap instead of asking every vehicle every step).
    ``read()``, if given, says whether anyone reads the vehicle's telemetry now:
    while nobody does, a :class:`QuietVehicle` sleeps through the samples only
    its battery would change, and the driver asks for the latest of them
    (:meth:`unsent`) when someone starts reading (:meth:`read_again`).
    """

    def __init__(
        self,
        inner: IdleVehicle,
        now: Callable[[], int],
        horizon: Callable[[], int],
        woken: Callable[[LazyVehicle], None] | None = None,
        read: Callable[[], bool] | None = None,
    ):
        self._inner = inner
        self._settles = settles(inner)
        self._now = now
        self._horizon = horizon
        self._woken = woken
        self._quiet = inner if read is not None and isinstance(inner, QuietVehicle) else None
        self._read = read
        self._at = 0  # the driver step the vehicle has been advanced to
        self.wake = 1  # the next driver step that must really step it

    def _sync(self) -> None:
        lag = self._now() - self._at
        if lag > 0:
            self._inner.skip(lag)
            self._at += lag

    def _touch(self) -> None:
        """Someone talks to the vehicle: bring it up to now; it steps next time."""
        self._sync()
        self.wake = self._at + 1
        if self._woken is not None:
            self._woken(self)

    @property
    def plugins(self) -> PluginRegistry:
        """The plugin actions the wrapped vehicle runs (none if it does not say)."""
        plugins: PluginRegistry = getattr(self._inner, "plugins", EMPTY_PLUGINS)
        return plugins

    def start(self) -> Telemetry:
        """As the wrapped vehicle."""
        return self._inner.start()

    def run(self, command: Command, done: DoneCallback) -> ActionHandle:
        """As the wrapped vehicle."""
        self._touch()
        return self._inner.run(command, done)

    def cancel(self, handle: ActionHandle) -> None:
        """As the wrapped vehicle."""
        self._touch()
        self._inner.cancel(handle)

    def abort(self) -> None:
        """As the wrapped vehicle."""
        self._touch()
        self._inner.abort()

    def state(self) -> Any:
        """As the wrapped vehicle, up to now."""
        self._sync()
        return self._inner.state()

    @property
    def settling(self) -> bool:
        """As the wrapped vehicle, up to now (False if it cannot tell)."""
        if self._settles is None:
            return False
        self._sync()
        return self._settles.settling

    def step(self) -> tuple[list[Finished], list[Telemetry]]:
        """The driver's step ``now()``: a real step if due, else nothing (still idle)."""
        now = self._now()
        if now < self.wake:
            return [], []
        lag = now - 1 - self._at
        if lag > 0:
            self._inner.skip(lag)
        out = self._inner.step()
        self._at = now
        quiet, read = self._quiet, self._read
        if quiet is not None and read is not None and not read():
            self.wake = now + 1 + quiet.quiet_steps(self._horizon())
        else:
            self.wake = now + 1 + self._inner.idle_steps(self._horizon())
        if self._woken is not None:
            self._woken(self)
        return out

    def unsent(self) -> Telemetry | None:
        """Up to now: the latest sample its skipped steps would have sent (None: none)."""
        if self._quiet is None:
            return None
        self._sync()
        return self._quiet.unsent()

    def read_again(self) -> None:
        """Someone reads its telemetry again: wake it for the next sample that shows news."""
        if self._quiet is None:
            return
        self._sync()
        wake = self._at + 1 + self._inner.idle_steps(self._horizon())
        if wake < self.wake:
            self.wake = wake
            if self._woken is not None:
                self._woken(self)


class WakeQueue:
    """The lazy vehicles' wakes, earliest first, so that a driver step costs the vehicles
    due, not the whole fleet.

    Every change of a followed vehicle's :attr:`LazyVehicle.wake` is noted (its
    ``woken`` hook is :meth:`note`); notes no longer true are dropped when they come up.
    """

    def __init__(self) -> None:
        self._heap: list[tuple[int, int]] = []  # (wake, order)
        self._order: dict[int, int] = {}  # id(vehicle) -> its place among the followed
        self._vehicles: list[LazyVehicle] = []

    def follow(self, vehicles: list[LazyVehicle]) -> None:
        """Follow ``vehicles``, in the order they are stepped in."""
        self._vehicles = list(vehicles)
        self._order = {id(v): i for i, v in enumerate(self._vehicles)}
        self._heap = [(v.wake, i) for i, v in enumerate(self._vehicles)]
        heapq.heapify(self._heap)

    def note(self, vehicle: LazyVehicle) -> None:
        """``vehicle``'s wake changed (a vehicle not followed is ignored)."""
        order = self._order.get(id(vehicle))
        if order is not None:
            heapq.heappush(self._heap, (vehicle.wake, order))

    def first(self) -> int | None:
        """The earliest wake (None: no vehicle followed)."""
        heap, vehicles = self._heap, self._vehicles
        while heap and vehicles[heap[0][1]].wake != heap[0][0]:
            heapq.heappop(heap)
        return heap[0][0] if heap else None

    def due(self, now: int) -> list[int]:
        """The places of the vehicles whose wake is ``now`` or before, in order.

        Their notes are taken off: stepped, each notes its next wake.
        """
        heap, vehicles = self._heap, self._vehicles
        due: set[int] = set()
        while heap and heap[0][0] <= now:
            _, order = heapq.heappop(heap)
            if vehicles[order].wake <= now:
                due.add(order)
        return sorted(due)


#: ``factory(drone, clock)`` builds the vehicle of one drone; ``clock`` reads virtual seconds.
VehicleFactory = Callable[[str, Clock], Vehicle]

#: Virtual seconds per vehicle step.
STEP_S = SIM_DT_S


class QuietLog:
    """A logger that drops everything (a virtual run needs speed, not adapter logs)."""

    def bind(self, **_: Any) -> QuietLog:
        return self

    def _drop(self, *_: Any, **__: Any) -> None:
        return None

    debug = info = warning = error = exception = critical = _drop


def sim_vehicles(
    settings: SimSettings | Mapping[str, SimSettings] | None = None,
    log: EventLog | None = None,
    plugins: PluginRegistry | None = None,
    start: Callable[[str], VehicleState | None] | None = None,
) -> VehicleFactory:
    """A factory of simulator cores: one ``settings`` for all, or one per drone.

    Drones without settings get ``SimSettings()``.  The cores run ``plugins``'
    actions (default: the plugins installed through entry points, found once here).
    ``start(drone)``: where a drone's vehicle is at the start (None: at home, on the
    ground; a continuation gives where its snapshot saw it).
    """
    registry = discover_plugins() if plugins is None else plugins

    def make(drone: str, clock: Clock) -> Vehicle:
        if isinstance(settings, Mapping):
            chosen = settings.get(drone, SimSettings())
        else:
            chosen = settings or SimSettings()
        return SimCore(
            drone,
            chosen,
            log if log is not None else QuietLog(),
            clock,
            plugins=registry,
            start=None if start is None else start(drone),
        )

    return make


class GroundPauses:
    """The ground station's ``PauseFor`` in virtual time (it never flies)."""

    def __init__(self) -> None:
        self._due: list[tuple[float, int, ActionHandle]] = []
        self._done: dict[int, DoneCallback] = {}
        self._order = itertools.count()

    def run(self, now_s: float, command: Command, done: DoneCallback) -> ActionHandle | None:
        """Start a pause; any other action fails at once (then None is returned)."""
        handle = ActionHandle(command.action, command.args)
        if command.action != "PauseFor":
            # As the ground adapter: no motion, no payload, no plugin action.
            done(ActionResult("failed", f"the ground station cannot {command.action}"))
            return None
        if command.args[0] < 0:
            done(ActionResult("failed", f"duration_s must be >= 0, got {command.args[0]!r}"))
            return None
        self._done[handle.id] = done
        heapq.heappush(self._due, (now_s + command.args[0], next(self._order), handle))
        return handle

    def cancel(self, handle: ActionHandle) -> None:
        """End a running pause ``cancelled`` (a finished one is left alone)."""
        done = self._done.pop(handle.id, None)
        if done is not None:
            done(ActionResult("cancelled", "cancelled"))

    def next_due(self) -> float | None:
        """When the earliest running pause ends."""
        while self._due and self._due[0][2].id not in self._done:
            heapq.heappop(self._due)
        return self._due[0][0] if self._due else None

    def expire(self, now_s: float) -> list[Finished]:
        """The pauses due by ``now_s``, finished ``ok``."""
        out: list[Finished] = []
        while self._due and self._due[0][0] <= now_s + 1e-9:
            _, _, handle = heapq.heappop(self._due)
            done = self._done.pop(handle.id, None)
            if done is not None:
                out.append((done, ActionResult("ok")))
        return out

    def busy(self) -> bool:
        """True while a pause runs."""
        return bool(self._done)
