"""``eamos-sim-vehicle``: a simulated quadcopter speaking MAVLink 2 like PX4 or ArduCopter SITL.

It stands in for a real autopilot in tests and CI, so the MAVLink adapter
(and any MAVLink client, e.g. MAVSDK) can fly without PX4 or ArduPilot
installed.  Its behaviour follows what was observed of the real SITL builds
(``/work/shared/notes/px4-sitl-behaviour.md`` and
``ardupilot-sitl-behaviour.md``):

* HEARTBEAT at 1 Hz from about 1 s after start: type quadrotor, autopilot
  PX4 (12) or ArduPilotMega (3), PX4 custom modes ``main << 16 | sub << 24``
  (boots in HOLD) or ArduCopter mode numbers (boots in STABILIZE; a mode set
  before "ArduPilot Ready" is overwritten).
* SYS_STATUS carries MAV_SYS_STATUS_PREARM_CHECK in its health bits only
  after the pre-arm delay (and, for PX4, not in OFFBOARD without a setpoint
  stream).  Arming before that is TEMPORARILY_REJECTED (PX4) or FAILED
  (ArduPilot) with an explaining STATUSTEXT.
* Every COMMAND_LONG/COMMAND_INT gets a COMMAND_ACK: ACCEPTED, rejected with
  the SITL's result codes, or UNSUPPORTED.  MAV_CMD_SET_MESSAGE_INTERVAL
  sets the rate (in simulated time) of LOCAL_POSITION_NED,
  GLOBAL_POSITION_INT, SYS_STATUS, EXTENDED_SYS_STATE, ATTITUDE,
  BATTERY_STATUS, HOME_POSITION and GPS_RAW_INT; MAV_CMD_REQUEST_MESSAGE
  sends one (AUTOPILOT_VERSION too); parameters answer PARAM_REQUEST_LIST,
  PARAM_REQUEST_READ and PARAM_SET (PX4 integers byte-wise in the float).
* PX4: OFFBOARD follows SET_POSITION_TARGET_LOCAL_NED/GLOBAL_INT and is
  refused in the air without a stream; a second without setpoints is a
  failsafe into HOLD, left by itself when setpoints resume.  AUTO.TAKEOFF
  (MAV_CMD_NAV_TAKEOFF, param7 AMSL or MIS_TAKEOFF_ALT) climbs, then HOLD.
  MAV_CMD_DO_REPOSITION flies to a WGS84 point in HOLD.  LOCAL_POSITION_NED
  z is offset on the ground (``ground_offset_m``), as PX4 SIH's is.
* ArduPilot: streams little until asked (SYS_STATUS only; REQUEST_DATA_STREAM
  and MAV_CMD_SET_MESSAGE_INTERVAL start the rest); GUIDED follows position
  targets once airborne;
  MAV_CMD_NAV_TAKEOFF (param7 metres above home) works only in GUIDED and
  armed, else FAILED.
* Both: MAV_CMD_NAV_LAND lands (mode AUTO.LAND / LAND) and the vehicle
  disarms 2 s after touchdown; armed on the ground without taking off for
  ``disarm_after_s`` (10 s) it disarms itself; disarming in the air needs
  the force flag.  STATUSTEXT narrates ("Armed by external command" /
  "Arming motors", "Disarming motors", "Arming denied: ...", "Failsafe
  activated ...").

It flies the same :class:`~eamos.hal.kinematics.Quadcopter` model as the
``sim`` adapter, stepped on its own simulated clock (paced by
``Event.wait``, ``speedup`` times real time).  One thread owns the
connection: each tick it drains incoming messages, steps the model and sends
what is due, so the vehicle needs no other locking than for the test hooks
(:meth:`SimVehicle.drop_link`, :meth:`SimVehicle.force_disarm`,
:meth:`SimVehicle.set_mode`) and observers (:meth:`SimVehicle.wait_until`).

Faults for tests: ``reject`` answers chosen commands with a chosen result;
``prearm_delay_s = inf`` never becomes armable; ``drop_link(s)`` drops
everything both ways for ``s`` wall seconds.
"""

from __future__ import annotations

import math
import struct
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any, Literal

from eamos.hal.autopilots import (
    ARDUCOPTER_MODES,
    MAV_AUTOPILOT_ARDUPILOTMEGA,
    MAV_AUTOPILOT_PX4,
    PX4_MODES,
    px4_custom_mode,
)
from eamos.hal.kinematics import GeoFrame, Limits, Quadcopter
from eamos.hal.mavlink_link import load_mavutil
from eamos.hal.sim import SIM_DT_S, paced_ticks
from eamos.logs import close_logger, make_logger

AutopilotName = Literal["px4", "ardupilot"]

# -- MAVLink numbers (kept local so the module reads without pymavlink open) --
MAV_TYPE_QUADROTOR = 2
MAV_STATE_STANDBY, MAV_STATE_ACTIVE = 3, 4
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1
MAV_MODE_FLAG_GUIDED_ENABLED = 8
MAV_MODE_FLAG_STABILIZE_ENABLED = 16
MAV_MODE_FLAG_SAFETY_ARMED = 128
ACCEPTED, TEMPORARILY_REJECTED, DENIED, UNSUPPORTED, FAILED = 0, 1, 2, 3, 4
RESULTS = {
    "ACCEPTED": ACCEPTED,
    "TEMPORARILY_REJECTED": TEMPORARILY_REJECTED,
    "DENIED": DENIED,
    "UNSUPPORTED": UNSUPPORTED,
    "FAILED": FAILED,
}
SEV_CRITICAL, SEV_WARNING, SEV_NOTICE, SEV_INFO = 2, 4, 5, 6
LANDED_ON_GROUND, LANDED_IN_AIR, LANDED_TAKEOFF, LANDED_LANDING = 1, 2, 3, 4
FORCE_MAGIC = 21196  # MAV_CMD_COMPONENT_ARM_DISARM param2: force (disarm in the air)

CMD_NAV_LAND, CMD_NAV_TAKEOFF = 21, 22
CMD_DO_SET_MODE, CMD_DO_REPOSITION = 176, 192
CMD_COMPONENT_ARM_DISARM = 400
CMD_GET_HOME_POSITION = 410
CMD_SET_MESSAGE_INTERVAL, CMD_REQUEST_MESSAGE = 511, 512
CMD_REQUEST_AUTOPILOT_CAPABILITIES = 520

