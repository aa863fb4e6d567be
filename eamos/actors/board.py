"""The telemetry board: latest property values per drone, pushed to the nodes watching them.

Conditions are evaluated when the telemetry they read changes (paper VI-B), never
by polling: a condition node ``Watch``-es the drones it reads, and the board
tells it every change.  Local samples (from the adapter) also go out to the
fleet through the out-bridge; remote ones arrive from the in-bridge.  The board
also answers the runtime's questions about this drone's own vehicle: has it
landed (:class:`WhenLanded`), has it stopped standing armed on the ground
(:class:`WhenSettled`: an autopilot disarms a moment after landing), and what
was its state once its last action ended (:class:`FinalSample`, for the report).
"""

from __future__ import annotations

import threading
import time
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from dataclasses import dataclass, field

import pykka

from ..hal.api import Telemetry
from ..net import wire
from .dispatch import Dispatcher
from .failure import FailureSink, RuntimePart
from .logic.telemetry import PropertyValues, telemetry_values
from .messages import Mailbox, RemoteTelemetry, TelemetryChanged, Unwatch, Watch

__all__ = [
    "FinalSample",
    "LocalSample",
    "TelemetryBoard",
    "WhenLanded",
    "WhenSettled",
    "ask_final_sample",
    "shows_effect",
]


def wire_sample(sample: Telemetry, mission_id: str, sender: str) -> wire.TelemetrySample:
    """A local sample as it goes to the fleet."""
    return wire.TelemetrySample(
        mission=mission_id,
        sender=sender,
        time_s=sample.time_s,
        x_m=sample.x_m,
        y_m=sample.y_m,
        z_m=sample.z_m,
        lat_deg=sample.lat_deg,
        lon_deg=sample.lon_deg,
        alt_m=sample.alt_m,
        battery_pct=sample.battery_pct,
        armed=sample.armed,
        landed=sample.landed,
    )


def shows_effect(action: str | None, sample: Telemetry) -> bool:
    """True when ``sample`` shows what ``action`` leaves behind (it was taken after it).

    Only for the actions whose effect is a flag: ``Disarm`` (disarmed), ``Arm``
    (armed), ``Land`` (landed); a position alone cannot tell old from new.
    """
    return (
        (action == "Disarm" and not sample.armed)
        or (action == "Arm" and sample.armed)
        or (action == "Land" and sample.landed)
    )


@dataclass(frozen=True)
class LocalSample:
    """A sample of this drone's vehicle, stamped (monotonic) when the adapter handed it over."""

    sample: Telemetry
    received_s: float = field(default_factory=time.monotonic)


@dataclass(frozen=True)
class WhenLanded:
    """Set ``event`` once the vehicle reports it is on the ground (at once if it is)."""

    event: threading.Event


@dataclass(frozen=True)
class WhenSettled:
    """Set ``event`` once a sample taken after the last action shows the vehicle not
    standing armed on the ground (disarmed, or in the air).

    After a landing, autopilots (and the simulated drone) disarm by themselves a
    moment later; the drone's report waits for that to tell the state it is left in.
    ``after_s`` and ``action`` say which samples are new enough, as for :class:`FinalSample`
    (a sample from before the landing would still show the vehicle in the air).
    """

    event: threading.Event
    after_s: float | None = None
    action: str | None = None


@dataclass(frozen=True)
class FinalSample:
    """Answer ``reply`` with the vehicle's state once its last action ended.

    ``after_s`` is when (monotonic) the last action that could change the
    reported state (``action``) was recorded; the answer is the latest sample
    if it shows that action's effect (:func:`shows_effect`), else the first
    sample handed over after ``after_s``, or, if the adapter sends none within
    ``wait_s`` (its state did not change: adapters send samples when it
    does), the latest one.  None before any sample.
    """

    after_s: float | None
    wait_s: float
    reply: Future[Telemetry | None]
    action: str | None = None


def ask_final_sample(
    board: Mailbox[FinalSample] | None,
    after_s: float | None,
    action: str | None,
    wait_s: float,
    timeout_s: float,
) -> Telemetry | None:
    """The board's answer to a :class:`FinalSample` (None without a board or an answer)."""
    if board is None:
        return None
    reply: Future[Telemetry | None] = Future()
    try:
        board.tell(FinalSample(after_s, wait_s, reply, action))
        return reply.result(timeout=wait_s + timeout_s)
    except (pykka.ActorDeadError, FutureTimeout):
        return None


@dataclass(frozen=True)
class _FinalDeadline:
    """The time a final sample may wait for a fresher frame is up."""

    request: FinalSample


