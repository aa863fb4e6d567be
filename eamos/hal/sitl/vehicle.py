"""``eamos-sim-vehicle``: a simulated quadcopter speaking MAVLink 2 like PX4 or ArduCopter SITL.

It stands in for a real autopilot in tests and CI, so the MAVLink adapter
(and any MAVLink client, e.g. MAVSDK) can fly without PX4 or ArduPilot
installed.  Its behaviour follows what was observed of the real SITL builds
(docs/flying-real-drones.md describes them as the adapter meets them):

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
``Event.wait``, ``speedup`` times real time).  The parts:

* :mod:`eamos.hal.sitl.core`: what both autopilots share (state,
  arming, modes, commands, parameters), asking a personality where they differ;
* :mod:`eamos.hal.sitl.px4` and :mod:`eamos.hal.sitl.ardupilot`:
  the two personalities;
* :mod:`eamos.hal.sitl.inbox`: the messages it understands, and its answers;
* :mod:`eamos.hal.sitl.streams`: HEARTBEAT and telemetry streams;
* :mod:`eamos.hal.sitl.wire`: MAVLink numbers, :class:`VehicleOptions`,
  :func:`parse_reject`;
* this module: :class:`SimVehicle`, the thread and the connection.

One thread owns the connection: each tick it drains incoming messages, steps
the core and sends what is due, so the vehicle needs no other locking than for
the test hooks (:meth:`SimVehicle.drop_link`, :meth:`SimVehicle.force_disarm`,
:meth:`SimVehicle.set_mode`) and observers (:meth:`SimVehicle.wait_until`).

Faults for tests: ``reject`` answers chosen commands with a chosen result;
``prearm_delay_s = inf`` never becomes armable; ``drop_link(s)`` drops
everything both ways for ``s`` wall seconds.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any

from eamos.hal.mavlink.link import load_mavutil
from eamos.hal.mavlink.signing import radio_status_only, refresh_timestamp
from eamos.hal.sim.adapter import paced_ticks
from eamos.hal.sitl.ardupilot import ArduPilotPersonality
from eamos.hal.sitl.core import LAND_MODES, RTL_MODES, Params, Personality, VehicleCore
from eamos.hal.sitl.fence import Geofence
from eamos.hal.sitl.inbox import Inbox
from eamos.hal.sitl.missions import MISSION, MissionItem
from eamos.hal.sitl.px4 import Px4Personality
from eamos.hal.sitl.transport import Links
from eamos.hal.sitl.wire import (
    ACCEPTED,
    DENIED,
    FAILED,
    RESULTS,
    SEV_CRITICAL,
    TEMPORARILY_REJECTED,
    UNSUPPORTED,
    AutopilotName,
    VehicleOptions,
    parse_reject,
)
from eamos.logs import close_logger, make_logger

#: The personality of each autopilot the vehicle can behave like.
PERSONALITIES: dict[str, Callable[[], Personality]] = {
    "px4": Px4Personality,
    "ardupilot": ArduPilotPersonality,
}


class SimVehicle:
    """A simulated MAVLink quadcopter (see module docstring): ``start()``, ``stop()``."""

    def __init__(self, options: VehicleOptions, on_death: Callable[[], None] | None = None) -> None:
        self.options = options
        self._on_death = on_death
        self._airborne_since: float | None = None
        #: Set when the vehicle died (``die_after_s``).
        self.dead = threading.Event()
        o = options
        self.autopilot: AutopilotName = o.autopilot
        # Reentrant, so wait_until predicates may read the public properties.
        self._lock = threading.RLock()
        self._cond = threading.Condition(self._lock)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._links: Links | None = None
        self._log = make_logger(o.log, vehicle=f"{o.autopilot}-{o.sysid}")
        self._drop_until = -math.inf  # wall clock: link dropped until then
        self._core = VehicleCore(o, PERSONALITIES[o.autopilot](), self._log, self._send)
        self._inbox = Inbox(self._core)
        self.received: dict[str, int] = {}  # message type -> count (observers)
        #: (MAV_CMD, MAV_RESULT) of every command answered (observers).
        self.commands: list[tuple[int, int]] = self._inbox.commands

    # -- lifecycle ---------------------------------------------------------------

    def start(self) -> None:
        """Open the connection and start the simulation thread (OSError if the port is taken)."""
        mavutil = load_mavutil()
        o = self.options
        self._links = Links(mavutil.mavlink, o.connection, o.sysid)
        if o.signing_key is not None:
            self._sign(o.signing_key)
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
            wander_m=o.wander_m,
            seed=o.seed,
            estimator_settle_s=self._core.settle_s,
            estimator_bias_m=o.estimator_bias_m,
            signing=o.signing_key is not None,
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
        links, self._links = self._links, None
        if links is not None:
            links.close()
        with self._cond:
            self._cond.notify_all()
        if self._log is not None:
            t_sim = round(self._core.t, 3)
            self._log.info("vehicle.stop", t_sim=t_sim, received=dict(self.received))
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
            self._log.info("vehicle.link.drop", seconds=seconds, t_sim=round(self._core.t, 3))

    def force_disarm(self) -> None:
        """Disarm now, even in the air (an emergency stop from the RC): the vehicle falls."""
        with self._lock:
            if self._core.armed:
                self._core.disarm("Disarmed by RC emergency stop", force=True)

    def set_mode(self, mode: str) -> None:
        """Switch to ``mode`` (a PX4 or ArduCopter mode name) as a pilot with an RC would."""
        with self._lock:
            if mode not in self._core.p.modes:
                raise ValueError(f"unknown {self.autopilot} mode {mode!r}")
            self._core.enter_mode(mode, "pilot")

    def failsafe(self, mode: str, text: str = "Failsafe activated") -> None:
        """The autopilot's own failsafe: say ``text`` (critical), then switch to ``mode``,
        holding where the vehicle is unless the mode lands or returns (PX4's geofence
        held a vehicle touching down on the fence's line: its SITL)."""
        with self._lock:
            core = self._core
            if mode not in core.p.modes:
                raise ValueError(f"unknown {self.autopilot} mode {mode!r}")
            core.text(text, SEV_CRITICAL)
            here = core.model.position
            core.enter_mode(mode, "failsafe")
            if mode not in LAND_MODES | RTL_MODES:
                core.steer(*here)

    # -- observation -----------------------------------------------------------------

    @property
    def mode(self) -> str:
        """The current mode name."""
        with self._lock:
            return self._core.mode

    @property
    def armed(self) -> bool:
        """True while armed."""
        with self._lock:
            return self._core.armed

    @property
    def position(self) -> tuple[float, float, float]:
        """The model's position: x north, y east, z up from the boot point (metres)."""
        with self._lock:
            return self._core.model.position

    @property
    def target(self) -> tuple[float, float, float] | None:
        """The model's current setpoint (x north, y east, z up), or None."""
        with self._lock:
            return self._core.model.target

    @property
    def heading_deg(self) -> float:
        """The compass heading (degrees, 0 north, 90 east)."""
        with self._lock:
            return self._core.manoeuvres.heading_deg

    @property
    def sim_time_s(self) -> float:
        """Simulated seconds since start."""
        with self._lock:
            return self._core.t

    @property
    def speed_mps(self) -> float:
        """The model's 3-D speed."""
        with self._lock:
            return self._core.model.state.speed_mps

    @property
    def geofence(self) -> Geofence:
        """The fence uploaded to the vehicle (empty: none)."""
        with self._lock:
            return self._core.geofence

    def mission_items(self, mission_type: int = MISSION) -> list[MissionItem]:
        """The items of one of the vehicle's lists (0 mission, 1 fence, 2 rally points)."""
        with self._lock:
            return self._core.missions.items(mission_type)

    @property
    def params(self) -> Params:
        """A copy of the vehicle's parameters (name -> (value, MAV_PARAM_TYPE))."""
        with self._lock:
            return self._core.params.snapshot()

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
    def signing(self) -> bool:
        """True once the vehicle signs its messages and refuses unsigned ones."""
        with self._lock:
            return self._links is not None and self._links.signing

    @property
    def refused(self) -> int:
        """Messages dropped as unsigned or wrongly signed (signing on)."""
        with self._lock:
            return 0 if self._links is None else self._links.rejected

    @property
    def address(self) -> tuple[str, int]:
        """The vehicle's own socket address (host, port): where a client may reach it."""
        with self._lock:
            if self._links is None:
                raise RuntimeError("the vehicle is not started")
            return self._links.address

    @property
    def clients(self) -> int:
        """How many clients the vehicle serves now (TCP connections, UDP peers)."""
        with self._lock:
            return 0 if self._links is None else self._links.clients

    def _sign(self, key: bytes, timestamp: int | None = None) -> None:
        # The key is never logged.
        assert self._links is not None
        self._links.sign(key, timestamp, radio_status_only)
        self._log.info("vehicle.signing", enabled=True, t_sim=round(self._core.t, 3))

    # -- the simulation thread ----------------------------------------------------------

    def _loop(self) -> None:
        for steps in paced_ticks(self._stop, self.options.speedup):
            try:
                with self._cond:
                    links = self._links
                    if links is not None and links.signing:
                        refresh_timestamp(links.mav)  # >= 1 Hz, from the clock
                    self._receive()
                    for _ in range(steps):
                        self._core.step()
                    if self._dies():
                        return
                    self._core.send_due()
                    if self._links is not None:
                        self._links.flush()
                    self._cond.notify_all()
            except Exception as exc:  # keep the process alive and tell why
                self._log.exception("vehicle.error", error=repr(exc))

    def _dies(self) -> bool:
        """Sudden death (``die_after_s`` after leaving the ground): go silent for good."""
        limit = self.options.die_after_s
        core = self._core
        if limit is None:
            return False
        if self._airborne_since is None:
            if not core.model.landed:
                self._airborne_since = core.t
            return False
        if core.t - self._airborne_since < limit:
            return False
        self._log.warning("vehicle.death", t_sim=round(core.t, 3), position=list(self.position))
        links, self._links = self._links, None
        if links is not None:
            links.close()
        self.dead.set()
        self._cond.notify_all()
        if self._on_death is not None:
            self._on_death()
        return True

    def _receive(self) -> None:
        links = self._links
        if links is None:
            return
        for _link, msg in links.receive():
            if time.monotonic() < self._drop_until or msg.get_type() == "BAD_DATA":
                continue  # lost on the way
            kind = msg.get_type()
            self.received[kind] = self.received.get(kind, 0) + 1
            if kind == "SETUP_SIGNING" and msg.target_system in (0, self.options.sysid):
                self._sign(bytes(msg.secret_key), msg.initial_timestamp or None)
                continue
            try:
                self._inbox.handle(msg)
            except Exception as exc:  # one odd message must not stop the vehicle
                self._log.exception("vehicle.message_error", message=kind, error=repr(exc))

    def _send(self, message: str, *args: Any) -> None:
        links = self._links
        if links is None or time.monotonic() < self._drop_until:
            return
        msg = getattr(links.mav, f"{message}_encode")(*args)
        links.send(msg)


__all__ = [
    "ACCEPTED",
    "DENIED",
    "FAILED",
    "PERSONALITIES",
    "RESULTS",
    "TEMPORARILY_REJECTED",
    "UNSUPPORTED",
    "SimVehicle",
    "VehicleOptions",
    "parse_reject",
]