MSG_HEARTBEAT, MSG_SYS_STATUS, MSG_GPS_RAW_INT, MSG_ATTITUDE = 0, 1, 24, 30
MSG_LOCAL_POSITION_NED, MSG_GLOBAL_POSITION_INT = 32, 33
MSG_BATTERY_STATUS, MSG_AUTOPILOT_VERSION = 147, 148
MSG_HOME_POSITION, MSG_EXTENDED_SYS_STATE = 242, 245
STREAMABLE = frozenset(
    {
        MSG_SYS_STATUS,
        MSG_GPS_RAW_INT,
        MSG_ATTITUDE,
        MSG_LOCAL_POSITION_NED,
        MSG_GLOBAL_POSITION_INT,
        MSG_BATTERY_STATUS,
        MSG_HOME_POSITION,
        MSG_EXTENDED_SYS_STATE,
    }
)
#: What each autopilot streams unasked (message id -> Hz, simulated time).
#: PX4's onboard link streams a lot by default; ArduPilot waits to be asked.
DEFAULT_RATES: dict[str, dict[int, float]] = {
    "px4": {
        MSG_SYS_STATUS: 1.0,
        MSG_EXTENDED_SYS_STATE: 1.0,
        MSG_LOCAL_POSITION_NED: 10.0,
        MSG_GLOBAL_POSITION_INT: 10.0,
        MSG_ATTITUDE: 10.0,
        MSG_HOME_POSITION: 0.5,
        MSG_GPS_RAW_INT: 1.0,
        MSG_BATTERY_STATUS: 0.5,
    },
    "ardupilot": {MSG_SYS_STATUS: 1.0},
}
#: ArduPilot's REQUEST_DATA_STREAM groups (MAV_DATA_STREAM) of the messages simulated here.
DATA_STREAMS: dict[int, tuple[int, ...]] = {
    2: (MSG_SYS_STATUS, MSG_GPS_RAW_INT),  # EXTENDED_STATUS
    6: (MSG_GLOBAL_POSITION_INT, MSG_LOCAL_POSITION_NED),  # POSITION
    10: (MSG_ATTITUDE,),  # EXTRA1
    12: (MSG_BATTERY_STATUS, MSG_EXTENDED_SYS_STATE, MSG_HOME_POSITION),  # EXTRA3
}

FRAME_GLOBAL, FRAME_LOCAL_NED, FRAME_GLOBAL_RELATIVE_ALT = 0, 1, 3
FRAME_GLOBAL_INT, FRAME_GLOBAL_RELATIVE_ALT_INT = 5, 6
#: SET_POSITION_TARGET type_mask bits meaning "ignore x, y, z".
IGNORE_POSITION = 0x7

PARAM_INT32, PARAM_REAL32 = 6, 9
#: MAV_SYS_STATUS sensors every simulated vehicle has and reports healthy.
SENSORS = (
    0x1
    | 0x2
    | 0x4
    | 0x8
    | 0x20  # gyro, accel, mag, baro, GPS
    | 0x400
    | 0x800
    | 0x1000
    | 0x2000
    | 0x4000
    | 0x8000  # rate, attitude, yaw, z, xy, motors
    | 0x200000
    | 0x2000000  # AHRS, battery
)
PREARM_CHECK = 0x10000000

#: Simulated seconds from start to the first HEARTBEAT (both SITLs take ~1 s).
BOOT_S = 1.0
#: ArduPilot: the initial mode replaces anything set before this (the notes: ~1.4 s).
ARDUPILOT_READY_S = 1.4
#: PX4 COM_OF_LOSS_T: simulated seconds without a setpoint before the failsafe...
OFFBOARD_LOSS_S = 1.0
#: ...and, so a host hiccup at a high speed-up is not a failsafe, wall seconds too.
OFFBOARD_LOSS_WALL_S = 0.5
#: Touchdown to automatic disarm (PX4 COM_DISARM_LAND; ArduPilot likewise ~2 s).
LAND_DISARM_S = 2.0
#: How often an unready vehicle repeats why it cannot arm (simulated seconds).
PREARM_TEXT_PERIOD_S = 10.0
#: Most messages handled per tick (a flood must not starve the simulation).
MAX_MESSAGES_PER_TICK = 200
#: STATUSTEXT payload length; longer texts go out in chunks sharing an id.
STATUSTEXT_LEN = 50


@dataclass(frozen=True)
class VehicleOptions:
    """How to build one :class:`SimVehicle` (the command line maps onto this)."""

    autopilot: AutopilotName
    connection: str
    sysid: int = 1
    speedup: float = 1.0
    prearm_delay_s: float = 3.0
    home: tuple[float, float, float] = (46.6103, 14.2640, 450.0)  # lat, lon, alt AMSL
    reject: Mapping[int, int] = field(default_factory=dict)  # MAV_CMD -> MAV_RESULT
    disarm_after_s: float = 10.0
    ground_offset_m: float | None = None  # PX4 LOCAL z on the ground; None: 1.5 PX4, 0 ArduPilot
    report_prearm: bool = True  # False: SYS_STATUS without the PREARM_CHECK bit (older firmware)
    limits: Limits = field(default_factory=Limits)
    log: Path | None = None

    def __post_init__(self) -> None:
        if self.autopilot not in ("px4", "ardupilot"):
            raise ValueError(f"autopilot must be px4 or ardupilot, got {self.autopilot!r}")
        if not self.connection.startswith(("udpout:", "udpin:", "tcpin:")):
            raise ValueError(
                f"connection must be udpout:, udpin: or tcpin:HOST:PORT, got {self.connection!r}"
            )
        if not 1 <= self.sysid <= 255:
            raise ValueError(f"sysid must be 1..255, got {self.sysid}")
        if not self.speedup > 0:
            raise ValueError("speedup must be > 0")
        if not self.prearm_delay_s >= 0 or not self.disarm_after_s > 0:
            raise ValueError("prearm delay must be >= 0 and disarm-after > 0")

    @property
    def offset_m(self) -> float:
        """LOCAL_POSITION_NED z of the ground (NED, down positive)."""
        if self.ground_offset_m is not None:
            return self.ground_offset_m
        return 1.5 if self.autopilot == "px4" else 0.0


