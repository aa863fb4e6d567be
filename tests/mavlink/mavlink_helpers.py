"""Helpers for the MAVLink tests (imported by name, like hal_helpers).

Every wait is on a condition or event with a generous timeout; nothing here
synchronizes by sleeping.
"""

from __future__ import annotations

import socket
import threading
import time
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from eamos.ground.vehicles import free_port
from eamos.hal.api import ActionHandle, ActionResult, Telemetry
from eamos.hal.mavlink.adapter import MavlinkAdapter
from eamos.hal.mavlink.link import load_mavutil, open_transport
from eamos.hal.sitl.vehicle import SimVehicle
from eamos.program.uniform import decode_command

#: Generous bound for one wait on a shared, small machine.
WAIT_S = 60.0


def connections(autopilot: str) -> tuple[str, str]:
    """(vehicle side, client side) connection strings on a free loopback port."""
    if autopilot == "px4":
        port = free_port(socket.SOCK_DGRAM)
        return f"udpout:127.0.0.1:{port}", f"udpin:127.0.0.1:{port}"
    port = free_port(socket.SOCK_STREAM)
    return f"tcpin:127.0.0.1:{port}", f"tcp:127.0.0.1:{port}"


class Done:
    """A done callback that can be waited on (and checks it is called once)."""

    def __init__(self) -> None:
        self._event = threading.Event()
        self.result: ActionResult | None = None
        self.calls = 0

    def __call__(self, result: ActionResult) -> None:
        self.calls += 1
        self.result = result
        self._event.set()

    def wait(self, timeout: float = WAIT_S) -> ActionResult:
        assert self._event.wait(timeout), f"action not done within {timeout} s"
        assert self.result is not None
        return self.result

    @property
    def is_done(self) -> bool:
        return self._event.is_set()


class Sink:
    """Collects telemetry samples; a test can wait for one that matches."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self.samples: list[Telemetry] = []

    def __call__(self, sample: Telemetry) -> None:
        with self._cond:
            self.samples.append(sample)
            self._cond.notify_all()

    def wait_for(
        self, predicate: Callable[[Telemetry], bool], timeout: float = WAIT_S
    ) -> Telemetry:
        with self._cond:
            assert self._cond.wait_for(lambda: any(predicate(s) for s in self.samples), timeout), (
                f"no matching sample in {len(self.samples)}"
            )
            return next(s for s in self.samples if predicate(s))

    def last(self) -> Telemetry:
        with self._cond:
            return self.samples[-1]


@dataclass
class Flight:
    """A simulated vehicle, a started adapter flying it, and the adapter's telemetry."""

    vehicle: SimVehicle
    adapter: MavlinkAdapter
    sink: Sink

    @classmethod
    def start(cls, vehicle: SimVehicle, adapter: MavlinkAdapter) -> Flight:
        sink = Sink()
        adapter.start(sink)
        return cls(vehicle, adapter, sink)

    def run(self, action: str, *args: float) -> tuple[ActionHandle, Done]:
        done = Done()
        handle = self.adapter.run(decode_command(action, args), done)
        return handle, done

    def do(self, action: str, *args: float, timeout: float = WAIT_S) -> ActionResult:
        return self.run(action, *args)[1].wait(timeout)

    def ok(self, action: str, *args: float, timeout: float = WAIT_S) -> None:
        result = self.do(action, *args, timeout=timeout)
        assert result.ok, f"{action}{args}: {result}"

    def airborne(self, height: float = 2.0) -> None:
        self.ok("Arm")
        self.ok("Takeoff", height)

    def wait_vehicle(
        self, predicate: Callable[[SimVehicle], bool], timeout: float = WAIT_S
    ) -> None:
        assert self.vehicle.wait_until(predicate, timeout), "vehicle condition not reached"


class RawClient:
    """A plain pymavlink client (our own code paths not involved) collecting messages."""

    def __init__(self, connection: str, sysid: int = 250) -> None:
        self.mavutil = load_mavutil()
        self.conn = open_transport(self.mavutil, connection, sysid, 190)
        self.sysid = sysid
        self._cond = threading.Condition()
        self.messages: dict[str, list[Any]] = defaultdict(list)
        self.times: dict[str, list[float]] = defaultdict(list)
        self._chunks: dict[int, list[str]] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while not self._stop.is_set():
            try:
                msg = self.conn.recv_msg()
            except OSError:
                msg = None
            if msg is None:
                try:
                    self.conn.select(0.05)
                except (OSError, ValueError):
                    self._stop.wait(0.05)
                continue
            with self._cond:
                self.messages[msg.get_type()].append(msg)
                self.times[msg.get_type()].append(time.monotonic())
                if msg.get_type() == "STATUSTEXT":
                    self._statustext(msg)
                self._cond.notify_all()

    def _statustext(self, msg: Any) -> None:
        """Reassembled texts go to ``messages["TEXT"]`` (MAVLink 2 chunks share an id)."""
        if not msg.id:
            self.messages["TEXT"].append(msg.text)
            return
        parts = self._chunks.setdefault(msg.id, [])
        parts.append(msg.text)
        if len(msg.text) < 50:
            self.messages["TEXT"].append("".join(self._chunks.pop(msg.id)))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self.conn.close()

    @property
    def mav(self) -> Any:
        return self.conn.mav

    def heartbeat(self) -> None:
        self.mav.heartbeat_send(6, 8, 0, 0, 4)

    def wait(
        self,
        kind: str,
        predicate: Callable[[Any], bool] = lambda m: True,
        timeout: float = WAIT_S,
        after: int = 0,
    ) -> Any:
        """The first ``kind`` message (index >= ``after``) matching ``predicate``."""
        with self._cond:

            def found() -> Any:
                return next((m for m in self.messages[kind][after:] if predicate(m)), None)

            assert self._cond.wait_for(lambda: found() is not None, timeout), f"no {kind}"
            return found()

    def count(self, kind: str) -> int:
        with self._cond:
            return len(self.messages[kind])

    def command(self, command: int, *params: float, target: int = 1, timeout: float = 10.0) -> int:
        """COMMAND_LONG and the result of its COMMAND_ACK."""
        seen = self.count("COMMAND_ACK")
        full = list(params) + [0.0] * (7 - len(params))
        self.mav.command_long_send(target, 1, command, 0, *full)
        ack = self.wait("COMMAND_ACK", lambda m: m.command == command, timeout, after=seen)
        return int(ack.result)

    def texts(self) -> list[str]:
        """Every STATUSTEXT so far, chunks reassembled."""
        with self._cond:
            return list(self.messages["TEXT"])
