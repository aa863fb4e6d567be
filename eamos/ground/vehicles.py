"""Simulated MAVLink vehicles for ``eamos run``: hybrid fleets without PX4 or ArduPilot installed.

A drone whose merged ``hal`` settings say ``adapter = "mavlink"`` and
``sim_vehicle = {autopilot = "px4" | "ardupilot", ...}`` gets its own
``eamos-sim-vehicle`` process on a free loopback port, started before the
drone's node; the node's config then carries the matching ``connection``
(PX4 style: the vehicle sends UDP to the node, ``udpin:127.0.0.1:PORT``;
ArduPilot style: the vehicle serves TCP, ``tcp:127.0.0.1:PORT``) and no
``sim_vehicle`` table.  :meth:`SimVehicleFleet.stop` ends the processes.

``sim_vehicle`` keys: ``autopilot`` (required), ``speedup`` (default: the
run's ``--speedup``), ``prearm_delay_s`` (3; ``inf``: never armable),
``disarm_after_s`` (10),
``estimator_settle_s`` and ``estimator_bias_m`` (an estimator that settles late, and
its error until then), ``sysid`` (1), ``home`` ([lat, lon, alt]; default: the drone's
home in the fleet frame, :func:`fleet_lla_homes`), ``reject`` (list of commands,
e.g. ``["MAV_CMD_NAV_LAND=FAILED"]``).  Each vehicle logs to
``<log_dir>/<drone>/sim-vehicle.log`` (its console to ``sim-vehicle.out``).

One home per drone everywhere: every simulated vehicle stands where the fleet file
puts its drone (``home_m``, ``home_lla``, or the default line 5 m apart), in WGS84
around the fleet's origin (the first ``home_lla``, else eamos-sim-vehicle's own
default home), so two of them are as far apart as ``eamos check`` assumes; and
every MAVLink drone's node gets its ``home_m``, its ``home_lla`` and the fleet's
``[safety]`` fence and ceiling (:func:`mavlink_fleet_settings`): the adapter logs the
home in ``adapter.start`` (the monitor, the report and the replay place it there)
and puts the fence on the vehicle.
"""

from __future__ import annotations

import math
import signal
import socket
import subprocess
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from eamos.config import ConfigError
from eamos.hal.api import AdapterError
from eamos.hal.kinematics import GeoFrame
from eamos.hal.mavlink.settings import MavlinkSettings

if TYPE_CHECKING:
    from eamos.config import FleetConfig

#: eamos-sim-vehicle's default home (``--home``): the fleet's origin when no drone
#: has a ``home_lla``.
SIM_VEHICLE_HOME = (46.6103, 14.2640, 450.0)

SIM_VEHICLE_KEYS = frozenset(
    {
        "autopilot",
        "speedup",
        "prearm_delay_s",
        "disarm_after_s",
        "sysid",
        "home",
        "reject",
        "wander_m",  # a wandering position estimate (PX4 SIH-like), with its seed
        "seed",
        "estimator_settle_s",  # when the estimator's flags settle (PX4 default 6 s)
        "estimator_bias_m",  # the unsettled estimate's error at start
        "die_after_s",  # sudden vehicle death after this long in the air
        "signing_key",  # MAVLink 2 signing: the fleet's key file
    }
)


def fleet_lla_homes(fleet: FleetConfig, drones: list[str]) -> dict[str, tuple[float, float, float]]:
    """Each drone's home in WGS84 (lat, lon, alt AMSL), placed as ``fleet.homes`` places it
    in the fleet frame: its ``home_lla``, else its fleet-frame home around the fleet's
    origin (the first ``home_lla`` in ``drones``' order, else :data:`SIM_VEHICLE_HOME`)."""
    homes = fleet.homes(drones)
    lla = [d for d in drones if d in fleet.homes_lla]
    if lla:
        o = fleet.homes_lla[lla[0]]
        origin = GeoFrame(o[0], o[1], o[2] if len(o) > 2 else SIM_VEHICLE_HOME[2])
    else:
        origin = GeoFrame(*SIM_VEHICLE_HOME)
    out = {}
    for d in drones:
        given = fleet.homes_lla.get(d)
        if given is not None:
            out[d] = (given[0], given[1], given[2] if len(given) > 2 else origin.home_alt_m)
        else:
            lat, lon, _ = origin.to_lla(homes[d][0], homes[d][1], 0.0)
            out[d] = (round(lat, 8), round(lon, 8), origin.home_alt_m)
    return out