def parse_reject(specs: Iterable[str]) -> dict[int, int]:
    """``["MAV_CMD_NAV_TAKEOFF", "400=FAILED"]`` -> {22: DENIED, 400: FAILED}.

    A command is a MAV_CMD name (with or without ``MAV_CMD_``) or number; the
    result (default DENIED) a MAV_RESULT name (with or without ``MAV_RESULT_``).
    """
    mavutil = load_mavutil()
    by_name = {entry.name: value for value, entry in mavutil.mavlink.enums["MAV_CMD"].items()}
    out: dict[int, int] = {}
    for spec in specs:
        cmd_text, _, result_text = spec.partition("=")
        cmd_text = cmd_text.strip().upper()
        if cmd_text.isdigit():
            command = int(cmd_text)
        else:
            name = cmd_text if cmd_text.startswith("MAV_CMD_") else f"MAV_CMD_{cmd_text}"
            if name not in by_name:
                raise ValueError(f"unknown MAVLink command {spec!r}")
            command = by_name[name]
        result_key = (result_text.strip().upper() or "DENIED").removeprefix("MAV_RESULT_")
        if result_key not in RESULTS or result_key == "ACCEPTED":
            raise ValueError(
                f"--reject {spec!r}: result must be one of "
                f"{', '.join(k for k in RESULTS if k != 'ACCEPTED')}"
            )
        out[command] = RESULTS[result_key]
    return out


def _tcp_server(mavutil: ModuleType, address: str, source_system: int) -> Any:
    """pymavlink's TCP listener, able to accept a new client after one leaves."""

    class TcpServer(mavutil.mavtcpin):  # type: ignore[name-defined,misc]
        port: Any  # the client's socket, None while nobody is connected
        fd: int

        def recv(self, n: int | None = None) -> bytes:
            if self.port is None:
                try:
                    self.port, _ = self.listen.accept()
                except OSError:
                    return b""
                self.port.setblocking(False)
                self.fd = self.port.fileno()
            try:
                data: bytes = self.port.recv(n or self.mav.bytes_needed())
            except BlockingIOError:
                return b""
            except OSError:
                data = b""
            if not data:
                # The client went away: accept the next one.
                self.port.close()
                self.port = None
                self.fd = self.listen.fileno()
            return data

    return TcpServer(address, source_system=source_system, source_component=1)


def _px4_float(value: float, ptype: int) -> float:
    """PX4 carries integer parameters byte-wise inside PARAM_VALUE's float."""
    if ptype == PARAM_INT32:
        return float(struct.unpack("<f", struct.pack("<i", int(value)))[0])
    return float(value)


def _px4_unfloat(raw: float, ptype: int) -> float:
    if ptype == PARAM_INT32:
        return float(struct.unpack("<i", struct.pack("<f", raw))[0])
    return float(raw)


