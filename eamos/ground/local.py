"""A fleet of local processes for ``eamos run``: ``eamos-node`` processes on loopback.

:func:`fly_local` takes a compiled mission's programs (already in the run
folder's ``programs/``), writes one node config per drone (simulated by
default; a fleet file may pick other adapters, and MAVLink drones get a
simulated vehicle each), starts the drones as processes (by default about one
per CPU core, ``drones_per_process`` drones sharing one, :func:`process_groups`;
1: one process per drone), and is their ground station through
:func:`~eamos.ground.flight.fly`.  Ctrl-C (the ``stop`` event) aborts: every
drone lands, then the processes end.
"""

from __future__ import annotations

import os
import secrets
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from eamos.actors.runtime import NetSettings
from eamos.actors.wiring import connected_peers
from eamos.config import (
    EXIT_CODE_FILE,
    ConfigError,
    FleetConfig,
    NodeConfig,
    fleet_order,
    in_range,
)
from eamos.hal import AdapterError, make_adapter
from eamos.logs import make_logger
from eamos.net.keys import FleetKeys, create_fleet_keys
from eamos.net.settings import LinkSettings
from eamos.program.format import DroneProgram
from eamos.program.uniform import GROUND_STATION

from .display import Display, make_display
from .flight import Limits, fly, ground_runtime, hurried
from .lookahead import Forecast
from .station import GroundStation
from .summary import RunSummary, summarize
from .vehicles import fleet_lla_homes, mavlink_fleet_settings, start_sim_vehicles

#: The command line of one drone's node (``eamos-node`` in this Python).
NODE_MODULE = "eamos.cli.node"


def new_deployment_id() -> str:
    """A fresh id for one run or roll-out (16 hex digits, random): its Start names it, and
    its nodes start only on that Start (a ground station of another run cannot start them)."""
    return secrets.token_hex(8)


def free_ports(n: int) -> list[int]:
    """``n`` distinct free TCP ports on loopback (free now: see :class:`PortReservation`)."""
    with PortReservation(n) as reserved:
        return list(reserved.ports)


class PortReservation:
    """``n`` loopback ports held until :meth:`release`, yet bindable by ZeroMQ meanwhile.

    A port found free and closed at once can be taken by anyone before the node
    binds it (five ``eamos run`` started together did).  Each port here stays
    bound by a socket with ``SO_REUSEADDR`` that never listens: the kernel gives
    it to no other automatic bind, a plain ``bind`` elsewhere fails, and the one
    ZeroMQ listener (which sets ``SO_REUSEADDR`` too) binds it as intended.
    """

    def __init__(self, n: int) -> None:
        self._socks: list[socket.socket] = []
        try:
            for _ in range(n):
                sock = socket.socket()
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                sock.bind(("127.0.0.1", 0))
                self._socks.append(sock)
        except OSError:
            self.release()
            raise
        self.ports: tuple[int, ...] = tuple(s.getsockname()[1] for s in self._socks)

    def release(self) -> None:
        """Let the ports go (once every listener is bound, or the run is over)."""
        for sock in self._socks:
            sock.close()
        self._socks = []

    def __enter__(self) -> PortReservation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


#: Where ``eamos run`` puts its run folders by default, and the ``latest`` link in it.
RUNS_ROOT = Path("runs")
LATEST = "latest"
_MAX_NAME = 120  # characters of the mission's name kept in a folder name (NAME_MAX is 255 bytes)


def new_run_dir(
    mission: str, root: Path = RUNS_ROOT, *, now: time.struct_time | None = None
) -> Path:
    """Create and return a fresh ``root/<mission>-<date-time>[-N]/`` folder, never a used one.

    The folder is made with ``mkdir`` without ``exist_ok``, so of runs started in
    the same second each gets its own (``-2``, ``-3``, ... on a collision): no run
    writes into another's configs or keys.  ``eamos run`` and ``eamos rollout``
    both name their folders here.
    """
    stamp = time.strftime("%Y%m%d-%H%M%S", now or time.localtime())
    base = f"{mission[:_MAX_NAME]}-{stamp}"
    use_run_dir(root, "the runs folder")
    for n in range(1, 10_000):
        folder = root / (base if n == 1 else f"{base}-{n}")
        try:
            folder.mkdir()
        except FileExistsError:
            continue
        return folder
    raise ConfigError(f"{root}: no free run folder name for {base}")