def mavlink_fleet_settings(fleet: FleetConfig, drone: str, drones: list[str]) -> dict[str, Any]:
    """What a MAVLink drone's node config gets from the fleet file: ``home_m`` (as the
    check places it), ``home_lla`` when the fleet gives one, the ``[safety]`` geofence
    and ceiling (put on the vehicle before its first arming)."""
    out: dict[str, Any] = {"home_m": list(fleet.homes(drones)[drone])}
    if drone in fleet.homes_lla:
        out["home_lla"] = list(fleet.homes_lla[drone])
    if fleet.safety.geofence_m:
        out["geofence_m"] = [list(p) for p in fleet.safety.geofence_m]
    if fleet.safety.max_altitude_m is not None:
        out["max_altitude_m"] = fleet.safety.max_altitude_m
    return out


def free_port(kind: int) -> int:
    """A free loopback port for ``kind`` (``socket.SOCK_DGRAM`` or ``socket.SOCK_STREAM``)."""
    with socket.socket(socket.AF_INET, kind) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@dataclass
class SimVehicleFleet:
    """The simulated vehicles of one run and the node ``hal`` settings that reach them."""

    hals: dict[str, dict[str, Any]]
    procs: dict[str, subprocess.Popen[bytes]] = field(default_factory=dict)

    def hal_for(self, drone: str) -> dict[str, Any]:
        """The ``[hal]`` table to write into ``drone``'s node config."""
        return dict(self.hals[drone])

    def stop(self, timeout_s: float = 10.0) -> None:
        """SIGTERM every vehicle (a clean exit), then SIGKILL what is left."""
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        for proc in self.procs.values():
            try:
                proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout_s)
            if proc.stdin is not None:
                proc.stdin.close()


def _vehicle_args(drone: str, spec: Any, speedup: float | None) -> list[str]:
    """Command-line options of one vehicle from its ``sim_vehicle`` table (validated)."""
    where = f"drones.{drone}.hal.sim_vehicle"
    if not isinstance(spec, Mapping):
        raise ConfigError(f'{where}: must be a table such as {{autopilot = "px4"}}')
    unknown = set(spec) - SIM_VEHICLE_KEYS
    if unknown:
        raise ConfigError(
            f"{where}.{sorted(unknown)[0]}: unknown field; valid: "
            f"{', '.join(sorted(SIM_VEHICLE_KEYS))}"
        )
    autopilot = spec.get("autopilot")
    if autopilot not in ("px4", "ardupilot"):
        raise ConfigError(f'{where}.autopilot: must be "px4" or "ardupilot", got {autopilot!r}')
    args = ["--autopilot", autopilot]

    def number(key: str, low: float, infinite: bool = False) -> float | None:
        value = spec.get(key)
        if value is None:
            return None
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not value >= low
            or not (math.isfinite(value) or infinite)
        ):
            raise ConfigError(f"{where}.{key}: must be a number >= {low:g}, got {value!r}")
        return float(value)

    run_speedup = number("speedup", 1e-9) or speedup
    if run_speedup:
        args += ["--speedup", repr(float(run_speedup))]
    for key, option in (
        ("prearm_delay_s", "--prearm-delay"),
        ("disarm_after_s", "--disarm-after"),
        ("wander_m", "--wander"),
        ("die_after_s", "--die-after"),
        ("estimator_settle_s", "--estimator-settle"),
        ("estimator_bias_m", "--estimator-bias"),
    ):
        # prearm_delay_s = inf: a vehicle that never passes its pre-arm checks (tests).
        value = number(key, 0.0, infinite=key == "prearm_delay_s")
        if value is not None:
            args += [option, repr(value)]
    if "seed" in spec:
        seed = spec["seed"]
        if isinstance(seed, bool) or not isinstance(seed, int):
            raise ConfigError(f"{where}.seed: must be an integer, got {seed!r}")
        args += ["--seed", str(seed)]
    if "signing_key" in spec:
        key_file = spec["signing_key"]
        if not isinstance(key_file, str) or not key_file:
            raise ConfigError(f"{where}.signing_key: must be the path of a key file")
        args += ["--signing-key", key_file]
    if "sysid" in spec:
        sysid = spec["sysid"]
        if isinstance(sysid, bool) or not isinstance(sysid, int) or not 1 <= sysid <= 255:
            raise ConfigError(f"{where}.sysid: must be an integer from 1 to 255, got {sysid!r}")
        args += ["--sysid", str(sysid)]
    if "home" in spec:
        home = spec["home"]
        if (
            not isinstance(home, list | tuple)
            or len(home) != 3
            or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in home)
        ):
            raise ConfigError(f"{where}.home: must be [lat, lon, alt], got {home!r}")
        args += ["--home", ",".join(repr(float(v)) for v in home)]
    if "reject" in spec:
        reject = spec["reject"]
        if (
            isinstance(reject, str)
            or not isinstance(reject, list | tuple)
            or not all(isinstance(v, str) for v in reject)
        ):
            raise ConfigError(f"{where}.reject: must be a list of command names, got {reject!r}")
        if reject:
            args += ["--reject", *reject]
    return args


