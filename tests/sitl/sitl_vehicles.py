"""Real autopilots for the SITL tier: find the builds, start vehicles, look at them afterwards.

The unmodified ArduCopter and PX4 SITL builds live outside the repository
(``EAMOS_SITL_DIR``, else ``../shared/sitl`` beside the checkout) with their start
script (``start.sh AUTOPILOT INSTANCE DIR SPEEDUP``, which prints the connection string
and writes ``DIR/pid``).  This module:

* finds them (:func:`find_sitl`), or says why not (the tier then skips);
* gives PX4 working command links when the copy lost them (:func:`runnable_sitl`);
* hands out SITL instance numbers 0-9 that no other test worker, nor anyone else on the
  machine, is using (:class:`InstanceLock`: an ``fcntl`` lock per instance under
  ``/tmp``, and the instance's ports free);
* starts a vehicle in a fresh folder and stops it by the pid it wrote, never by name
  (:class:`SitlVehicle`);
* reads a vehicle's parameters, HEARTBEAT and landed state over MAVLink after a run
  (:func:`inspect_vehicle`), and sets parameters before one (:func:`set_params`).
"""

from __future__ import annotations

import fcntl
import os
import select
import shutil
import signal
import socket
import subprocess
import time
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Literal

REPO = Path(__file__).resolve().parents[2]
Autopilot = Literal["arducopter", "px4"]
INSTANCES = range(10)
LOCK_PATTERN = "/tmp/eamos-sitl-instance-{n}.lock"
#: Generous for a loaded 2-core machine.
MAVLINK_WAIT_S = 60.0


def find_sitl() -> tuple[Path | None, str]:
    """The SITL folder (``EAMOS_SITL_DIR`` or ``../shared/sitl``), or None and why not."""
    configured = os.environ.get("EAMOS_SITL_DIR")
    folder = Path(configured) if configured else REPO.parent / "shared" / "sitl"
    where = "EAMOS_SITL_DIR" if configured else "../shared/sitl"
    needed = ("start.sh", "ardupilot/arducopter", "px4/bin/px4", "px4/etc")
    missing = [name for name in needed if not (folder / name).exists()]
    if missing:
        return None, (
            f"no SITL autopilots at {folder} ({where}; missing {', '.join(missing)}): "
            "set EAMOS_SITL_DIR to a folder with start.sh, ardupilot/ and px4/"
        )
    return folder, ""


def _links_work(bin_dir: Path) -> bool:
    link = bin_dir / "px4-param"
    return link.is_symlink() or os.access(link, os.X_OK)


def runnable_sitl(folder: Path, scratch: Path) -> Path:
    """``folder``, or a copy under ``scratch`` whose PX4 command links work.

    PX4's start-up script runs its commands (``px4-param`` ...) as links to the ``px4``
    binary found next to it (its real path).  A copy of the SITL folder that turned
    those links into small text files (``px4``) leaves PX4 without parameters or an
    airframe; then the binary is copied (3.8 MB) beside real links, and the rest of the
    folder is linked, not copied.  Call it under a lock: workers share ``scratch``.
    """
    if _links_work(folder / "px4" / "bin"):
        return folder
    stamp = (folder / "px4" / "bin" / "px4").stat()
    overlay = scratch / f"sitl-{stamp.st_size}-{int(stamp.st_mtime)}"
    if (overlay / "start.sh").exists():
        return overlay
    building = scratch / f"{overlay.name}.building-{os.getpid()}"
    shutil.rmtree(building, ignore_errors=True)
    (building / "px4" / "bin").mkdir(parents=True)
    (building / "ardupilot").symlink_to(folder / "ardupilot")
    (building / "px4" / "etc").symlink_to(folder / "px4" / "etc")
    shutil.copy2(folder / "px4" / "bin" / "px4", building / "px4" / "bin" / "px4")
    for entry in (folder / "px4" / "bin").iterdir():
        if entry.name.startswith("px4-"):
            target = entry if entry.name.endswith(".sh") else Path("px4")
            (building / "px4" / "bin" / entry.name).symlink_to(target)
    # Last: its presence says the overlay is complete.
    (building / "start.sh").symlink_to(folder / "start.sh")
    building.rename(overlay)
    return overlay