def use_run_dir(path: Path, option: str = "--run-dir") -> Path:
    """Make the run folder ``path`` (and its parents) if needed; ConfigError if it cannot be one.

    A file in the way (``--run-dir`` naming a file) or a folder we may not write is
    bad input, said with the option and the path, not an internal error.
    """
    try:
        path.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        blocker = next((p for p in (path, *path.parents) if p.exists() and not p.is_dir()), path)
        raise ConfigError(f"{option} {path}: {blocker} is a file, not a folder") from None
    except OSError as exc:
        raise ConfigError(f"{option} {path}: cannot make the folder: {exc.strerror}") from None
    return path


def link_latest(run_dir: Path, root: Path = RUNS_ROOT) -> Path | None:
    """Point ``root/latest`` at ``run_dir`` (replaced atomically); the link, or None.

    A relative link, so the runs folder can be moved or copied whole.  Nothing is
    replaced when ``root/latest`` is something other than a link (someone's folder).
    """
    link = root / LATEST
    if link.exists() and not link.is_symlink():
        return None
    target = os.path.relpath(Path(run_dir).resolve(), Path(root).resolve())
    temp = root / f".{LATEST}.{os.getpid()}.{threading.get_ident()}"
    try:
        temp.unlink(missing_ok=True)
        temp.symlink_to(target, target_is_directory=True)
        os.replace(temp, link)  # rename(2): readers see the old or the new link, never none
    except OSError:
        temp.unlink(missing_ok=True)
        return None
    return link


def fresh_keys_folder(run_dir: Path) -> Path:
    """A new, empty ``run_dir/keys`` for this run's keys; the keys of a run before moved aside.

    Keys are never overwritten in place: when a run folder is used again
    (``--run-dir``), the last run's ``keys`` folder is renamed to ``keys.old``
    (``keys.old-2``, ...) first.  ``keys`` appearing meanwhile means another run
    is using the same folder: refused.
    """
    keys = run_dir / "keys"
    if keys.exists() or keys.is_symlink():
        os.replace(keys, fresh_folder(run_dir / "keys.old"))  # onto an empty folder: atomic
    try:
        keys.mkdir()
    except FileExistsError:
        raise ConfigError(f"{run_dir}: another run is using this run folder") from None
    return keys


def fresh_folder(path: Path) -> Path:
    """Create ``path`` (or ``path-2``, ``path-3``, ... if taken) atomically; return it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    for n in range(1, 10_000):
        folder = path if n == 1 else path.with_name(f"{path.name}-{n}")
        try:
            folder.mkdir()
        except FileExistsError:
            continue
        return folder
    raise ConfigError(f"{path}: no free folder name")


def check_hal_settings(drone: str, hal: Mapping[str, Any], fleet_path: Path | None) -> None:
    """Validate a drone's hardware settings before any process starts (ConfigError if bad)."""
    try:
        adapter = make_adapter(drone, hal, make_logger(None))
    except AdapterError as exc:
        where = f"{fleet_path}: drones.{drone}." if fleet_path else f"{drone}: "
        raise ConfigError(f"{where}{exc}") from exc
    adapter.close()


def last_line(path: Path, about: str = "") -> str:
    """The last non-empty line of a text file containing ``about`` ("" when there is none)."""
    try:
        lines = [
            ln for ln in path.read_text(errors="replace").splitlines() if ln.strip() and about in ln
        ]
    except OSError:
        return ""
    return lines[-1] if lines else ""


