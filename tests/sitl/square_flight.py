"""Experiment A flown with plain pymavlink, on a real SITL or on ``eamos-sim-vehicle`` alike.

The same commands the MAVLink adapter sends, from one driver, so two vehicles
can be compared: ArduCopter GUIDED (MAV_CMD_NAV_TAKEOFF, position targets
re-sent every second, MAV_CMD_NAV_LAND), PX4 OFFBOARD (20 Hz position
setpoints, the climb a setpoint too, then MAV_CMD_NAV_LAND).  The drone type's
speeds are set first (``eamos.hal.mavlink.params.speed_plan``, as the adapter
does).  An action is done as the adapter decides it (``eamos.hal.mavlink.autopilots``):
within the autopilot's tolerance of the target and slower than its settle speed
for half a second; Land when EXTENDED_SYS_STATE says on the ground; Disarm when
the HEARTBEAT says disarmed (both autopilots disarm by themselves after landing).

Every time is the vehicle's own (``time_boot_ms``), so a loaded machine that
slows a SITL down changes no figure.  Also the simulated SITL starts (helpers
that find ``../shared/sitl`` or ``EAMOS_SITL_DIR`` and start instances 6-8, the
ones these tests may use).
"""

from __future__ import annotations

import itertools
import math
import os
import shutil
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from eamos.hal.mavlink.link import load_mavutil
from eamos.hal.mavlink.params import speed_plan

#: Experiment A (missions/experiment_a.go): take-off height and the square's legs (x, y).
TAKEOFF_M = 1.5
LEGS = ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))
#: The drone type's speeds (the built-in types': eamos.hal.mavlink.settings defaults).
SPEEDS = (2.0, 1.0, 0.7)
#: Completion as the adapter decides it: tolerance (m), settle speed (m/s), settle window (s).
COMPLETION = {"ardupilot": (0.3, 0.3, 0.5), "px4": (0.6, 0.5, 0.5)}
#: Vehicle seconds any one phase may take before the flight is given up.
PHASE_LIMIT_S = 180.0
ARDUPILOT_GUIDED = 4
PX4_OFFBOARD = (6, 0)
LANDED_ON_GROUND = 1
PREARM = 0x10000000
#: Messages asked for, Hz (vehicle time).
STREAMS = {32: 20.0, 33: 5.0, 1: 2.0, 245: 5.0, 30: 5.0}


@dataclass
class FlightRecord:
    """One flight of experiment A: what happened when, in vehicle seconds."""

    autopilot: str
    #: Vehicle seconds from the first message to the vehicle saying it may arm.
    armable_wait_s: float = math.nan
    #: (action, vehicle seconds from the arming acknowledgement when it was done).
    ends: list[tuple[str, float]] = field(default_factory=list)
    #: (vehicle seconds from arming, x north, y east, z up: metres from where it took off).
    track: list[tuple[float, float, float, float]] = field(default_factory=list)
    #: The speeds (m/s) the vehicle reached: horizontal, climbing, descending.
    top_speeds: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def end_of(self, action: str, occurrence: int = 0) -> float:
        """When the ``occurrence``-th ``action`` was done."""
        times = [t for name, t in self.ends if name == action]
        return times[occurrence]

    def position_at(self, t: float) -> tuple[float, float, float]:
        """The track linearly interpolated at ``t`` (clamped to its ends)."""
        track = self.track
        if t <= track[0][0]:
            return track[0][1:]
        for (t0, *p0), (t1, *p1) in itertools.pairwise(track):
            if t0 <= t <= t1:
                k = 0.0 if t1 == t0 else (t - t0) / (t1 - t0)
                return tuple(a + (b - a) * k for a, b in zip(p0, p1, strict=True))  # type: ignore[return-value]
        return track[-1][1:]


