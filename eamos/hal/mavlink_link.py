"""One MAVLink connection to one vehicle: transport, reader thread, periodic sender.

:class:`MavlinkLink` owns a pymavlink connection.  Its reader thread is the
only one that receives: it blocks on the socket (``select`` with a short
timeout, the socket read itself) and folds every message from the target
vehicle into a :class:`LinkState` under :attr:`MavlinkLink.cond`, notifying
all waiters.  Everything that waits for the vehicle does so with
``cond.wait_for(predicate, timeout)`` against a ``time.monotonic()``
deadline; nothing polls.

Sends from any thread go through one lock.  A ticker thread runs periodic
jobs (the 1 Hz GCS heartbeat, and whatever the adapter registers with
:meth:`MavlinkLink.every`, e.g. PX4's setpoint stream) paced by
``Event.wait`` on the stop event.

Heartbeat loss is tracked here: when no HEARTBEAT came for more than
``heartbeat_timeout_s`` the state's ``link_ok`` turns False (and waiters
wake); the next HEARTBEAT turns it True again.  A TCP connection the vehicle
closes is re-dialled every half second.
"""

from __future__ import annotations

import math
import os
import re
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

#: MAVLink ids used by the link (numbers rather than pymavlink attributes keep
#: this module importable without touching pymavlink's dialect machinery).
MAV_TYPE_GCS = 6
MAV_AUTOPILOT_INVALID = 8
MAV_STATE_ACTIVE = 4
MAV_MODE_FLAG_SAFETY_ARMED = 128
MAV_RESULT_ACCEPTED = 0
MAV_RESULT_TEMPORARILY_REJECTED = 1
MAV_RESULT_IN_PROGRESS = 5
MAV_SYS_STATUS_PREARM_CHECK = 0x10000000

MAV_RESULT_NAMES = {
    0: "MAV_RESULT_ACCEPTED",
    1: "MAV_RESULT_TEMPORARILY_REJECTED",
    2: "MAV_RESULT_DENIED",
    3: "MAV_RESULT_UNSUPPORTED",
    4: "MAV_RESULT_FAILED",
    5: "MAV_RESULT_IN_PROGRESS",
    6: "MAV_RESULT_CANCELLED",
    7: "MAV_RESULT_COMMAND_LONG_ONLY",
    8: "MAV_RESULT_COMMAND_INT_ONLY",
    9: "MAV_RESULT_COMMAND_UNSUPPORTED_MAV_FRAME",
}

#: Silence on the link (any message) that counts as a gap when it ends.
GAP_S = 1.0
#: The reader's socket wait: bounds how late heartbeat loss is noticed.
READ_WAIT_S = 0.1
#: Pause between TCP re-dials / after a transport error.
REDIAL_S = 0.5
#: STATUSTEXT payload size: a chunk this long is continued by the next one.
STATUSTEXT_CHUNK = 50


class LinkError(Exception):
    """The transport cannot be opened (bad address, port taken, serial missing).

    ``unreachable`` is True when the peer simply never answered (a TCP vehicle
    that refused every dial until the deadline), as opposed to a local problem.
    """

    def __init__(self, message: str, unreachable: bool = False) -> None:
        super().__init__(message)
        self.unreachable = unreachable


def result_name(result: int | None) -> str:
    """``"MAV_RESULT_DENIED"`` for 2, etc.; ``"no COMMAND_ACK"`` for None."""
    if result is None:
        return "no COMMAND_ACK"
    return MAV_RESULT_NAMES.get(result, f"MAV_RESULT({result})")


def load_mavutil() -> ModuleType:
    """pymavlink's ``mavutil``, set up for MAVLink 2.

    pymavlink picks its wire protocol from the ``MAVLINK20`` environment
    variable when it loads a dialect; PX4 and ArduPilot both speak MAVLink 2,
    so it is set before the first import (and the dialect reloaded if another
    module imported pymavlink for MAVLink 1 first).
    """
    os.environ.setdefault("MAVLINK20", "1")
    from pymavlink import mavutil

    if mavutil.mavlink.WIRE_PROTOCOL_VERSION != "2.0":
        mavutil.set_dialect(mavutil.current_dialect)
    return mavutil