def process_groups(
    drones: list[str], per_process: int | None, alone: Iterable[str] = ()
) -> list[list[str]]:
    """The drones each process runs, in mission order: ``per_process`` at most per process.

    ``None`` (automatic): about one process per CPU core, each drone's
    runtime a thread of it; the drones in ``alone`` (those with a vehicle of
    their own, which may fail to connect) then get a process each, so that
    one failing to start is reported at once, not when its process-mates give
    up.  ``1``: one process per drone (a drone killed alone, as the fault tests do).
    """
    if per_process is not None and per_process < 1:
        raise ConfigError(f"--drones-per-process {per_process}: must be at least 1")
    if per_process is not None:
        return [drones[i : i + per_process] for i in range(0, len(drones), per_process)]
    single = set(alone)
    shared = [d for d in drones if d not in single]
    cores = os.cpu_count() or 1
    size = max(1, -(-len(shared) // cores))
    groups = [shared[i : i + size] for i in range(0, len(shared), size)]
    groups += [[d] for d in drones if d in single]
    first = {d: i for i, d in enumerate(drones)}
    return sorted(groups, key=lambda g: first[g[0]])


def telemetry_readers(programs: Mapping[str, DroneProgram]) -> set[str]:
    """The drones whose telemetry a condition of another participant reads (``telemetry_from``).

    The ground station's own conditions count: they need the peers' rate too.
    """
    return {
        read
        for name, program in programs.items()
        for read in program.telemetry_from
        if read != name
    }


def telemetry_links(
    programs: Mapping[str, DroneProgram], drones: list[str], fleet: FleetConfig
) -> dict[str, LinkSettings]:
    """Each drone's link settings: its outgoing telemetry rate from the fleet file.

    Only the ground station reads a drone's telemetry: ``[net] ground_telemetry_hz``
    (the newest sample, a burst coalesced by the link); another drone's conditions
    read it too: the peers' rate (:meth:`FleetConfig.telemetry_hz`).
    """
    read = telemetry_readers(programs)
    return {d: LinkSettings(telemetry_max_hz=fleet.telemetry_hz(d in read)) for d in drones}


def exit_reason(code: int, group: tuple[str, ...], why: str = "") -> str:
    """Why a drone without a report failed: its process ended with ``code``.

    Said for each drone of a shared process (``group``, its drones), so the
    operator sees why they all failed at once; ``why`` is the last line of the
    process's output about the drone.
    """
    shared = f" (shared by {', '.join(group)})" if len(group) > 1 else ""
    return f"process exited with code {code}{shared}" + (f": {why}" if why else "")


@dataclass
class _Proc:
    name: str  # the process's first drone
    popen: subprocess.Popen[bytes]
    drones: tuple[str, ...] = ()
    exit_code: int | None = None


class LocalFleet:
    """The drone processes of one run, watched by a thread each.

    ``on_exit(drone, code)`` is called for each drone of a process when it ends:
    with the drone's own exit code when it shared the process (``exit_code``
    in its log folder), else the process's.
    """

    def __init__(self, on_exit: Callable[[str, int], None]) -> None:
        self.procs: dict[str, _Proc] = {}
        self.on_exit = on_exit
        self.log_dirs: dict[str, Path] = {}
        self.outputs: dict[str, Path] = {}  # drone -> its process's node.out
        self.groups: dict[str, tuple[str, ...]] = {}  # drone -> the drones of its process

    def spawn(self, name: str, config: Path, log_dir: Path) -> None:
        """Start ``eamos-node --config config``; its output goes to ``log_dir/node.out``."""
        self.spawn_group({name: config}, {name: log_dir}, log_dir / "node.out")

    def spawn_group(
        self, configs: Mapping[str, Path], log_dirs: Mapping[str, Path], out_path: Path
    ) -> None:
        """Start one ``eamos-node`` running the drones of ``configs``; output to ``out_path``."""
        names = list(configs)
        out_path.parent.mkdir(parents=True, exist_ok=True)
        for name in names:
            log_dirs[name].mkdir(parents=True, exist_ok=True)
            (log_dirs[name] / EXIT_CODE_FILE).unlink(missing_ok=True)  # a run before's, if reused
            self.log_dirs[name] = log_dirs[name]
            self.outputs[name] = out_path
            self.groups[name] = tuple(names)
        out = out_path.open("wb")
        env = dict(os.environ)
        env.setdefault("PYTHONUNBUFFERED", "1")
        argv = [sys.executable, "-m", NODE_MODULE]
        for name in names:
            argv += ["--config", str(configs[name])]
        popen = subprocess.Popen(
            argv,
            stdout=out,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            env=env,
            start_new_session=True,  # Ctrl-C reaches the ground station only; it lands everyone
        )
        out.close()
        proc = _Proc(names[0], popen, tuple(names))
        self.procs[names[0]] = proc
        threading.Thread(
            target=self._watch, args=(proc,), name=f"watch-{names[0]}", daemon=True
        ).start()

    def _watch(self, proc: _Proc) -> None:
        proc.exit_code = proc.popen.wait()
        for name in proc.drones:
            own = None
            if len(proc.drones) > 1:
                try:
                    own = int((self.log_dirs[name] / EXIT_CODE_FILE).read_text().strip())
                except (OSError, ValueError):
                    own = None  # it never finished: the process's code says why
            self.on_exit(name, proc.exit_code if own is None else own)

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


def running(station: GroundStation, drones: list[str]) -> list[str]:
    """The drones whose node runs: not exited, or exited and rejoined by a new node."""
    views = station.snapshot()
    return [n for n in drones if not views[n].exited]


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
    keys_dir: Path | None = None,
    peers_of: Mapping[str, list[str]] | None = None,
    battery_reserve_pct: float | None = None,
    links: Mapping[str, LinkSettings] | None = None,
    deployment: str = "",
) -> dict[str, Path]:
    """One ``configs/<Drone>.toml`` per drone of ``hals`` (paths relative to it); their paths.

    ``keys_dir`` holds the run's keys (default ``run_dir/keys``).  ``peers_of``
    names each drone's peers (:func:`~eamos.actors.wiring.connected_peers`);
    default every other participant.  ``battery_reserve_pct``: the fleet's
    ``[safety]`` reserve, below which a Try's Body action fails.  ``links``:
    each drone's link settings (:func:`telemetry_links`; default the built-in ones).
    ``deployment``: this run's id (:func:`new_deployment_id`): the drones start only
    on the Start naming it.
    """
    keys_root = keys_dir or run_dir / "keys"
    configs: dict[str, Path] = {}
    for name, hal in hals.items():
        config = NodeConfig(
            path=run_dir / "configs" / f"{name}.toml",
            drone=name,
            program=run_dir / "programs" / f"{name}.program.json",
            log_dir=run_dir / "logs" / name,
            bind=endpoints[name],
            peers={
                n: e
                for n, e in endpoints.items()
                if n != name and (peers_of is None or n in peers_of[name])
            },
            hal=dict(hal),
            ready_timeout_s=ready_timeout_s,
            keys_dir=keys_root,  # the run's one folder (FleetKeys.load finds name's in it)
            battery_reserve_pct=battery_reserve_pct,
            link=links[name] if links is not None and name in links else LinkSettings(),
            deployment=deployment,
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
    drones_per_process: int | None = None,
    forecast: Forecast | None = None,
) -> RunSummary:
    """Fly ``mission`` with drones as local processes; return the summary (also written).

    ``display`` defaults to a live table on a terminal, plain lines otherwise.
    ``drones_per_process`` drones share one process (None, the default: about
    one process per core; 1: one process per drone).  ``forecast``: the live look-ahead's,
    used when the fleet's ``[look_ahead] period_s`` is above 0 (:mod:`.lookahead`).
    Before anything starts, a fleet table for a drone not in the mission and a
    ready timeout a drone's config cannot hold are refused (ConfigError).
    """
    names = list(mission.programs)
    drones = [n for n in names if n != GROUND_STATION]
    fleet.check_drones(drones)
    # The drones' configs must load: an option beyond a config's range is refused here.
    in_range("--ready-timeout", limits.ready_timeout_s, "ready_timeout_s")
    # Drones with a vehicle of their own (not simulated here) each get a process.
    own_vehicle = [d for d in drones if fleet.hal_for(d).get("adapter", "sim") != "sim"]
    groups = process_groups(drones, drones_per_process, alone=own_vehicle)
    # The ports stay reserved until the run is over (see PortReservation).
    ports = PortReservation(len(names))
    try:
        return _fly_local(
            mission, run_dir, fleet, limits, stop, ports.ports, speedup, display, groups, forecast
        )
    finally:
        ports.release()


def _fly_local(
    mission: LocalMission,
    run_dir: Path,
    fleet: FleetConfig,
    limits: Limits,
    stop: threading.Event,
    ports: tuple[int, ...],
    speedup: float | None,
    display: Display | None,
    groups: list[list[str]],
    forecast: Forecast | None = None,
) -> RunSummary:
    names = list(mission.programs)
    drones = [n for n in names if n != GROUND_STATION]
    endpoints = {n: f"tcp://127.0.0.1:{p}" for n, p in zip(names, ports, strict=True)}
    # A fresh CURVE key pair per participant for every run: the links are
    # encrypted and only this run's participants can connect (docs/network.md).
    keys_dir = create_fleet_keys(fresh_keys_folder(run_dir), names, shipped=False)
    # MAVLink simulated vehicles (hal.sim_vehicle) start first; their nodes get the connection.
    # Every drone stands at its home in the fleet frame, as the check saw it: simulated
    # drones and simulated MAVLink vehicles are placed there; a MAVLink drone's node is
    # told where, and the fleet's fence (vehicles.py).
    order = fleet_order(mission.programs)
    homes = fleet.homes(order)
    vehicles = start_sim_vehicles(
        {n: fleet.hal_for(n) for n in drones},
        run_dir / "logs",
        speedup,
        homes=fleet_lla_homes(fleet, order),
    )
    hals: dict[str, dict[str, Any]] = {}
    try:
        for name in drones:
            hal = vehicles.hal_for(name)
            if hal.get("adapter", "sim") == "sim":
                hal["home_m"] = list(homes[name])
                if speedup is not None:
                    hal["speedup"] = speedup
            elif hal.get("adapter") == "mavlink":
                hal = {**mavlink_fleet_settings(fleet, name, order), **hal}
            check_hal_settings(name, hal, fleet.path)
            hals[name] = hal
    except ConfigError:
        vehicles.stop()
        raise
    # Each drone connects only to the peers it works with and the ground station.
    peers_of = connected_peers(dict(mission.programs))
    deployment = new_deployment_id()
    configs = write_node_configs(
        run_dir,
        endpoints,
        hals,
        limits.ready_timeout_s,
        keys_dir,
        peers_of,
        battery_reserve_pct=fleet.safety.battery_reserve_pct,
        links=telemetry_links(mission.programs, drones, fleet),
        deployment=deployment,
    )
    shown = display or make_display(None, drones)
    station = GroundStation(
        drones,
        mission.mission_id,
        on_change=shown.event,
        deployment=deployment,
        checksums={name: program.checksum for name, program in mission.programs.items()},
    )
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
            keys=FleetKeys.load(keys_dir, GROUND_STATION),
        ),
        run_dir / "logs" / GROUND_STATION,
        ground_hal,
    )
    exits: dict[str, int] = {}

    def on_exit(name: str, code: int) -> None:
        # Every exit is counted at once (GroundStation.exited): the normal end after
        # Complete, else a failure, with the last line its node wrote about it.
        exits[name] = code
        out = processes.outputs.get(name, run_dir / "logs" / name / "node.out")
        # A shared process's output: the last line that names this drone.
        why = last_line(out, "" if out.name == "node.out" else f" {name}:")
        station.exited(name, exit_reason(code, processes.groups.get(name, (name,)), why))

    processes = LocalFleet(on_exit)
    started = time.time()
    outcome = "ok"
    try:
        runtime.start()
        station.attach(runtime)
        for group in groups:
            if len(group) == 1:
                processes.spawn(group[0], configs[group[0]], run_dir / "logs" / group[0])
            else:  # several drones in one process: its output beside their folders
                processes.spawn_group(
                    {n: configs[n] for n in group},
                    {n: run_dir / "logs" / n for n in group},
                    run_dir / "logs" / f"node-{group[0]}-{group[-1]}.out",
                )
        with shown:
            shown.say(f"mission {mission.name}: {len(drones)} drone(s), run folder {run_dir}")
            flight = fly(
                station,
                shown,
                stop,
                limits,
                alive=lambda: running(station, drones),
                control=run_dir,
                forecast=forecast,
                look_ahead=fleet.look_ahead,
            )
            outcome, started = flight.outcome, flight.started
    finally:
        # After a second Ctrl-C nobody waits for a graceful end: SIGTERM now (each
        # node still lands its drone before it exits), SIGKILL what is left.
        if not processes.wait(0.0 if hurried(stop) else 30.0):
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