def start_sim_vehicles(
    hals: Mapping[str, Mapping[str, Any]],
    log_dir: Path,
    speedup: float | None = None,
    homes: Mapping[str, tuple[float, float, float]] | None = None,
) -> SimVehicleFleet:
    """Start an ``eamos-sim-vehicle`` for every drone whose ``hal`` asks for one.

    ``hals`` maps each drone to its merged ``hal`` settings; the result's
    :meth:`SimVehicleFleet.hal_for` gives the settings to write into the
    node's config.  ``homes``: each drone's home in WGS84 (:func:`fleet_lla_homes`),
    a vehicle's home unless its table names one.  Raises
    :class:`~eamos.config.ConfigError` for a bad ``sim_vehicle`` table (no process
    is left running then).
    """
    fleet = SimVehicleFleet({})
    plans: list[tuple[str, list[str], Path]] = []
    for drone, hal in hals.items():
        node_hal = {k: v for k, v in hal.items() if k != "sim_vehicle"}
        fleet.hals[drone] = node_hal
        if "sim_vehicle" not in hal:
            continue
        if hal.get("adapter") != "mavlink":
            raise ConfigError(f'drones.{drone}.hal.sim_vehicle: only for adapter = "mavlink"')
        if "connection" in hal:
            raise ConfigError(
                f"drones.{drone}.hal.connection: leave it out with sim_vehicle "
                "(eamos run picks a free port)"
            )
        args = _vehicle_args(drone, hal["sim_vehicle"], speedup)
        if "--home" not in args and homes is not None and drone in homes:
            args += ["--home", ",".join(repr(float(v)) for v in homes[drone])]
        if "--speedup" in args:
            # The vehicle's clock runs this much faster: the adapter scales its timeouts.
            node_hal.setdefault("speedup", float(args[args.index("--speedup") + 1]))
        if args[1] == "px4":
            # PX4 SITL style: the vehicle sends UDP to the companion's port.
            port = free_port(socket.SOCK_DGRAM)
            args += ["--connection", f"udpout:127.0.0.1:{port}"]
            node_hal["connection"] = f"udpin:127.0.0.1:{port}"
        else:
            # ArduPilot SITL style: the vehicle serves TCP, the companion dials in.
            port = free_port(socket.SOCK_STREAM)
            args += ["--connection", f"tcpin:127.0.0.1:{port}"]
            node_hal["connection"] = f"tcp:127.0.0.1:{port}"
        try:
            # Check the node's settings now, so a typo starts no process at all.
            MavlinkSettings.from_mapping(node_hal)
        except AdapterError as exc:
            raise ConfigError(f"drones.{drone}.{exc}") from exc
        plans.append((drone, args, log_dir / drone))
    for drone, args, folder in plans:
        folder.mkdir(parents=True, exist_ok=True)
        with (folder / "sim-vehicle.out").open("wb") as out:
            fleet.procs[drone] = subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "eamos.cli.sim_vehicle",
                    *args,
                    "--log",
                    str(folder / "sim-vehicle.log"),
                    "--watch-stdin",
                ],
                # A pipe nobody writes to: when eamos run dies, it closes and the vehicle exits.
                stdin=subprocess.PIPE,
                stdout=out,
                stderr=subprocess.STDOUT,
                start_new_session=True,  # Ctrl-C goes to eamos run, which stops us in order
            )
    return fleet


__all__ = [
    "SIM_VEHICLE_HOME",
    "SIM_VEHICLE_KEYS",
    "SimVehicleFleet",
    "fleet_lla_homes",
    "free_port",
    "mavlink_fleet_settings",
    "start_sim_vehicles",
]
