"""A fleet of local processes for ``eamos run``: one ``eamos-node`` per drone, on loopback.

:func:`fly_local` takes a compiled mission's programs (already in the run
folder's ``programs/``), writes one node config per drone (simulated by
default; a fleet file may pick other adapters, and MAVLink drones get a
simulated vehicle each), starts every drone as its own process, and is their
ground station through :func:`~eamos.ground.flight.fly`.  Ctrl-C (the ``stop``
event) aborts: every drone lands, then the processes end.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from eamos.actors.runtime import NetSettings
from eamos.config import ConfigError, FleetConfig, NodeConfig
from eamos.hal import AdapterError, make_adapter
from eamos.logs import make_logger
from eamos.net.keys import FleetKeys, create_fleet_keys
from eamos.program.format import DroneProgram
from eamos.program.uniform import GROUND_STATION

from .display import Display, make_display
from .flight import Limits, fly, ground_runtime
from .station import GroundStation
from .summary import RunSummary, summarize
from .vehicles import start_sim_vehicles

#: The command line of one drone's node (``eamos-node`` in this Python).
NODE_MODULE = "eamos.cli.node"


def free_ports(n: int) -> list[int]:
    """``n`` distinct free TCP ports on loopback."""
    socks = []
    try:
        for _ in range(n):
            s = socket.socket()
            s.bind(("127.0.0.1", 0))
            socks.append(s)
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


def check_hal_settings(drone: str, hal: Mapping[str, Any], fleet_path: Path | None) -> None:
    """Validate a drone's hardware settings before any process starts (ConfigError if bad)."""
    try:
        adapter = make_adapter(drone, hal, make_logger(None))
    except AdapterError as exc:
        where = f"{fleet_path}: drones.{drone}." if fleet_path else f"{drone}: "
        raise ConfigError(f"{where}{exc}") from exc
    adapter.close()