@contextmanager
def scratch_lock(scratch: Path) -> Iterator[None]:
    """Exclusive use of ``scratch`` between test workers (an ``fcntl`` lock)."""
    scratch.mkdir(parents=True, exist_ok=True)
    with open(scratch / "lock", "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def instance_ports(n: int) -> tuple[list[int], list[int]]:
    """(TCP ports, UDP ports) SITL instance ``n`` uses (start.sh's header)."""
    tcp = [5760 + 10 * n, 5762 + 10 * n, 5763 + 10 * n]
    udp = [14540 + n, 14580 + n, 18570 + n, 14280 + n, 13030 + n, 19450 + n]
    return tcp, udp


def _ports_free(n: int) -> bool:
    tcp, udp = instance_ports(n)
    for kind, ports in ((socket.SOCK_STREAM, tcp), (socket.SOCK_DGRAM, udp)):
        for port in ports:
            with socket.socket(socket.AF_INET, kind) as s:
                try:
                    s.bind(("127.0.0.1", port))
                except OSError:
                    return False
    return True


class InstanceLock:
    """One SITL instance number held for as long as the lock is open (module docstring)."""

    def __init__(self, n: int, handle: IO[str]) -> None:
        self.n = n
        self._handle = handle

    @classmethod
    def take(cls) -> InstanceLock:
        """The first free instance 0-9; RuntimeError when all are taken."""
        for n in INSTANCES:
            handle = open(LOCK_PATTERN.format(n=n), "a")  # noqa: SIM115 (held until release)
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                handle.close()
                continue
            if _ports_free(n):
                return cls(n, handle)
            handle.close()  # someone else's vehicle (not ours: it holds no lock)
        raise RuntimeError("every SITL instance 0-9 is in use")

    def release(self) -> None:
        """Let other workers have the instance."""
        with suppress(OSError):
            fcntl.flock(self._handle, fcntl.LOCK_UN)
        self._handle.close()


@dataclass
class SitlVehicle:
    """One running SITL vehicle: its instance, folder, connection string and pid."""

    autopilot: Autopilot
    instance: InstanceLock
    folder: Path
    connection: str
    pid: int
    speedup: float
    stopped: bool = field(default=False)

    @property
    def system_id(self) -> int:
        """start.sh gives instance N system id N + 1."""
        return self.instance.n + 1

    @property
    def console(self) -> str:
        """What the autopilot printed so far (``console.log``)."""
        return (self.folder / "console.log").read_text(errors="replace")

    def alive(self) -> bool:
        """The process still runs."""
        try:
            os.kill(self.pid, 0)
        except ProcessLookupError:
            return False
        return True

    def kill_process(self, grace_s: float = 10.0) -> None:
        """SIGTERM by the pid in ``DIR/pid`` (never by name), SIGKILL after ``grace_s``;
        returns once the process is gone."""
        try:
            pidfd = os.pidfd_open(self.pid)
        except ProcessLookupError:
            return
        try:
            for sig in (signal.SIGTERM, signal.SIGKILL):
                with suppress(ProcessLookupError):
                    os.kill(self.pid, sig)
                if select.select([pidfd], [], [], grace_s)[0]:
                    break
        finally:
            os.close(pidfd)

    def stop(self) -> None:
        """Kill the vehicle (:meth:`kill_process`) and free its instance number."""
        if self.stopped:
            return
        self.stopped = True
        try:
            self.kill_process()
        finally:
            self.instance.release()


def _start_sh(sitl: Path, autopilot: Autopilot, n: int, folder: Path, speedup: float) -> str:
    out = subprocess.run(
        [str(sitl / "start.sh"), autopilot, str(n), str(folder), f"{speedup:g}"],
        capture_output=True,
        text=True,
        check=True,
        timeout=30,
    )
    return out.stdout.strip()


def start_vehicle(
    sitl: Path,
    autopilot: Autopilot,
    folder: Path,
    speedup: float,
    params: Mapping[str, float] | None = None,
) -> SitlVehicle:
    """Start one vehicle with ``start.sh`` in the fresh folder ``folder``.

    ``params`` are set over MAVLink and the vehicle started again in the same folder
    (both autopilots keep them there), as a user configures a vehicle: a camera or a
    mount (ArduPilot ``CAM1_TYPE``, ``MNT1_TYPE``) exists only after a reboot.
    """
    lock = InstanceLock.take()
    try:
        folder.mkdir(parents=True, exist_ok=False)
        connection = _start_sh(sitl, autopilot, lock.n, folder, speedup)
        pid = int((folder / "pid").read_text().strip())
        vehicle = SitlVehicle(autopilot, lock, folder, connection, pid, speedup)
        if params:
            set_params(vehicle, params)
            vehicle.kill_process()
            _start_sh(sitl, autopilot, lock.n, folder, speedup)
            vehicle.pid = int((folder / "pid").read_text().strip())
    except BaseException:
        lock.release()
        raise
    return vehicle


# -- looking at a vehicle over MAVLink (tests only: pymavlink, blocking reads) -----------


def _connect(vehicle: SitlVehicle) -> Any:
    os.environ.setdefault("MAVLINK20", "1")
    from pymavlink import mavutil

    conn = mavutil.mavlink_connection(vehicle.connection, source_system=250, source_component=190)
    conn.wait_heartbeat(timeout=MAVLINK_WAIT_S)
    return conn


def _recv(conn: Any, kind: str, vehicle: SitlVehicle, timeout: float) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        msg = conn.recv_match(type=kind, blocking=True, timeout=0.5)
        if msg is not None and msg.get_srcSystem() == vehicle.system_id:
            return msg
    raise TimeoutError(
        f"{vehicle.autopilot} {vehicle.instance.n}: no {kind} in {timeout:g} s; "
        + process_report(vehicle.pid, vehicle.folder)
    )


def process_report(pid: int, folder: Path, lines: int = 15) -> str:
    """Whether the vehicle's process still runs, and the end of its ``console.log``: what a
    silent vehicle's failure message should show (2 of 5 CI runs heard no HEARTBEAT from a
    PX4 after its adapter let go, and left nothing to tell why)."""
    try:
        os.kill(pid, 0)
        state = f"process {pid} running"
    except ProcessLookupError:
        state = f"process {pid} gone"
    try:
        tail = (folder / "console.log").read_text(errors="replace").splitlines()[-lines:]
    except OSError as exc:
        tail = [f"(no console.log: {exc})"]
    return state + "; console.log ends:\n" + "\n".join(tail)


def _param_value(msg: Any, bytewise: bool) -> float:
    import struct

    if bytewise and msg.param_type in range(1, 9):
        return float(struct.unpack("<i", struct.pack("<f", msg.param_value))[0])
    return float(msg.param_value)


def _read_param(conn: Any, vehicle: SitlVehicle, name: str) -> float:
    for _ in range(5):
        conn.mav.param_request_read_send(vehicle.system_id, 1, name.encode(), -1)
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline:
            msg = conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.5)
            if msg is not None and msg.param_id == name:
                return _param_value(msg, vehicle.autopilot == "px4")
    raise TimeoutError(f"{vehicle.autopilot}: no PARAM_VALUE for {name}")


