"""One MAVLink connection to one vehicle: transport, reader thread, sends.

:class:`MavlinkLink` owns a pymavlink connection.  Its reader thread is the
only one that receives: it blocks on the socket (``select`` with a short
timeout, the socket read itself) and folds every message from the target
vehicle into a :class:`LinkState` under :attr:`MavlinkLink.cond`, notifying
all waiters.  Everything that waits for the vehicle does so with
``cond.wait_for(predicate, timeout)`` against a ``time.monotonic()``
deadline; nothing polls.

Sends from any thread go through one lock.  A ticker thread
(:class:`~eamos.hal.mavlink.ticker.Ticker`) runs periodic jobs (the 1 Hz GCS
heartbeat, and whatever the adapter registers with :meth:`MavlinkLink.every`,
e.g. PX4's setpoint stream) paced by ``Event.wait`` on the stop event.  The
exchanges on top of the link are their own modules: the command protocol
(:mod:`~eamos.hal.mavlink.command_protocol`), the parameter protocol
(:mod:`~eamos.hal.mavlink.param_protocol`); so is signing
(:class:`~eamos.hal.mavlink.signing.LinkSigning`).

Heartbeat loss is tracked here: when no HEARTBEAT came for more than
``heartbeat_timeout_s`` the state's ``link_ok`` turns False (and waiters
wake); the next HEARTBEAT turns it True again.  A TCP connection the vehicle
closes is re-dialled every half second.  How each message changes the state
is :class:`~eamos.hal.mavlink.state.StateTracker`'s business.
"""

from __future__ import annotations

import os
import re
import threading
import time
from collections.abc import Callable
from types import ModuleType
from typing import Any

from eamos.hal.mavlink.signing import LinkSigning, refused_frame
from eamos.hal.mavlink.state import (
    MAV_AUTOPILOT_INVALID,
    MAV_RESULT_NAMES,
    MAV_TYPE_GCS,
    Events,
    GlobalPosition,
    LinkState,
    StateTracker,
    result_name,
)
from eamos.hal.mavlink.ticker import EventCallback, Ticker

#: MAVLink ids used by the link (numbers rather than pymavlink attributes keep
#: this module importable without touching pymavlink's dialect machinery).
MAV_STATE_ACTIVE = 4
MAV_SYS_STATUS_PREARM_CHECK = 0x10000000


#: The reader's socket wait: bounds how late heartbeat loss is noticed.
READ_WAIT_S = 0.1
#: Pause between TCP re-dials / after a transport error.
REDIAL_S = 0.5


class LinkError(Exception):
    """The transport cannot be opened (bad address, port taken, serial missing).

    ``unreachable`` is True when the peer simply never answered (a TCP vehicle
    that refused every dial until the deadline), as opposed to a local problem.
    """

    def __init__(self, message: str, unreachable: bool = False) -> None:
        super().__init__(message)
        self.unreachable = unreachable


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
        signing_key: bytes | None = None,
        signing_setup: bool = False,
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
        self._ticker = Ticker(self._stop, self._on_event)
        self._tracker = StateTracker(
            self.state,
            source_system=source_system,
            component_id=component_id,
            heartbeat_timeout_s=heartbeat_timeout_s,
            notify=self.cond.notify_all,
        )
        self._boot = time.monotonic()
        self._transport_down = False
        #: Called with the condition held after each message folded into the state, with
        #: the events it caused and the receive time; it may append events of its own
        #: (the vehicle's takeover watch: a mode change classified before any waiter
        #: wakes to it).
        self.observe: Callable[[Events, float], None] | None = None
        self.message_errors = 0  # messages the reader could not fold into the state
        self._signing = None if signing_key is None else LinkSigning(signing_key, signing_setup)
        self._signed_seen = False  # kept for the summary once the connection is closed

    # -- opening and closing -------------------------------------------------

    def every(self, period_s: float, job: Callable[[], None], name: str) -> None:
        """Run ``job`` every ``period_s`` on the ticker thread (register before :meth:`open`)."""
        self._ticker.every(period_s, job, name)

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
        if self._signing is not None:
            self._signing.install(self._conn)  # sign what we send, refuse what is unsigned
            self.every(1.0, self._signing_tick, "signing")
        for target, name in ((self._read_loop, "reader"), (self._ticker.run, "ticker")):
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
        _ = self.signed  # remembered for the summary, read after closing
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

    def _signing_tick(self) -> None:
        conn, signing = self._conn, self._signing
        if conn is None or signing is None:
            return
        with self._send_lock:
            pending = signing.refresh(conn.mav)
        if pending and self.state.system_id is not None:
            system, component = self.target
            self.send("setup_signing", system, component, *signing.setup_fields(time.time()))
            self._on_event("link.signing_setup", {"system_id": system})

    def _send_gcs_heartbeat(self) -> None:
        # Announces us as a ground station: autopilots track GCS presence by it.
        self.send("heartbeat", MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID, 0, 0, MAV_STATE_ACTIVE)

    # -- threads ---------------------------------------------------------------

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
            try:
                with self.cond:
                    if msg is not None and msg.get_type() != "BAD_DATA":
                        self._tracker.handle(msg, now, events)
                    elif msg is not None and self._signing is not None:
                        self._refused(msg, now, events)
                    self._tracker.check_heartbeat(now, events)
                    if events and self.observe is not None:
                        self.observe(events, now)
            # One message the tracker cannot fold in must not stop the reader: the
            # vehicle's state would freeze (heartbeats, position) for the whole flight.
            except Exception as exc:
                self.message_errors += 1
                if self.message_errors <= 20 or self.message_errors % 1000 == 0:
                    kind = msg.get_type() if msg is not None else ""
                    events.append(
                        (
                            "link.message_error",
                            {
                                "message": kind,
                                "error": repr(exc)[:300],
                                "errors": self.message_errors,
                            },
                        )
                    )
            for name, fields in events:
                self._on_event(name, fields)

    def _refused(self, msg: Any, now: float, events: Events) -> None:
        """A frame refused for its signature: who sent it (condition held)."""
        if getattr(msg, "reason", "") != "Invalid signature":
            return
        frame = refused_frame(bytes(getattr(msg, "data", b"")))
        if frame is not None:
            self._tracker.refused(frame, now, events)

    @property
    def signed(self) -> bool:
        """Whether this link signs and the vehicle's messages arrive signed with our key."""
        conn, signing = self._conn, self._signing
        if conn is None or signing is None:
            return self._signed_seen
        self._signed_seen = signing.signed(conn.mav) and not signing.provisioning(conn.mav)
        return self._signed_seen

    @property
    def signing(self) -> bool:
        """Whether this link has a signing key (it signs what it sends)."""
        return self._signing is not None

    def provisioning(self) -> bool:
        """Whether the vehicle still has to show it signs with our key (hal.signing_setup)."""
        conn, signing = self._conn, self._signing
        return conn is not None and signing is not None and signing.provisioning(conn.mav)

    def _transport_error(self, exc: BaseException) -> None:
        if not self._transport_down:
            self._transport_down = True
            self._on_event(
                "link.transport_error", {"connection": self.connection, "error": repr(exc)}
            )
        now = time.monotonic()
        events: Events = []
        with self.cond:
            self._tracker.check_heartbeat(now, events)
        for name, fields in events:
            self._on_event(name, fields)
        self._stop.wait(REDIAL_S)


__all__ = [
    "MAV_RESULT_NAMES",
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