_NET = re.compile(r"^(udpin|udpout|udp|tcp|tcpin):([^:]+):(\d+)$")


def check_connection(text: str) -> str:
    """Why ``text`` is not a usable connection string, or ``""`` when it is.

    Accepted: ``udpin:HOST:PORT``, ``udpout:HOST:PORT``, ``udp:HOST:PORT``,
    ``tcp:HOST:PORT``, ``tcpin:HOST:PORT``, and a serial device
    ``/dev/ttyACM0`` or ``/dev/ttyAMA0,921600`` (``COM3,57600`` on Windows).
    """
    m = _NET.match(text)
    if m:
        port = int(m.group(3))
        return "" if 0 < port < 65536 else f"port {port} is out of range 1..65535"
    device, _, baud = text.partition(",")
    if device.startswith("/dev/") or re.fullmatch(r"COM\d+", device):
        if baud and not (baud.isdigit() and int(baud) > 0):
            return f"baud rate {baud!r} is not a positive integer"
        return ""
    return (
        "expected udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT "
        "or a serial device such as /dev/ttyACM0,921600"
    )


def open_transport(
    mavutil: ModuleType, connection: str, source_system: int, source_component: int
) -> Any:
    """Open a pymavlink connection once (no retries, no sleeps); OSError if it fails."""
    if connection.startswith("tcp:"):
        return _tcp_client(mavutil, connection[4:], source_system, source_component)
    device, _, baud = connection.partition(",")
    if not _NET.match(connection):
        return mavutil.mavlink_connection(
            device,
            baud=int(baud or 57600),
            source_system=source_system,
            source_component=source_component,
            autoreconnect=False,
        )
    return mavutil.mavlink_connection(
        connection, source_system=source_system, source_component=source_component
    )


def _tcp_client(
    mavutil: ModuleType, address: str, source_system: int, source_component: int
) -> Any:
    """pymavlink's TCP client, minus its prints, sleeps and silent reconnects.

    The link's reader re-dials itself (paced by its stop event), so a closed
    connection must surface as an exception instead of a busy loop.
    """

    class TcpClient(mavutil.mavtcp):  # type: ignore[name-defined,misc]
        port: Any  # the socket, None while disconnected
        fd: int

        def handle_disconnect(self) -> None:
            self.drop()

        def handle_eof(self) -> None:
            self.drop()
            raise ConnectionError("the vehicle closed the TCP connection")

        def reconnect(self) -> None:
            """Disabled: :class:`MavlinkLink` re-dials (see :meth:`redial`)."""

        def recv(self, n: int | None = None) -> Any:
            if self.port is None:
                raise ConnectionError("TCP connection closed")
            return super().recv(n)

        def drop(self) -> None:
            if self.port is not None:
                self.port.close()
                self.port = None

        def close(self) -> None:
            self.drop()

        def redial(self) -> None:
            self.retries = 0
            self.do_connect()
            self.fd = self.port.fileno()

    return TcpClient(
        address, source_system=source_system, source_component=source_component, retries=0
    )


@dataclass
class GlobalPosition:
    """GLOBAL_POSITION_INT in SI units."""

    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    rel_alt_m: float
    vn_mps: float
    ve_mps: float
    vd_mps: float