class SquareFlight:
    """The pymavlink driver (see module docstring): ``fly()`` returns a :class:`FlightRecord`."""

    def __init__(self, connection: str, autopilot: str, wall_limit_s: float = 600.0) -> None:
        self.mavutil = load_mavutil()
        self.autopilot = autopilot
        self.conn = self.mavutil.mavlink_connection(
            connection, source_system=246, source_component=191
        )
        self.record = FlightRecord(autopilot)
        self._cond = threading.Condition()
        self._last: dict[str, Any] = {}
        self._acks: list[tuple[int, int]] = []
        self._t_boot = math.nan  # vehicle seconds (time_boot_ms) of the newest message
        self._t_first = math.nan
        self._t_arm = math.nan
        # LOCAL_POSITION_NED where it took off (PX4 SIH's origin is not where it stands).
        self._ground = (0.0, 0.0, 0.0)
        self._setpoint: tuple[float, float, float] | None = None  # NED
        self._stop = threading.Event()
        self._deadline = time.monotonic() + wall_limit_s
        self.target = 1

    # -- the connection ------------------------------------------------------------------

    def _read(self) -> None:
        next_beat = 0.0
        next_setpoint = 0.0
        while not self._stop.is_set():
            now = time.monotonic()
            if now >= next_beat:
                next_beat = now + 1.0
                self.conn.mav.heartbeat_send(6, 8, 0, 0, 4)
            if now >= next_setpoint:
                next_setpoint = now + (0.05 if self.autopilot == "px4" else 1.0)
                self._send_setpoint()
            try:
                msg = self.conn.recv_match(blocking=True, timeout=0.02)
            except OSError:
                continue
            if msg is None or msg.get_type() == "BAD_DATA":
                continue
            self._take(msg)

    def _take(self, msg: Any) -> None:
        kind = msg.get_type()
        with self._cond:
            if kind == "HEARTBEAT" and msg.get_srcComponent() == 1:
                self.target = msg.get_srcSystem()
            boot_ms = getattr(msg, "time_boot_ms", None)
            if boot_ms is not None:
                self._t_boot = boot_ms / 1000.0
                if math.isnan(self._t_first):
                    self._t_first = self._t_boot
            self._last[kind] = msg
            if kind == "COMMAND_ACK":
                self._acks.append((msg.command, msg.result))
            if kind == "LOCAL_POSITION_NED" and not math.isnan(self._t_arm):
                t = msg.time_boot_ms / 1000.0 - self._t_arm
                gx, gy, gz = self._ground
                self.record.track.append((t, msg.x - gx, msg.y - gy, gz - msg.z))
                h, c, d = self.record.top_speeds
                self.record.top_speeds = (
                    max(h, math.hypot(msg.vx, msg.vy)),
                    max(c, -msg.vz),
                    max(d, msg.vz),
                )
            self._cond.notify_all()

    def wait(self, predicate: Callable[[], Any], what: str, limit_s: float = PHASE_LIMIT_S) -> Any:
        """Wait (on received messages) until ``predicate()`` holds; vehicle-time bounded."""
        with self._cond:
            start = self._t_boot
            while True:
                value = predicate()
                if value:
                    return value
                if time.monotonic() > self._deadline:
                    raise TimeoutError(f"{self.autopilot}: {what}: wall-clock limit")
                if not math.isnan(start) and self._t_boot - start > limit_s:
                    raise TimeoutError(f"{self.autopilot}: {what}: not within {limit_s} s")
                self._cond.wait(0.5)

    def command(self, command: int, *params: float, retries: int = 5) -> int:
        """COMMAND_LONG, resent until acknowledged; the result."""
        full = list(params) + [0.0] * (7 - len(params))
        for _ in range(retries):
            with self._cond:
                seen = len(self._acks)
            self.conn.mav.command_long_send(self.target, 1, command, 0, *full)
            deadline = time.monotonic() + 3.0
            with self._cond:
                while time.monotonic() < deadline:
                    ack = next((r for c, r in self._acks[seen:] if c == command), None)
                    if ack is not None:
                        return int(ack)
                    self._cond.wait(0.2)
        raise TimeoutError(f"{self.autopilot}: command {command} never acknowledged")

    def _send_setpoint(self) -> None:
        sp = self._setpoint
        if sp is None:
            return
        self.conn.mav.set_position_target_local_ned_send(
            0, self.target, 1, 1, 0x09F8, sp[0], sp[1], sp[2], 0, 0, 0, 0, 0, 0, 0.0, 0
        )

    # -- phases --------------------------------------------------------------------------

    def _position(self) -> tuple[float, float, float, float]:
        lp = self._last["LOCAL_POSITION_NED"]
        speed = math.sqrt(lp.vx**2 + lp.vy**2 + lp.vz**2)
        return lp.x, lp.y, lp.z, speed

    def _reach(self, target: tuple[float, float, float], action: str) -> None:
        tolerance, settle_speed, window = COMPLETION[self.autopilot]
        since = [math.nan]

        def settled() -> bool:
            x, y, z, speed = self._position()
            near = math.dist((x, y, z), target) <= tolerance and speed <= settle_speed
            if not near:
                since[0] = math.nan
                return False
            if math.isnan(since[0]):
                since[0] = self._t_boot
            return self._t_boot - since[0] >= window

        self.wait(settled, action)
        self._done(action)

    def _done(self, action: str) -> None:
        with self._cond:
            self.record.ends.append((action, self._t_boot - self._t_arm))

    def _set_param(self, name: str, value: float) -> None:
        self.conn.mav.param_set_send(self.target, 1, name.encode(), value, 9)
        self.wait(
            lambda: (
                (p := self._last.get("PARAM_VALUE")) is not None
                and p.param_id == name
                and abs(p.param_value - value) < 1e-3
            ),
            f"PARAM_SET {name}",
            30.0,
        )

    def fly(self) -> FlightRecord:
        """Experiment A from connection to disarm."""
        reader = threading.Thread(target=self._read, daemon=True)
        reader.start()
        try:
            return self._fly()
        finally:
            self._stop.set()
            reader.join(5)
            self.conn.close()

    def _fly(self) -> FlightRecord:
        ap = self.autopilot
        self.wait(lambda: "HEARTBEAT" in self._last, "heartbeat", 60.0)
        for msg_id, hz in STREAMS.items():
            self.command(511, msg_id, 1e6 / hz)
        self.wait(lambda: "LOCAL_POSITION_NED" in self._last, "LOCAL_POSITION_NED", 60.0)
        for name, value in speed_plan(ap, *SPEEDS):  # type: ignore[arg-type]
            self._set_param(name, value)
        status = self.wait(
            lambda: (
                (s := self._last.get("SYS_STATUS")) is not None
                and s.onboard_control_sensors_health & PREARM
                and s
            ),
            "armable",
            240.0,
        )
        del status
        with self._cond:
            self.record.armable_wait_s = self._t_boot - self._t_first
        x0, y0, z0, _ = self._position()
        self._ground = (x0, y0, z0)
        if ap == "ardupilot":
            assert self.command(176, 1, ARDUPILOT_GUIDED) == 0
            self.wait(
                lambda: self._last["HEARTBEAT"].custom_mode == ARDUPILOT_GUIDED, "GUIDED", 10.0
            )
            self._arm()
            assert self.command(22, 0, 0, 0, 0, 0, 0, TAKEOFF_M) == 0
        else:
            self._setpoint = (x0, y0, z0 - TAKEOFF_M)
            time.sleep(0.5)  # a setpoint stream before OFFBOARD, as PX4 requires
            assert self.command(176, 1, *PX4_OFFBOARD) == 0
            self._arm()
        target = (x0, y0, z0 - TAKEOFF_M)
        self._reach(target, "Takeoff")
        for dx, dy in LEGS:
            target = (target[0] + dx, target[1] + dy, target[2])
            self._setpoint = target
            if ap == "ardupilot":
                self._send_setpoint()
            self._reach(target, "FlyByX" if dx else "FlyByY")
        self._setpoint = None
        assert self.command(21) == 0
        self.wait(
            lambda: (
                (e := self._last.get("EXTENDED_SYS_STATE")) is not None
                and e.landed_state == LANDED_ON_GROUND
            ),
            "landed",
        )
        self._done("Land")
        # Disarm as the adapter does: the command (it may have disarmed by itself already).
        assert self.command(400, 0) == 0
        self.wait(lambda: not self._last["HEARTBEAT"].base_mode & 128, "disarmed", 60.0)
        self._done("Disarm")
        return self.record

    def _arm(self) -> None:
        assert self.command(400, 1) == 0, "arming refused"
        with self._cond:
            self._t_arm = self._t_boot
        self.record.ends.append(("Arm", 0.0))