class SimVehicle:
    """A simulated MAVLink quadcopter (see module docstring): ``start()``, ``stop()``."""

    def __init__(self, options: VehicleOptions) -> None:
        self.options = options
        o = options
        self.autopilot = o.autopilot
        self._px4 = o.autopilot == "px4"
        self._frame = GeoFrame(*o.home)
        self._model = Quadcopter(o.limits)
        # Reentrant, so wait_until predicates may read the public properties.
        self._lock = threading.RLock()
        self._cond = threading.Condition(self._lock)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._conn: Any = None
        self._log = make_logger(o.log, vehicle=f"{o.autopilot}-{o.sysid}")
        self._t = 0.0  # simulated seconds since start
        self._boot_wall = time.monotonic()
        self._armed = False
        self._armed_at = 0.0
        self._flew = False  # left the ground since arming
        self._touchdown_at: float | None = None
        self._was_landed = True
        self._mode = self._initial_mode()
        self._ready_announced = False  # ArduPilot "ArduPilot Ready"
        self._armable_announced = False
        self._next_prearm_text = BOOT_S
        self._next_heartbeat = BOOT_S
        self._last_sp_t = -math.inf  # PX4 setpoint stream: last setpoint (sim, wall)
        self._last_sp_wall = -math.inf
        self._offboard_target: tuple[float, float, float] | None = None  # model frame
        self._failsafe = False
        self._takeoff_z: float | None = None  # PX4 AUTO.TAKEOFF target height
        self._drop_until = -math.inf  # wall clock: link dropped until then
        self._rates: dict[int, float] = dict(DEFAULT_RATES[o.autopilot])
        self._due: dict[int, float] = {}
        self._text_id = 0
        self._gcs: tuple[int, int] | None = None  # last GCS heard (sysid, compid)
        self._params = self._initial_params()
        self._next_position_log = 0.0
        self._last_position_key: tuple[Any, ...] | None = None
        self.received: dict[str, int] = {}  # message type -> count (observers)
        self.commands: list[tuple[int, int]] = []  # (MAV_CMD, MAV_RESULT) answered

    # -- lifecycle ---------------------------------------------------------------

    def start(self) -> None:
        """Open the connection and start the simulation thread (OSError if the port is taken)."""
        mavutil = load_mavutil()
        o = self.options
        if o.connection.startswith("tcpin:"):
            self._conn = _tcp_server(mavutil, o.connection[6:], o.sysid)
        else:
            self._conn = mavutil.mavlink_connection(
                o.connection, source_system=o.sysid, source_component=1
            )
        self._boot_wall = time.monotonic()
        self._log.info(
            "vehicle.start",
            autopilot=o.autopilot,
            connection=o.connection,
            sysid=o.sysid,
            speedup=o.speedup,
            prearm_delay_s=o.prearm_delay_s,
            home=list(o.home),
            reject={str(k): v for k, v in o.reject.items()},
            disarm_after_s=o.disarm_after_s,
        )
        self._thread = threading.Thread(
            target=self._loop, name=f"sim-vehicle-{o.sysid}", daemon=True
        )
        self._thread.start()

    def stop(self) -> None:
        """Stop the simulation and close the connection. Idempotent."""
        self._stop.set()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=10)
        conn, self._conn = self._conn, None
        if conn is not None:
            try:
                conn.close()
            except OSError:
                pass
        with self._cond:
            self._cond.notify_all()
        if self._log is not None:
            self._log.info("vehicle.stop", t_sim=round(self._t, 3), received=dict(self.received))
            close_logger(self._log)

    def __enter__(self) -> SimVehicle:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- test hooks ----------------------------------------------------------------

    def drop_link(self, seconds: float) -> None:
        """Lose every message, both ways, for ``seconds`` of wall time (a radio dropout)."""
        with self._lock:
            self._drop_until = time.monotonic() + seconds
            self._log.info("vehicle.link.drop", seconds=seconds, t_sim=round(self._t, 3))

    def force_disarm(self) -> None:
        """Disarm now, even in the air (an emergency stop from the RC): the vehicle falls."""
        with self._lock:
            if self._armed:
                self._disarm("Disarmed by RC emergency stop", force=True)

    def set_mode(self, mode: str) -> None:
        """Switch to ``mode`` (a PX4 or ArduCopter mode name) as a pilot with an RC would."""
        with self._lock:
            table = PX4_MODES if self._px4 else ARDUCOPTER_MODES
            if mode not in table:
                raise ValueError(f"unknown {self.autopilot} mode {mode!r}")
            self._enter_mode(mode, "pilot")

    # -- observation -----------------------------------------------------------------

    @property
    def mode(self) -> str:
        """The current mode name."""
        with self._lock:
            return self._mode

    @property
    def armed(self) -> bool:
        """True while armed."""
        with self._lock:
            return self._armed

    @property
    def position(self) -> tuple[float, float, float]:
        """The model's position: x north, y east, z up from the boot point (metres)."""
        with self._lock:
            return self._model.position

    @property
    def sim_time_s(self) -> float:
        """Simulated seconds since start."""
        with self._lock:
            return self._t

    def wait_until(self, predicate: Callable[[SimVehicle], bool], timeout: float) -> bool:
        """Wait (on the tick condition) until ``predicate(self)`` holds; False on timeout.

        The predicate is checked after every simulation tick, with the
        vehicle's (reentrant) lock held, so it sees one consistent state.
        """
        deadline = time.monotonic() + timeout
        with self._cond:
            return (
                self._cond.wait_for(
                    lambda: self._stop.is_set() or predicate(self),
                    timeout=max(0.0, deadline - time.monotonic()),
                )
                and not self._stop.is_set()
            )

    @property
    def speed_mps(self) -> float:
        """The model's 3-D speed."""
        with self._lock:
            return self._model.state.speed_mps

    # -- the simulation thread ----------------------------------------------------------

    def _loop(self) -> None:
        for steps in paced_ticks(self._stop, self.options.speedup):
            try:
                with self._cond:
                    self._receive()
                    for _ in range(steps):
                        self._step()
                    self._send_due()
                    self._cond.notify_all()
            except Exception as exc:  # keep the process alive and tell why
                self._log.exception("vehicle.error", error=repr(exc))

    def _receive(self) -> None:
        conn = self._conn
        if conn is None:
            return
        for _ in range(MAX_MESSAGES_PER_TICK):
            try:
                msg = conn.recv_msg()
            except OSError:
                return
            if msg is None:
                return
            if time.monotonic() < self._drop_until or msg.get_type() == "BAD_DATA":
                continue  # lost on the way
            kind = msg.get_type()
            self.received[kind] = self.received.get(kind, 0) + 1
            handler = getattr(self, f"_on_{kind.lower()}", None)
            if handler is not None:
                try:
                    handler(msg)
                except Exception as exc:  # one odd message must not stop the vehicle
                    self._log.exception("vehicle.message_error", message=kind, error=repr(exc))

    def _send(self, message: str, *args: Any) -> None:
        conn = self._conn
        if conn is None or time.monotonic() < self._drop_until:
            return
        try:
            getattr(conn.mav, f"{message}_send")(*args)
        except OSError:
            pass  # nobody listening yet (UDP) or the client left (TCP)

    def _text(self, text: str, severity: int = SEV_INFO) -> None:
        self._log.info("vehicle.statustext", text=text, t_sim=round(self._t, 3))
        if len(text) <= STATUSTEXT_LEN:
            self._send("statustext", severity, text.encode(), 0, 0)
            return
        self._text_id = self._text_id % 65535 + 1
        chunks = [text[i : i + STATUSTEXT_LEN] for i in range(0, len(text), STATUSTEXT_LEN)]
        for seq, chunk in enumerate(chunks):
            self._send("statustext", severity, chunk.encode(), self._text_id, seq)

    # -- simulated time -----------------------------------------------------------------

    def _step(self) -> None:
        o = self.options
        self._t += SIM_DT_S
        t = self._t
        if not self._px4 and not self._ready_announced and t >= ARDUPILOT_READY_S:
            self._ready_announced = True
            self._mode = "STABILIZE"  # the initial mode wins over anything set during boot
            self._text("ArduPilot Ready")
        if self._armable() and not self._armable_announced:
            self._armable_announced = True
            self._text("EKF3 IMU0 is using GPS" if not self._px4 else "Ready for takeoff!")
        if not self._armable() and t >= self._next_prearm_text and t >= BOOT_S:
            self._next_prearm_text = t + PREARM_TEXT_PERIOD_S
            self._text(self._prearm_reason(), SEV_CRITICAL)
        if self._px4:
            self._px4_logic()
        model = self._model
        if (
            self._armed
            and model.landed
            and not self._flew
            and t - self._armed_at >= o.disarm_after_s
        ):
            self._disarm(
                "Disarmed by auto preflight disarming" if self._px4 else "Disarming motors"
            )
        model.step(SIM_DT_S)
        if not model.landed:
            self._flew = True
        if model.landed and not self._was_landed:
            self._touchdown_at = t
            self._text("Landing detected" if self._px4 else "Land complete", SEV_INFO)
            if not self._armed and model.armed:
                model.disarm()  # a force-disarmed vehicle has now hit the ground
        self._was_landed = model.landed
        if (
            self._touchdown_at is not None
            and self._armed
            and model.landed
            and t - self._touchdown_at >= LAND_DISARM_S
        ):
            self._disarm("Disarmed by landing" if self._px4 else "Disarming motors")
        self._log_position()

    def _px4_logic(self) -> None:
        model, t = self._model, self._t
        streaming = self._streaming()
        if self._mode == "OFFBOARD" and self._armed and not streaming:
            # COM_OF_LOSS_T passed: failsafe (COM_OBL_RC_ACT = 5: hold).
            self._failsafe = True
            self._mode = "HOLD"
            model.hold()
            self._log.info("vehicle.mode", mode="HOLD", by="failsafe", t_sim=round(t, 3))
            self._text("Failsafe activated: no offboard signal, holding", SEV_CRITICAL)
        if self._mode == "AUTO.TAKEOFF" and self._armed and self._takeoff_z is not None:
            x, y, z = model.position
            if model.target is None or model.landed:
                model.set_target(x, y, self._takeoff_z)
            if abs(z - self._takeoff_z) < 0.1 and model.state.speed_mps < 0.2:
                self._takeoff_z = None
                self._enter_mode("HOLD", "takeoff complete")

    def _streaming(self) -> bool:
        """PX4: setpoints keep coming (within COM_OF_LOSS_T, see OFFBOARD_LOSS_*)."""
        return (
            self._t - self._last_sp_t <= OFFBOARD_LOSS_S
            or time.monotonic() - self._last_sp_wall <= OFFBOARD_LOSS_WALL_S
        )

    def _armable(self) -> bool:
        if self._t < max(BOOT_S, self.options.prearm_delay_s):
            return False
        if not self._px4 and not self._ready_announced:
            return False
        # PX4: OFFBOARD without a stream is not "armable in the current mode".
        return not (self._px4 and self._mode == "OFFBOARD" and not self._streaming())

    def _prearm_reason(self) -> str:
        if self._t < self.options.prearm_delay_s:
            return (
                "Preflight Fail: ekf2 missing data"
                if self._px4
                else "PreArm: EKF3 still initialising"
            )
        return "Preflight Fail: no offboard setpoints"

    # -- state changes ------------------------------------------------------------------

    def _initial_mode(self) -> str:
        return "HOLD" if self._px4 else "STABILIZE"

    def _custom_mode(self) -> int:
        if self._px4:
            return px4_custom_mode(*PX4_MODES[self._mode])
        return ARDUCOPTER_MODES[self._mode]

    def _arm(self) -> None:
        self._armed = True
        self._armed_at = self._t
        self._flew = False
        self._touchdown_at = None
        self._model.arm()
        self._log.info("vehicle.armed", armed=True, t_sim=round(self._t, 3))
        self._text("Armed by external command" if self._px4 else "Arming motors")
        self._apply_mode_target()

    def _disarm(self, text: str, force: bool = False) -> None:
        self._armed = False
        self._touchdown_at = None
        if self._model.landed:
            self._model.disarm()
        else:
            self._model.land()  # falls (a kinematic model descends) and stops on the ground
        self._log.info("vehicle.armed", armed=False, forced=force, t_sim=round(self._t, 3))
        self._text(text)
        if self._px4 and self._mode in ("AUTO.LAND", "AUTO.TAKEOFF"):
            self._mode = "HOLD"  # PX4 returns to HOLD after a landing
        self._takeoff_z = None

    def _enter_mode(self, mode: str, by: str) -> None:
        self._mode = mode
        self._failsafe = False
        self._log.info("vehicle.mode", mode=mode, by=by, t_sim=round(self._t, 3))
        model = self._model
        if mode in ("AUTO.LAND", "LAND"):
            model.land()
            if model.landed and self._armed:
                self._touchdown_at = self._t  # already down: disarm soon
        elif mode in ("AUTO.RTL", "RTL"):
            # Back over the boot point at the current height (landing there is left out).
            if not model.landed:
                model.set_target(0.0, 0.0, max(model.position[2], 2.0))
        elif mode == "OFFBOARD" or mode == "AUTO.TAKEOFF":
            self._apply_mode_target()
        else:
            model.hold()  # HOLD, LOITER, BRAKE, GUIDED, POSCTL...: stop where it is

    def _apply_mode_target(self) -> None:
        if not self._armed:
            return
        if self._px4 and self._mode == "OFFBOARD" and self._offboard_target is not None:
            self._model.set_target(*self._offboard_target)
        elif self._px4 and self._mode == "AUTO.TAKEOFF" and self._takeoff_z is not None:
            x, y, _ = self._model.position
            self._model.set_target(x, y, self._takeoff_z)

    # -- incoming messages ------------------------------------------------------------------

    def _for_us(self, msg: Any) -> bool:
        return msg.target_system in (0, self.options.sysid) and msg.target_component in (0, 1)

    def _on_heartbeat(self, msg: Any) -> None:
        if self._gcs is None:
            self._log.info("vehicle.gcs", sysid=msg.get_srcSystem(), compid=msg.get_srcComponent())
        self._gcs = (msg.get_srcSystem(), msg.get_srcComponent())

    def _on_command_long(self, msg: Any) -> None:
        if self._for_us(msg):
            params = (
                msg.param1,
                msg.param2,
                msg.param3,
                msg.param4,
                msg.param5,
                msg.param6,
                msg.param7,
            )
            self._command(msg, msg.command, params, None)

    def _on_command_int(self, msg: Any) -> None:
        if self._for_us(msg):
            params = (
                msg.param1,
                msg.param2,
                msg.param3,
                msg.param4,
                float(msg.x),
                float(msg.y),
                msg.z,
            )
            self._command(msg, msg.command, params, msg.frame)

    def _command(self, msg: Any, command: int, p: tuple[float, ...], frame: int | None) -> None:
        if command in self.options.reject:
            result = self.options.reject[command]
            self._text(f"Command {command} rejected (test fault)", SEV_WARNING)
        else:
            handler = {
                CMD_COMPONENT_ARM_DISARM: self._cmd_arm_disarm,
                CMD_DO_SET_MODE: self._cmd_set_mode,
                CMD_NAV_TAKEOFF: self._cmd_takeoff,
                CMD_NAV_LAND: self._cmd_land,
                CMD_DO_REPOSITION: self._cmd_reposition,
                CMD_SET_MESSAGE_INTERVAL: self._cmd_message_interval,
                CMD_REQUEST_MESSAGE: self._cmd_request_message,
                CMD_GET_HOME_POSITION: lambda p, f: self._send_now(MSG_HOME_POSITION),
                CMD_REQUEST_AUTOPILOT_CAPABILITIES: lambda p, f: self._send_now(
                    MSG_AUTOPILOT_VERSION
                ),
            }.get(command)
            result = UNSUPPORTED if handler is None else handler(p, frame)
        self.commands.append((command, result))
        self._log.info(
            "vehicle.command",
            command=command,
            params=[_num(v) for v in p],
            result=result,
            t_sim=round(self._t, 3),
        )
        self._send(
            "command_ack", command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()
        )

    def _cmd_arm_disarm(self, p: tuple[float, ...], frame: int | None) -> int:
        force = _int(p[1]) == FORCE_MAGIC
        if p[0] >= 0.5:
            if self._armed:
                return ACCEPTED
            if not force and not self._armable():
                if self._px4:
                    self._text("Arming denied: Resolve system health failures first", SEV_CRITICAL)
                    self._text(self._prearm_reason(), SEV_CRITICAL)
                    return TEMPORARILY_REJECTED
                self._text(f"Arm: {self._prearm_reason().removeprefix('PreArm: ')}", SEV_CRITICAL)
                return FAILED
            if self._mode in ("AUTO.LAND", "AUTO.RTL", "LAND", "RTL", "AUTO"):
                self._text(
                    "Arming denied: not in a mode that can arm"
                    if self._px4
                    else "Arm: Mode not armable",
                    SEV_CRITICAL,
                )
                return DENIED if self._px4 else FAILED
            self._arm()
            return ACCEPTED
        if not self._armed:
            return ACCEPTED
        if not self._model.landed and not force:
            self._text(
                "Disarming denied: not landed" if self._px4 else "Disarm: vehicle in the air",
                SEV_CRITICAL,
            )
            return DENIED if self._px4 else FAILED
        self._disarm(
            "Disarmed by external command" if self._px4 else "Disarming motors", force=force
        )
        return ACCEPTED

    def _cmd_set_mode(self, p: tuple[float, ...], frame: int | None) -> int:
        if not _int(p[0]) & MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return DENIED
        if self._px4:
            main, sub = _int(p[1]), _int(p[2])
            if main == 4 and sub == 0:
                sub = 3  # AUTO without a sub mode: PX4 takes LOITER
            names = {pair: name for name, pair in PX4_MODES.items()}
            mode = names.get((main, sub))
            if mode is None:
                return DENIED
            if mode == self._mode:
                return ACCEPTED
            if (
                mode == "OFFBOARD"
                and (self._armed or not self._model.landed)
                and not self._streaming()
            ):
                self._text("Switching to Offboard is currently not available", SEV_CRITICAL)
                return TEMPORARILY_REJECTED
            if mode in ("MANUAL", "ALTCTL", "POSCTL", "ACRO", "STABILIZED"):
                self._text("Switching to mode not possible: no RC", SEV_CRITICAL)
                return TEMPORARILY_REJECTED
            if mode == "AUTO.MISSION":
                self._text("Mission rejected: no mission", SEV_CRITICAL)
                return DENIED
            if mode == "AUTO.TAKEOFF":
                self._takeoff_z = self._params["MIS_TAKEOFF_ALT"][0]
        else:
            names_ap = {value: name for name, value in ARDUCOPTER_MODES.items()}
            mode = names_ap.get(_int(p[1]))
            if mode is None or mode in ("AUTO", "ACRO", "THROW", "GUIDED_NOGPS"):
                return FAILED
            if mode == self._mode:
                return ACCEPTED
        self._enter_mode(mode, "command")
        return ACCEPTED

    def _cmd_takeoff(self, p: tuple[float, ...], frame: int | None) -> int:
        model = self._model
        x, y, _ = model.position
        if self._px4:
            alt = p[6]
            height = (
                alt - self.options.home[2]
                if math.isfinite(alt)
                else self._params["MIS_TAKEOFF_ALT"][0]
            )
            if height < 0.5:
                return DENIED
            self._takeoff_z = height
            self._enter_mode("AUTO.TAKEOFF", "takeoff command")
            self._text(f"Takeoff to {height:.1f} meters above home started")
            return ACCEPTED
        # ArduCopter: GUIDED and armed, on the ground, a positive height.
        if self._mode != "GUIDED" or not self._armed or not model.landed:
            return FAILED
        height = p[6]
        if not math.isfinite(height) or height <= 0:
            return FAILED
        model.set_target(x, y, height)
        self._flew = True  # taking off counts: no preflight auto-disarm
        return ACCEPTED

    def _cmd_land(self, p: tuple[float, ...], frame: int | None) -> int:
        if not self._armed:
            return DENIED if self._px4 else FAILED
        self._enter_mode("AUTO.LAND" if self._px4 else "LAND", "land command")
        if self._px4:
            self._text("Landing at current position")
        return ACCEPTED

    def _cmd_reposition(self, p: tuple[float, ...], frame: int | None) -> int:
        model = self._model
        if not self._armed or model.landed:
            return DENIED if self._px4 else FAILED
        x, y, z = model.position
        lat, lon, alt = p[4], p[5], p[6]
        if frame is not None:  # COMMAND_INT: degrees * 1e7
            lat, lon = lat / 1e7, lon / 1e7
        relative = frame in (FRAME_GLOBAL_RELATIVE_ALT, FRAME_GLOBAL_RELATIVE_ALT_INT)
        tx, ty = (
            (x, y)
            if not (math.isfinite(lat) and math.isfinite(lon) and (lat or lon))
            else self._frame.from_lla(lat, lon, 0.0)[:2]
        )
        tz = z if not math.isfinite(alt) else (alt if relative else alt - self.options.home[2])
        if self._px4:
            if self._mode != "HOLD":
                self._enter_mode("HOLD", "reposition")
        elif self._mode != "GUIDED":
            if not _int(p[1]) & 1:  # MAV_DO_REPOSITION_FLAGS_CHANGE_MODE
                return FAILED
            self._enter_mode("GUIDED", "reposition")
        model.set_target(tx, ty, max(tz, 0.5))
        return ACCEPTED

    def _cmd_message_interval(self, p: tuple[float, ...], frame: int | None) -> int:
        msg_id, interval_us = _int(p[0], -1), p[1]
        if not math.isfinite(interval_us):
            interval_us = 0.0
        if msg_id == MSG_HEARTBEAT:
            return FAILED if 0 < interval_us < 1e6 else ACCEPTED  # PX4: HEARTBEAT stays 1 Hz
        if msg_id not in STREAMABLE:
            return UNSUPPORTED
        if interval_us < 0:
            self._rates.pop(msg_id, None)
        elif interval_us == 0:
            default = DEFAULT_RATES["px4"].get(msg_id, 1.0)
            self._rates[msg_id] = default
        else:
            self._rates[msg_id] = 1e6 / interval_us
        self._due[msg_id] = self._t
        return ACCEPTED

    def _cmd_request_message(self, p: tuple[float, ...], frame: int | None) -> int:
        msg_id = _int(p[0], -1)
        if msg_id not in STREAMABLE and msg_id != MSG_AUTOPILOT_VERSION:
            return UNSUPPORTED
        return self._send_now(msg_id)

    def _send_now(self, msg_id: int) -> int:
        self._send_message(msg_id)
        return ACCEPTED

    def _on_set_position_target_local_ned(self, msg: Any) -> None:
        if not self._for_us(msg):
            return
        if self._px4:
            self._last_sp_t, self._last_sp_wall = self._t, time.monotonic()
        if msg.type_mask & IGNORE_POSITION or msg.coordinate_frame != FRAME_LOCAL_NED:
            return  # velocity/acceleration setpoints only keep the stream alive here
        target = (msg.x, msg.y, -(msg.z - self.options.offset_m))
        self._position_target(target)

    def _on_set_position_target_global_int(self, msg: Any) -> None:
        if not self._for_us(msg):
            return
        if self._px4:
            self._last_sp_t, self._last_sp_wall = self._t, time.monotonic()
        if msg.type_mask & IGNORE_POSITION:
            return
        x, y, _ = self._frame.from_lla(msg.lat_int / 1e7, msg.lon_int / 1e7, 0.0)
        if msg.coordinate_frame in (FRAME_GLOBAL_RELATIVE_ALT, FRAME_GLOBAL_RELATIVE_ALT_INT):
            z = msg.alt
        elif msg.coordinate_frame in (FRAME_GLOBAL, FRAME_GLOBAL_INT):
            z = msg.alt - self.options.home[2]
        else:
            return
        self._position_target((x, y, z))

    def _position_target(self, target: tuple[float, float, float]) -> None:
        if self._px4:
            self._offboard_target = target
            if self._failsafe and self._mode == "HOLD":
                # PX4 returns to OFFBOARD by itself once setpoints resume.
                self._enter_mode("OFFBOARD", "setpoints resumed")
                self._text("Failsafe deactivated: offboard signal regained", SEV_NOTICE)
            elif self._mode == "OFFBOARD" and self._armed:
                self._model.set_target(*target)
        elif self._mode == "GUIDED" and self._armed and not self._model.landed:
            # ArduCopter ignores position targets until it has taken off.
            self._model.set_target(*target)

    def _on_request_data_stream(self, msg: Any) -> None:
        """ArduPilot's older way to ask for telemetry (PX4 ignores it)."""
        if self._px4 or not self._for_us(msg):
            return
        if msg.req_stream_id == 0:
            groups = list(DATA_STREAMS.values())
        else:
            groups = [DATA_STREAMS.get(msg.req_stream_id, ())]
        for msg_id in (m for group in groups for m in group):
            if msg.start_stop and msg.req_message_rate > 0:
                self._rates[msg_id] = float(msg.req_message_rate)
                self._due[msg_id] = self._t
            else:
                self._rates.pop(msg_id, None)

    def _on_param_request_list(self, msg: Any) -> None:
        if self._for_us(msg):
            for index, name in enumerate(self._params):
                self._send_param(name, index)

    def _on_param_request_read(self, msg: Any) -> None:
        if not self._for_us(msg):
            return
        names = list(self._params)
        name = msg.param_id.decode() if isinstance(msg.param_id, bytes) else msg.param_id
        name = name.rstrip("\x00")
        if msg.param_index >= 0 and msg.param_index < len(names):
            name = names[msg.param_index]
        if name in self._params:
            self._send_param(name, names.index(name))

    def _on_param_set(self, msg: Any) -> None:
        if not self._for_us(msg):
            return
        name = msg.param_id.decode() if isinstance(msg.param_id, bytes) else msg.param_id
        name = name.rstrip("\x00")
        if name not in self._params:
            return  # both SITLs stay silent about unknown parameters
        _, ptype = self._params[name]
        value = _px4_unfloat(msg.param_value, ptype) if self._px4 else float(msg.param_value)
        self._params[name] = (value, ptype)
        self._log.info("vehicle.param", name=name, value=value)
        self._send_param(name, list(self._params).index(name))

    def _send_param(self, name: str, index: int) -> None:
        value, ptype = self._params[name]
        wire = _px4_float(value, ptype) if self._px4 else float(value)
        self._send("param_value", name.encode(), wire, ptype, len(self._params), index)

    def _initial_params(self) -> dict[str, tuple[float, int]]:
        o = self.options
        if self._px4:
            return {
                "MAV_SYS_ID": (float(o.sysid), PARAM_INT32),
                "MIS_TAKEOFF_ALT": (2.5, PARAM_REAL32),
                "COM_DISARM_PRFLT": (o.disarm_after_s, PARAM_REAL32),
                "COM_DISARM_LAND": (LAND_DISARM_S, PARAM_REAL32),
                "COM_OF_LOSS_T": (OFFBOARD_LOSS_S, PARAM_REAL32),
                "COM_OBL_RC_ACT": (5.0, PARAM_INT32),
                "MPC_XY_CRUISE": (o.limits.horizontal_speed_mps, PARAM_REAL32),
                "MPC_Z_VEL_MAX_UP": (o.limits.climb_speed_mps, PARAM_REAL32),
                "MPC_Z_VEL_MAX_DN": (o.limits.descent_speed_mps, PARAM_REAL32),
            }
        return {
            "SYSID_THISMAV": (float(o.sysid), PARAM_REAL32),
            "DISARM_DELAY": (o.disarm_after_s, PARAM_REAL32),
            "PILOT_TKOFF_ALT": (0.0, PARAM_REAL32),
            "WPNAV_SPEED": (o.limits.horizontal_speed_mps * 100, PARAM_REAL32),
            "WPNAV_SPEED_UP": (o.limits.climb_speed_mps * 100, PARAM_REAL32),
            "WPNAV_SPEED_DN": (o.limits.descent_speed_mps * 100, PARAM_REAL32),
            "FS_GCS_ENABLE": (0.0, PARAM_REAL32),
        }

    # -- outgoing messages --------------------------------------------------------------------

    def _send_due(self) -> None:
        t = self._t
        if t >= BOOT_S and t >= self._next_heartbeat:
            self._next_heartbeat = max(self._next_heartbeat + 1.0, t)
            self._send_heartbeat()
        if t < BOOT_S:
            return
        for msg_id, hz in self._rates.items():
            due = self._due.get(msg_id, t)
            if t >= due and hz > 0:
                self._send_message(msg_id)
                # At most once per tick; keep the cadence without bursting.
                self._due[msg_id] = max(due + 1.0 / hz, t)

    def _send_heartbeat(self) -> None:
        base = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | MAV_MODE_FLAG_STABILIZE_ENABLED
        if (
            self._mode in ("OFFBOARD", "GUIDED")
            or self._mode.startswith("AUTO")
            or self._mode in ("HOLD", "LAND", "RTL")
        ):
            base |= MAV_MODE_FLAG_GUIDED_ENABLED
        if self._armed:
            base |= MAV_MODE_FLAG_SAFETY_ARMED
        autopilot = MAV_AUTOPILOT_PX4 if self._px4 else MAV_AUTOPILOT_ARDUPILOTMEGA
        self._send(
            "heartbeat",
            MAV_TYPE_QUADROTOR,
            autopilot,
            base,
            self._custom_mode(),
            MAV_STATE_ACTIVE if self._armed else MAV_STATE_STANDBY,
            3,
        )

    def _send_message(self, msg_id: int) -> None:
        st = self._model.state
        o = self.options
        ms = int(self._t * 1000) & 0xFFFFFFFF
        lat, lon, _ = self._frame.to_lla(st.x_m, st.y_m, st.z_m)
        amsl = o.home[2] + st.z_m
        if msg_id == MSG_LOCAL_POSITION_NED:
            self._send(
                "local_position_ned",
                ms,
                st.x_m,
                st.y_m,
                o.offset_m - st.z_m,
                st.vx_mps,
                st.vy_mps,
                -st.vz_mps,
            )
        elif msg_id == MSG_GLOBAL_POSITION_INT:
            self._send(
                "global_position_int",
                ms,
                round(lat * 1e7),
                round(lon * 1e7),
                round(amsl * 1000),
                round(st.z_m * 1000),
                round(st.vx_mps * 100),
                round(st.vy_mps * 100),
                round(-st.vz_mps * 100),
                0,
            )
        elif msg_id == MSG_SYS_STATUS:
            reported = SENSORS | (PREARM_CHECK if o.report_prearm else 0)
            health = SENSORS | (PREARM_CHECK if self._armable() and o.report_prearm else 0)
            self._send(
                "sys_status",
                reported,
                reported,
                health,
                250,
                12600,
                500 if self._armed else 50,
                round(st.battery_pct),
                0,
                0,
                0,
                0,
                0,
                0,
            )
        elif msg_id == MSG_EXTENDED_SYS_STATE:
            self._send("extended_sys_state", 0, self._landed_state())
        elif msg_id == MSG_ATTITUDE:
            self._send("attitude", ms, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        elif msg_id == MSG_BATTERY_STATUS:
            self._send(
                "battery_status",
                0,
                0,
                1,
                32767,
                [12600] + [65535] * 9,
                -1,
                -1,
                -1,
                round(st.battery_pct),
                0,
                1,
                [0, 0, 0, 0],
                0,
                0,
            )
        elif msg_id == MSG_HOME_POSITION:
            hlat, hlon, halt = o.home
            self._send(
                "home_position",
                round(hlat * 1e7),
                round(hlon * 1e7),
                round(halt * 1000),
                0.0,
                0.0,
                o.offset_m,
                [1.0, 0.0, 0.0, 0.0],
                0.0,
                0.0,
                0.0,
                int(self._t * 1e6),
            )
        elif msg_id == MSG_GPS_RAW_INT:
            self._send(
                "gps_raw_int",
                int(self._t * 1e6),
                3,
                round(lat * 1e7),
                round(lon * 1e7),
                round(amsl * 1000),
                80,
                120,
                round(st.horizontal_speed_mps * 100),
                0,
                12,
                0,
                0,
                0,
                0,
                0,
                0,
            )
        elif msg_id == MSG_AUTOPILOT_VERSION:
            caps = 0x2000 | 0x8 | 0x2 | 0x4 | 0x80 | 0x100  # MAVLINK2, COMMAND_INT, PARAM_FLOAT...
            caps |= 0x10 if self._px4 else 0x20000  # param encoding: byte-wise / C cast
            version = (1 << 24 | 15 << 16 | 0 << 8 | 255) if self._px4 else (4 << 24 | 7 << 16)
            self._send(
                "autopilot_version",
                caps,
                version,
                0,
                0,
                0,
                [0] * 8,
                [0] * 8,
                [0] * 8,
                0,
                0,
                o.sysid,
            )

    def _landed_state(self) -> int:
        model = self._model
        if model.landed:
            return LANDED_ON_GROUND
        if self._mode in ("AUTO.LAND", "LAND"):
            return LANDED_LANDING
        if self._mode == "AUTO.TAKEOFF":
            return LANDED_TAKEOFF
        return LANDED_IN_AIR

    def _log_position(self) -> None:
        if self._t < self._next_position_log:
            return
        self._next_position_log = self._t + 1.0
        st = self._model.state
        key = (round(st.x_m, 2), round(st.y_m, 2), round(st.z_m, 2), self._armed, self._mode)
        if key != self._last_position_key:
            self._last_position_key = key
            self._log.info(
                "vehicle.position",
                x_m=key[0],
                y_m=key[1],
                z_m=key[2],
                armed=self._armed,
                mode=self._mode,
                t_sim=round(self._t, 3),
            )


def _int(value: float, default: int = 0) -> int:
    """A command parameter as an integer; NaN ("unused", as MAVSDK sends) gives ``default``."""
    return round(value) if math.isfinite(value) else default


def _num(value: float) -> float | None:
    """A JSON-friendly number (NaN becomes null)."""
    return None if not math.isfinite(value) else round(value, 7)