@dataclass
class LinkState:
    """What the reader knows about the vehicle; read and written under ``MavlinkLink.cond``."""

    system_id: int | None = None
    component_id: int = 1
    autopilot: int | None = None
    vehicle_type: int | None = None
    base_mode: int = 0
    custom_mode: int = 0
    armed: bool = False
    heartbeats: int = 0
    last_heartbeat: float = -math.inf  # time.monotonic()
    link_ok: bool = False  # heartbeats arrive (none missing for > heartbeat_timeout_s)
    link_losses: int = 0
    last_rx: float = -math.inf
    gap_ended_at: float = -math.inf  # first message after a silence of GAP_S or more
    failsafe_at: float = -math.inf  # last STATUSTEXT mentioning a failsafe
    local: tuple[float, float, float, float, float, float] | None = None  # NED x y z vx vy vz
    local_count: int = 0
    global_pos: GlobalPosition | None = None
    home: tuple[float, float, float] | None = None  # HOME_POSITION lat, lon, alt AMSL
    sensors_present: int | None = None
    sensors_health: int | None = None
    battery_pct: float | None = None
    landed_state: int | None = None  # EXTENDED_SYS_STATE (MAV_LANDED_STATE)
    acks: dict[int, tuple[int, int]] = field(default_factory=dict)  # command -> (result, serial)
    ack_serial: int = 0
    statustexts: deque[str] = field(default_factory=lambda: deque(maxlen=20))
    statustext_serial: int = 0
    closed: bool = False

    @property
    def last_statustext(self) -> str:
        """The latest STATUSTEXT (reassembled), or ``""``."""
        return self.statustexts[-1] if self.statustexts else ""

    def ack_since(self, command: int, serial: int) -> int | None:
        """The result of the latest COMMAND_ACK for ``command`` newer than ``serial``."""
        entry = self.acks.get(command)
        return entry[0] if entry is not None and entry[1] > serial else None


EventCallback = Callable[[str, dict[str, Any]], None]
#: Events collected under the condition, reported after releasing it.
Events = list[tuple[str, dict[str, Any]]]


@dataclass
class _Periodic:
    period_s: float
    job: Callable[[], None]
    name: str
    due: float = 0.0