# -- the SITLs in ../shared/sitl -----------------------------------------------------------


def sitl_dir() -> tuple[Path | None, str]:
    """The folder of the prebuilt SITLs (``EAMOS_SITL_DIR`` or ``../shared/sitl``), or why not."""
    given = os.environ.get("EAMOS_SITL_DIR")
    root = Path(__file__).resolve().parents[2]
    folder = Path(given) if given else root.parent / "shared" / "sitl"
    if not (folder / "ardupilot" / "arducopter").is_file():
        return None, f"no ArduCopter SITL in {folder} (set EAMOS_SITL_DIR to ../shared/sitl)"
    if not (folder / "px4" / "bin" / "px4").is_file():
        return None, f"no PX4 SITL in {folder} (set EAMOS_SITL_DIR to ../shared/sitl)"
    return folder, ""


def px4_bin(sitl: Path, scratch: Path) -> Path:
    """A ``bin`` folder whose ``px4-*`` commands run the PX4 binary.

    They are symbolic links upstream; a copy of the folder that lost them holds
    3-byte files saying ``px4`` instead, which the start-up script cannot run,
    so the links are made again here (the binary itself is used where it is).
    """
    original = sitl / "px4" / "bin"
    if os.access(original / "px4-param", os.X_OK):
        return original
    made = scratch / "px4-bin"
    made.mkdir(parents=True, exist_ok=True)
    for entry in original.iterdir():
        link = made / entry.name
        if link.exists() or link.is_symlink():
            continue
        if entry.name == "px4":
            link.symlink_to(entry)
        elif entry.name.startswith("px4-") and entry.stat().st_size <= 4:
            link.symlink_to("px4")
        else:
            link.symlink_to(entry)
    return made