def last_line(path: Path) -> str:
    """The last non-empty line of a text file ("" when there is none)."""
    try:
        lines = [ln for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    except OSError:
        return ""
    return lines[-1] if lines else ""


@dataclass
class _Proc:
    name: str
    popen: subprocess.Popen[bytes]
    exit_code: int | None = None


class LocalFleet:
    """The drone processes of one run, watched by a thread each."""

    def __init__(self, on_exit: Callable[[str, int], None]) -> None:
        self.procs: dict[str, _Proc] = {}
        self.on_exit = on_exit

    def spawn(self, name: str, config: Path, log_dir: Path) -> None:
        """Start ``eamos-node --config config``; its output goes to ``log_dir/node.out``."""
        log_dir.mkdir(parents=True, exist_ok=True)
        out = (log_dir / "node.out").open("wb")
        env = dict(os.environ)
        env.setdefault("PYTHONUNBUFFERED", "1")
        popen = subprocess.Popen(
            [sys.executable, "-m", NODE_MODULE, "--config", str(config)],
            stdout=out,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            env=env,
            start_new_session=True,  # Ctrl-C reaches the ground station only; it lands everyone
        )
        out.close()
        proc = _Proc(name, popen)
        self.procs[name] = proc
        threading.Thread(
            target=self._watch, args=(proc,), name=f"watch-{name}", daemon=True
        ).start()

    def _watch(self, proc: _Proc) -> None:
        proc.exit_code = proc.popen.wait()
        self.on_exit(proc.name, proc.exit_code)

    def wait(self, timeout_s: float) -> bool:
        """Wait until every process ended; False on timeout."""
        deadline = time.monotonic() + timeout_s
        for proc in self.procs.values():
            remaining = max(0.0, deadline - time.monotonic())
            try:
                proc.popen.wait(remaining)
            except subprocess.TimeoutExpired:
                return False
        return True

    def terminate(self) -> None:
        """SIGTERM (the node lands and exits), then SIGKILL what is left."""
        for proc in self.procs.values():
            if proc.popen.poll() is None:
                proc.popen.send_signal(signal.SIGTERM)
        if not self.wait(20):
            for proc in self.procs.values():
                if proc.popen.poll() is None:
                    proc.popen.kill()
            self.wait(10)


@dataclass(frozen=True)
class LocalMission:
    """A compiled mission to fly here: its programs are in ``run_dir/programs/``."""

    name: str
    mission_id: str
    programs: Mapping[str, DroneProgram]  # by participant, ground station included


def write_node_configs(
    run_dir: Path,
    endpoints: Mapping[str, str],
    hals: Mapping[str, dict[str, Any]],
    ready_timeout_s: float,
) -> dict[str, Path]:
    """One ``configs/<Drone>.toml`` per drone of ``hals`` (paths relative to it); their paths."""
    configs: dict[str, Path] = {}
    for name, hal in hals.items():
        config = NodeConfig(
            path=run_dir / "configs" / f"{name}.toml",
            drone=name,
            program=run_dir / "programs" / f"{name}.program.json",
            log_dir=run_dir / "logs" / name,
            bind=endpoints[name],
            peers={n: e for n, e in endpoints.items() if n != name},
            hal=dict(hal),
            ready_timeout_s=ready_timeout_s,
            keys_dir=run_dir / "keys" / name,
        )
        configs[name] = config.write()
    return configs


def fly_local(
    mission: LocalMission,
    run_dir: Path,
    fleet: FleetConfig,
    limits: Limits,
    stop: threading.Event,
    *,
    speedup: float | None = None,
    display: Display | None = None,
) -> RunSummary:
    """Fly ``mission`` with one process per drone; return the summary (also written).

    ``display`` defaults to a live table on a terminal, plain lines otherwise.
    """
    names = list(mission.programs)
    drones = [n for n in names if n != GROUND_STATION]
    endpoints = {
        n: f"tcp://127.0.0.1:{p}" for n, p in zip(names, free_ports(len(names)), strict=True)
    }
    # A fresh CURVE key pair per participant for every run: the links are
    # encrypted and only this run's participants can connect (docs/network.md).
    create_fleet_keys(run_dir / "keys", names, force=True)
    # MAVLink simulated vehicles (hal.sim_vehicle) start first; their nodes get the connection.
    vehicles = start_sim_vehicles({n: fleet.hal_for(n) for n in drones}, run_dir / "logs", speedup)
    hals: dict[str, dict[str, Any]] = {}
    try:
        for name in drones:
            hal = vehicles.hal_for(name)
            if speedup is not None and hal.get("adapter", "sim") == "sim":
                hal["speedup"] = speedup
            check_hal_settings(name, hal, fleet.path)
            hals[name] = hal
    except ConfigError:
        vehicles.stop()
        raise
    configs = write_node_configs(run_dir, endpoints, hals, limits.ready_timeout_s)
    shown = display or make_display(None, drones)
    station = GroundStation(drones, mission.mission_id, on_change=shown.event)
    shown.watch(station)
    ground_hal: dict[str, Any] = {"adapter": "ground"}
    if speedup:
        ground_hal["speedup"] = speedup
    runtime = ground_runtime(
        mission.programs[GROUND_STATION],
        station,
        NetSettings(
            endpoints[GROUND_STATION],
            {n: endpoints[n] for n in drones},
            keys=FleetKeys.load(run_dir / "keys" / GROUND_STATION, GROUND_STATION),
        ),
        run_dir / "logs" / GROUND_STATION,
        ground_hal,
    )
    exits: dict[str, int] = {}

    def on_exit(name: str, code: int) -> None:
        exits[name] = code
        view = station.snapshot().get(name)
        if view is not None and view.report is None:
            why = last_line(run_dir / "logs" / name / "node.out")
            station.fail(name, f"process exited with code {code}" + (f": {why}" if why else ""))

    processes = LocalFleet(on_exit)
    started = time.time()
    outcome = "ok"
    try:
        runtime.start()
        station.attach(runtime)
        for name in drones:
            processes.spawn(name, configs[name], run_dir / "logs" / name)
        with shown:
            shown.say(f"mission {mission.name}: {len(drones)} drone(s), run folder {run_dir}")
            flight = fly(
                station, shown, stop, limits, alive=lambda: [n for n in drones if n not in exits]
            )
            outcome, started = flight.outcome, flight.started
    finally:
        if not processes.wait(30):
            processes.terminate()
        vehicles.stop()
        gcs_report = runtime.drone_report() if runtime.executive is not None else None
        runtime.stop()
    summary = summarize(
        mission.name,
        mission.mission_id,
        outcome,
        started,
        time.time(),
        run_dir,
        station.snapshot(),
        drones,
        list(station.failures),
        gcs_report,
        exits=exits,
    )
    summary.write(run_dir / "summary.json")
    return summary