def param_save_failures(autopilot: str, folder: Path) -> list[str]:
    """PX4's complaints about saving its parameters in ``folder/console.log`` (``verify:
    ...``, ``parameter export ... failed``): a PARAM_SET that landed while PX4 wrote and read
    back its parameter file.  PX4 SITL has been seen to stall for good after one."""
    if autopilot != "px4":
        return []
    console = (folder / "console.log").read_text(errors="replace")
    return [
        line
        for line in console.splitlines()
        if "verify:" in line or "parameter export" in line or "param auto save failed" in line
    ]


@dataclass(frozen=True)
class VehicleState:
    """What a vehicle says about itself after a run."""

    armed: bool
    landed_state: int | None  # EXTENDED_SYS_STATE (1: on the ground)
    relative_alt_m: float  # GLOBAL_POSITION_INT
    params: dict[str, float]


def inspect_vehicle(vehicle: SitlVehicle, params: Iterable[str] = ()) -> VehicleState:
    """Connect (the run's node has let go), read the HEARTBEAT, landed state, height and
    ``params``."""
    conn = _connect(vehicle)
    try:
        for msg_id in (245, 33):  # EXTENDED_SYS_STATE, GLOBAL_POSITION_INT at 4 Hz
            conn.mav.command_long_send(vehicle.system_id, 1, 511, 0, msg_id, 250_000, 0, 0, 0, 0, 0)
        beat = _recv(conn, "HEARTBEAT", vehicle, MAVLINK_WAIT_S)
        extended = _recv(conn, "EXTENDED_SYS_STATE", vehicle, 10.0)
        where = _recv(conn, "GLOBAL_POSITION_INT", vehicle, 10.0)
        values = {name: _read_param(conn, vehicle, name) for name in params}
    finally:
        conn.close()
    return VehicleState(
        armed=bool(beat.base_mode & 128),
        landed_state=extended.landed_state,
        relative_alt_m=where.relative_alt / 1000.0,
        params=values,
    )


def set_params(vehicle: SitlVehicle, values: Mapping[str, float]) -> None:
    """PARAM_SET each of ``values`` (ArduPilot: REAL32 casts) and see it echoed."""
    conn = _connect(vehicle)
    try:
        for name, value in values.items():
            for _ in range(5):
                conn.mav.param_set_send(vehicle.system_id, 1, name.encode(), value, 9)
                msg = conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=3.0)
                while msg is not None and msg.param_id != name:
                    msg = conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=3.0)
                if msg is not None and abs(msg.param_value - value) < 1e-3:
                    break
            else:
                raise RuntimeError(f"{name} = {value} not taken")
    finally:
        conn.close()