class LatestSample:
    """The drone's own latest sample, as the adapter hands it over (set on its thread).

    A value read from other threads, not an actor: where the vehicle is when an action
    begins, for the node's journal and a restarted node's rest of an action, without a
    message round trip on the action's path.
    """

    def __init__(self) -> None:
        self._sample: Telemetry | None = None
        self._lock = threading.Lock()

    def put(self, sample: Telemetry) -> None:
        with self._lock:
            self._sample = sample

    def position(self) -> tuple[float, float, float] | None:
        """(x, y, z) of the latest sample (None: none yet)."""
        with self._lock:
            s = self._sample
        return None if s is None else (s.x_m, s.y_m, s.z_m)


class TelemetryBoard(RuntimePart):
    """Latest property values per drone; pushes changes to the nodes watching them."""

    part = "telemetry board"

    def __init__(
        self,
        dispatcher: Dispatcher,
        drone: str,
        out_bridge: Mailbox[wire.TelemetrySample] | None,
        mission_id: str,
        failure: FailureSink | None = None,
    ) -> None:
        super().__init__(dispatcher)
        self.drone = drone
        self.out_bridge = out_bridge
        self.mission_id = mission_id
        self.failure = failure
        self.latest: dict[str, PropertyValues] = {}
        self.local: Telemetry | None = None
        self.local_received_s = float("-inf")
        self.watchers: dict[Mailbox[TelemetryChanged], tuple[str, ...]] = {}
        self.landed_waiters: list[threading.Event] = []
        self.settled_waiters: list[WhenSettled] = []
        self.final_waiters: list[FinalSample] = []
        self._timers: list[threading.Timer] = []

    def on_receive(self, message: object) -> None:
        if isinstance(message, LocalSample):
            self._local(message.sample, message.received_s)
        elif isinstance(message, RemoteTelemetry):
            self._update(message.drone, message.values)
        elif isinstance(message, Watch):
            self.watchers[message.watcher] = message.drones
            for drone in message.drones:
                if drone in self.latest:
                    message.watcher.tell(TelemetryChanged(drone, self.latest[drone]))
        elif isinstance(message, Unwatch):
            self.watchers.pop(message.watcher, None)
        elif isinstance(message, WhenLanded):
            if self.local is None or self.local.landed:
                message.event.set()
            else:
                self.landed_waiters.append(message.event)
        elif isinstance(message, WhenSettled):
            if self.local is None or self._settled(message):
                message.event.set()
            else:
                self.settled_waiters.append(message)
        elif isinstance(message, FinalSample):
            self._final(message)
        elif isinstance(message, _FinalDeadline):
            self._answer(message.request)

    def on_stop(self) -> None:
        for timer in self._timers:
            timer.cancel()
        for request in self.final_waiters:
            self._answer(request)

    def _local(self, sample: Telemetry, received_s: float) -> None:
        self.local = sample
        self.local_received_s = received_s
        self._update(self.drone, telemetry_values(sample))
        if self.out_bridge is not None:
            self.out_bridge.tell(wire_sample(sample, self.mission_id, self.drone))
        if sample.landed:
            for event in self.landed_waiters:
                event.set()
            self.landed_waiters.clear()
        for waiter in [w for w in self.settled_waiters if self._settled(w)]:
            waiter.event.set()
            self.settled_waiters.remove(waiter)
        for request in [r for r in self.final_waiters if self._fresh(r)]:
            self._answer(request)

    def _settled(self, request: WhenSettled) -> bool:
        local = self.local
        return local is not None and self._fresh(request) and not (local.landed and local.armed)

    def _fresh(self, request: FinalSample | WhenSettled) -> bool:
        return (
            request.after_s is None
            or self.local_received_s > request.after_s
            or (self.local is not None and shows_effect(request.action, self.local))
        )

    def _final(self, request: FinalSample) -> None:
        if self.local is None or self._fresh(request) or request.wait_s <= 0:
            self._answer(request)
            return
        self.final_waiters.append(request)
        # The deadline comes back as a message: the answer is given on the actor's
        # worker, in order with the samples.
        timer = threading.Timer(request.wait_s, self._deadline, (request,))
        timer.daemon = True
        self._timers.append(timer)
        timer.start()

    def _deadline(self, request: FinalSample) -> None:
        try:
            self.actor_ref.tell(_FinalDeadline(request))
        except pykka.ActorDeadError:
            pass  # stopped meanwhile: on_stop answered

    def _answer(self, request: FinalSample) -> None:
        if request in self.final_waiters:
            self.final_waiters.remove(request)
        if not request.reply.done():
            request.reply.set_result(self.local)

    def _update(self, drone: str, values: PropertyValues) -> None:
        old = self.latest.get(drone)
        self.latest[drone] = values
        if old is not None and all(
            old.get(k) == v for k, v in values.items() if not k.startswith("_")
        ):
            return  # nothing a condition reads changed
        for watcher, drones in list(self.watchers.items()):
            if drone in drones:
                watcher.tell(TelemetryChanged(drone, values))