class MavlinkLink:
    """A pymavlink connection with its reader and ticker threads (see module docstring)."""

    def __init__(
        self,
        connection: str,
        *,
        source_system: int,
        source_component: int,
        system_id: int | None,
        component_id: int,
        heartbeat_timeout_s: float,
        on_event: EventCallback | None = None,
    ) -> None:
        self.connection = connection
        self.source_system = source_system
        self.source_component = source_component
        self.component_id = component_id
        self.heartbeat_timeout_s = heartbeat_timeout_s
        # An RLock: predicates evaluated inside wait_for may read helper
        # methods that take the condition again.
        self.cond = threading.Condition(threading.RLock())
        self.state = LinkState(system_id=system_id, component_id=component_id)
        self._on_event = on_event or (lambda name, fields: None)
        self._send_lock = threading.Lock()
        self._stop = threading.Event()
        self._conn: Any = None
        self._mavutil: ModuleType | None = None
        self._threads: list[threading.Thread] = []
        self._jobs: list[_Periodic] = []
        self._chunks: dict[int, list[str]] = {}  # reader thread only: STATUSTEXT parts by id
        self._boot = time.monotonic()
        self._transport_down = False

    # -- opening and closing -------------------------------------------------

    def every(self, period_s: float, job: Callable[[], None], name: str) -> None:
        """Run ``job`` every ``period_s`` on the ticker thread (register before :meth:`open`)."""
        self._jobs.append(_Periodic(period_s, job, name))

    def open(self, deadline: float) -> None:
        """Open the transport and start the threads.

        A TCP vehicle that is not listening yet is dialled again every
        :data:`REDIAL_S` until ``deadline`` (then :class:`LinkError`); other
        transports fail at once with :class:`LinkError`.
        """
        self._mavutil = load_mavutil()
        while True:
            try:
                self._conn = open_transport(
                    self._mavutil, self.connection, self.source_system, self.source_component
                )
                break
            except (OSError, ValueError) as exc:
                if not self.connection.startswith("tcp:"):
                    raise LinkError(f"cannot open {self.connection}: {exc}") from exc
                if time.monotonic() >= deadline:
                    raise LinkError(f"TCP: {exc}", unreachable=True) from exc
                # Wait before re-dialling; the stop event ends the wait on close().
                if self._stop.wait(min(REDIAL_S, max(0.0, deadline - time.monotonic()))):
                    raise LinkError(f"{self.connection}: closed while connecting") from exc
        self.every(1.0, self._send_gcs_heartbeat, "gcs-heartbeat")
        for target, name in ((self._read_loop, "reader"), (self._tick_loop, "ticker")):
            thread = threading.Thread(target=target, name=f"mavlink-{name}", daemon=True)
            self._threads.append(thread)
            thread.start()

    def close(self) -> None:
        """Stop the threads, close the transport, wake every waiter. Idempotent."""
        self._stop.set()
        for thread in self._threads:
            if thread is not threading.current_thread():
                thread.join(timeout=5.0)
        with self.cond:
            self.state.closed = True
            self.cond.notify_all()
        conn, self._conn = self._conn, None
        if conn is not None:
            try:
                conn.close()
            except OSError:
                pass

    # -- waiting ---------------------------------------------------------------

    def wait_for(self, predicate: Callable[[], bool], deadline: float) -> bool:
        """Wait (on the condition) until ``predicate()`` holds or ``deadline`` passes."""
        with self.cond:
            return self.cond.wait_for(predicate, timeout=max(0.0, deadline - time.monotonic()))

    @property
    def target(self) -> tuple[int, int]:
        """(system id, component id) to address commands to."""
        with self.cond:
            return (self.state.system_id or 0, self.component_id)

    def time_boot_ms(self) -> int:
        """Milliseconds since this link was made (for time_boot_ms fields)."""
        return int((time.monotonic() - self._boot) * 1000) & 0xFFFFFFFF

    # -- sending ---------------------------------------------------------------

    def send(self, message: str, *args: Any) -> None:
        """Send one message, e.g. ``send("heartbeat", ...)`` (pymavlink's ``heartbeat_send``)."""
        conn = self._conn
        if conn is None:
            return
        with self._send_lock:
            try:
                getattr(conn.mav, f"{message}_send")(*args)
            except OSError as exc:
                # A serial device that vanished; the reader reports transport errors.
                self._on_event("link.send_error", {"message": message, "error": repr(exc)})

    def command_long(
        self,
        command: int,
        params: tuple[float, ...],
        *,
        timeout_s: float,
        retries: int,
        abandon: Callable[[], bool] = lambda: False,
    ) -> int | None:
        """Send COMMAND_LONG and return the MAV_RESULT of its COMMAND_ACK.

        Tries ``retries`` times, waiting ``timeout_s`` for an ack each time
        (``confirmation`` counts the tries, as the protocol asks).  Returns
        None when no ack came, or early when ``abandon()`` (evaluated under
        the condition) turns true.  MAV_RESULT_IN_PROGRESS extends the wait.
        """
        if len(params) != 7:
            raise ValueError("COMMAND_LONG takes 7 params")
        for attempt in range(retries):
            with self.cond:
                seen = self.state.ack_serial
            system, component = self.target
            self.send("command_long", system, component, command, attempt, *params)
            deadline = time.monotonic() + timeout_s
            while True:
                with self.cond:

                    def answered(seen: int = seen) -> bool:
                        return (
                            abandon()
                            or self.state.closed
                            or self.state.ack_since(command, seen) is not None
                        )

                    self.cond.wait_for(answered, timeout=max(0.0, deadline - time.monotonic()))
                    result = self.state.ack_since(command, seen)
                    if result is None:
                        if abandon() or self.state.closed:
                            return None
                        break  # no ack: try again
                    if result != MAV_RESULT_IN_PROGRESS:
                        return result
                    seen = self.state.ack_serial
                    deadline = time.monotonic() + timeout_s
        return None

    def _send_gcs_heartbeat(self) -> None:
        # Announces us as a ground station: autopilots track GCS presence by it.
        self.send("heartbeat", MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID, 0, 0, MAV_STATE_ACTIVE)

    # -- threads ---------------------------------------------------------------

    def _tick_loop(self) -> None:
        now = time.monotonic()
        for job in self._jobs:
            job.due = now
        while not self._stop.is_set():
            now = time.monotonic()
            for job in self._jobs:
                if now >= job.due:
                    try:
                        job.job()
                    except Exception as exc:  # a periodic job must not end the others
                        self._on_event("link.job_error", {"job": job.name, "error": repr(exc)})
                    # Keep the cadence; after a stall, restart from now instead of bursting.
                    job.due = max(job.due + job.period_s, now)
            wait = min(job.due for job in self._jobs) - time.monotonic()
            # The pacing wait of the periodic streams; close() ends it at once.
            if self._stop.wait(max(0.0, wait)):
                return

    def _read_loop(self) -> None:
        while not self._stop.is_set():
            conn = self._conn
            if conn is None:
                return
            try:
                if getattr(conn, "port", True) is None:
                    conn.redial()  # a TCP connection the vehicle closed
                    self._transport_down = False
                    self._on_event("link.transport_restored", {"connection": self.connection})
                msg = conn.recv_msg()
                if msg is None:
                    # The only blocking read: wait for the socket, briefly, so
                    # heartbeat loss is noticed even when nothing arrives.
                    conn.select(READ_WAIT_S)
            except (OSError, ValueError) as exc:
                self._transport_error(exc)
                continue
            now = time.monotonic()
            events: Events = []
            with self.cond:
                if msg is not None and msg.get_type() != "BAD_DATA":
                    self._handle(msg, now, events)
                self._check_heartbeat(now, events)
            for name, fields in events:
                self._on_event(name, fields)

    def _transport_error(self, exc: BaseException) -> None:
        if not self._transport_down:
            self._transport_down = True
            self._on_event(
                "link.transport_error", {"connection": self.connection, "error": repr(exc)}
            )
        now = time.monotonic()
        events: Events = []
        with self.cond:
            self._check_heartbeat(now, events)
        for name, fields in events:
            self._on_event(name, fields)
        self._stop.wait(REDIAL_S)

    def _check_heartbeat(self, now: float, events: Events) -> None:
        st = self.state
        if st.link_ok and now - st.last_heartbeat > self.heartbeat_timeout_s:
            st.link_ok = False
            st.link_losses += 1
            events.append(
                (
                    "link.lost",
                    {
                        "silent_s": round(now - st.last_heartbeat, 3),
                        "heartbeat_timeout_s": self.heartbeat_timeout_s,
                    },
                )
            )
            self.cond.notify_all()

    # -- message handling (reader thread, condition held) -----------------------

    def _handle(self, msg: Any, now: float, events: Events) -> None:
        st = self.state
        kind = msg.get_type()
        src, comp = msg.get_srcSystem(), msg.get_srcComponent()
        if kind == "HEARTBEAT":
            if not self._is_vehicle_heartbeat(msg, src, comp):
                return
        elif st.system_id is None or src != st.system_id:
            return  # another system on a shared port, or before we know the vehicle
        if now - st.last_rx >= GAP_S and st.last_rx > -math.inf:
            st.gap_ended_at = now
            events.append(("link.gap", {"silent_s": round(now - st.last_rx, 3)}))
        st.last_rx = now
        handler = getattr(self, f"_on_{kind.lower()}", None)
        if handler is not None:
            handler(msg, now, events)
            self.cond.notify_all()

    def _is_vehicle_heartbeat(self, msg: Any, src: int, comp: int) -> bool:
        st = self.state
        if comp != self.component_id and not (self.component_id == 0 and comp == 1):
            return False
        if st.system_id is None:
            # Lock onto the first autopilot heard; ignore ground stations and
            # other companions sharing the port.
            if msg.autopilot == MAV_AUTOPILOT_INVALID or msg.type == MAV_TYPE_GCS:
                return False
            st.system_id = src
            return True
        return src == st.system_id

    def _on_heartbeat(self, msg: Any, now: float, events: Events) -> None:
        st = self.state
        armed = bool(msg.base_mode & MAV_MODE_FLAG_SAFETY_ARMED)
        if st.heartbeats == 0:
            events.append(
                (
                    "link.vehicle",
                    {"system_id": st.system_id, "autopilot": msg.autopilot, "type": msg.type},
                )
            )
        else:
            if msg.custom_mode != st.custom_mode:
                events.append(
                    ("vehicle.mode", {"custom_mode": msg.custom_mode, "previous": st.custom_mode})
                )
            if armed != st.armed:
                events.append(("vehicle.armed", {"armed": armed}))
        if not st.link_ok:
            if st.heartbeats:
                events.append(("link.restored", {"silent_s": round(now - st.last_heartbeat, 3)}))
            st.link_ok = True
        st.autopilot, st.vehicle_type = msg.autopilot, msg.type
        st.base_mode, st.custom_mode, st.armed = msg.base_mode, msg.custom_mode, armed
        st.heartbeats += 1
        st.last_heartbeat = now

    def _on_command_ack(self, msg: Any, now: float, events: Events) -> None:
        target = getattr(msg, "target_system", 0)
        if target not in (0, self.source_system):
            return  # an ack meant for another ground station
        st = self.state
        st.ack_serial += 1
        st.acks[msg.command] = (msg.result, st.ack_serial)
        events.append(("vehicle.ack", {"command": msg.command, "result": result_name(msg.result)}))

    def _on_local_position_ned(self, msg: Any, now: float, events: Events) -> None:
        self.state.local = (msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz)
        self.state.local_count += 1

    def _on_global_position_int(self, msg: Any, now: float, events: Events) -> None:
        self.state.global_pos = GlobalPosition(
            msg.lat / 1e7,
            msg.lon / 1e7,
            msg.alt / 1000.0,
            msg.relative_alt / 1000.0,
            msg.vx / 100.0,
            msg.vy / 100.0,
            msg.vz / 100.0,
        )

    def _on_home_position(self, msg: Any, now: float, events: Events) -> None:
        self.state.home = (msg.latitude / 1e7, msg.longitude / 1e7, msg.altitude / 1000.0)

    def _on_sys_status(self, msg: Any, now: float, events: Events) -> None:
        st = self.state
        st.sensors_present = msg.onboard_control_sensors_present
        st.sensors_health = msg.onboard_control_sensors_health
        if msg.battery_remaining >= 0:
            st.battery_pct = float(msg.battery_remaining)

    def _on_battery_status(self, msg: Any, now: float, events: Events) -> None:
        if msg.battery_remaining >= 0:
            self.state.battery_pct = float(msg.battery_remaining)

    def _on_extended_sys_state(self, msg: Any, now: float, events: Events) -> None:
        self.state.landed_state = msg.landed_state

    def _on_statustext(self, msg: Any, now: float, events: Events) -> None:
        text = msg.text.decode("utf-8", "replace") if isinstance(msg.text, bytes) else msg.text
        text = text.rstrip("\x00")
        chunk_id = getattr(msg, "id", 0)
        if chunk_id:
            # MAVLink 2 splits long texts into chunks sharing an id (PX4 does).
            parts = self._chunks.setdefault(chunk_id, [])
            parts.append(text)
            if len(text) >= STATUSTEXT_CHUNK and len(parts) < 8:
                return
            text = "".join(self._chunks.pop(chunk_id))
        st = self.state
        st.statustexts.append(text)
        st.statustext_serial += 1
        if "failsafe" in text.lower():
            st.failsafe_at = now
        events.append(("vehicle.statustext", {"severity": msg.severity, "text": text}))


__all__ = [
    "MAV_RESULT_ACCEPTED",
    "MAV_RESULT_NAMES",
    "MAV_RESULT_TEMPORARILY_REJECTED",
    "MAV_SYS_STATUS_PREARM_CHECK",
    "GlobalPosition",
    "LinkError",
    "LinkState",
    "MavlinkLink",
    "check_connection",
    "load_mavutil",
    "open_transport",
    "result_name",
]