@contextmanager
def sitl_vehicle(autopilot: str, instance: int, speedup: float, folder: Path) -> Iterator[str]:
    """Start one SITL instance (6-8 only: others use 0-5) in ``folder``; its connection."""
    assert 6 <= instance <= 8, "these tests use SITL instances 6-8"
    sitl, reason = sitl_dir()
    assert sitl is not None, reason
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    console = (folder / "console.log").open("wb")
    if autopilot == "ardupilot":
        args = [
            str(sitl / "ardupilot" / "arducopter"),
            "--model",
            "+",
            "--speedup",
            str(speedup),
            "-I",
            str(instance),
            "--sysid",
            str(instance + 1),
            "--defaults",
            str(sitl / "ardupilot" / "copter.parm"),
            "--home",
            "-35.363261,149.165230,584,353",
        ]
        env = dict(os.environ)
        connection = f"tcp:127.0.0.1:{5760 + 10 * instance}"
    else:
        args = [str(px4_bin(sitl, folder.parent) / "px4"), "-d", "-i", str(instance)]
        args.append(str(sitl / "px4" / "etc"))
        env = dict(
            os.environ,
            PX4_SYS_AUTOSTART="10040",
            PX4_SIMULATOR="sihsim",
            PX4_SIM_MODEL="sihsim_quadx",
            PX4_SIM_SPEED_FACTOR=str(speedup),
        )
        connection = f"udpin:127.0.0.1:{14540 + instance}"
    proc = subprocess.Popen(args, cwd=folder, env=env, stdout=console, stderr=subprocess.STDOUT)
    try:
        yield connection  # pymavlink's tcp: retries until the SITL listens
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(15)
        console.close()


def load_average() -> float:
    """The machine's one-minute load average (a SITL loses heartbeats far above 2 per core)."""
    return float(Path("/proc/loadavg").read_text().split()[0])
