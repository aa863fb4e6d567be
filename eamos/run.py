"""``eamos run``: fly a whole mission on this machine, one process per drone (the main job).

Compiles the mission into a run folder, writes one ``eamos-node`` config per
drone (simulated by default; a fleet file may pick other adapters), starts
every drone as its own process on loopback, acts as the ground station
(start trigger once all are ready, live progress, completion), and writes
``summary.json``.  Ctrl-C aborts: every drone lands, then the processes end.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import Any

from .actors.ground import DroneView, GroundStation
from .actors.runtime import DroneRuntime, NetSettings
from .compiler import CompiledMission, compile_file
from .config import ConfigError, FleetConfig, toml_value
from .ground.vehicles import start_sim_vehicles
from .hal import AdapterError, make_adapter
from .logs import make_logger
from .net import wire
from .net.keys import FleetKeys, create_fleet_keys
from .program.format import DroneProgram
from .program.uniform import GROUND_STATION


@dataclass
class RunOptions:
    """What ``eamos run`` was asked to do."""

    mission: Path
    fleet: FleetConfig = field(default_factory=FleetConfig.empty)
    speedup: float | None = None
    summary: Path | None = None
    run_dir: Path | None = None
    timeout_s: float = 600.0
    ready_timeout_s: float = 60.0
    live: bool | None = None  # None: live table when stdout is a terminal
    svg: bool = True


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


def _default_run_dir(compiled: CompiledMission) -> Path:
    stamp = time.strftime("%Y%m%d-%H%M%S")
    return Path("runs") / f"{compiled.mission.name}-{stamp}"


def check_hal_settings(drone: str, hal: dict[str, Any], fleet_path: Path | None) -> None:
    """Validate a drone's hardware settings before any process starts (ConfigError if bad)."""
    try:
        adapter = make_adapter(drone, hal, make_logger(None))
    except AdapterError as exc:
        where = f"{fleet_path}: drones.{drone}." if fleet_path else f"{drone}: "
        raise ConfigError(f"{where}{exc}") from exc
    adapter.close()


def _last_line(path: Path) -> str:
    try:
        lines = [ln for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    except OSError:
        return ""
    return lines[-1] if lines else ""


def node_config_text(
    drone: str,
    program: str,
    log_dir: str,
    bind: str,
    peers: dict[str, str],
    hal: dict[str, Any],
    ready_timeout_s: float,
    *,
    keys: str | None = None,
    plain: bool = False,
    net: dict[str, Any] | None = None,
) -> str:
    """The TOML text of one drone's config.

    ``keys`` is the drone's key folder (relative to the config), ``plain``
    asks for plain sockets instead (loopback only); ``net`` adds ``[net]``
    settings such as ``peer_timeout_s``.
    """
    lines = [
        f"drone = {toml_value(drone)}",
        f"program = {toml_value(program)}",
        f"log_dir = {toml_value(log_dir)}",
        f"ready_timeout_s = {ready_timeout_s!r}",
        "",
        "[net]",
        f"bind = {toml_value(bind)}",
    ]
    if keys is not None:
        lines.append(f"keys = {toml_value(keys)}")
    if plain:
        lines.append("plain = true")
    lines += [f"{k} = {toml_value(v)}" for k, v in (net or {}).items()]
    lines += [
        "",
        "[net.peers]",
    ]
    lines += [f"{json.dumps(k)} = {toml_value(v)}" for k, v in peers.items()]
    lines += ["", "[hal]"]
    lines += [f"{json.dumps(k)} = {toml_value(v)}" for k, v in hal.items()]
    return "\n".join(lines) + "\n"


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
        log_dir.mkdir(parents=True, exist_ok=True)
        out = (log_dir / "node.out").open("wb")
        env = dict(os.environ)
        env.setdefault("PYTHONUNBUFFERED", "1")
        popen = subprocess.Popen(
            [sys.executable, "-m", "eamos.node", "--config", str(config)],
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


class ProgressDisplay:
    """Live progress: a rich table on a terminal, plain lines otherwise."""

    def __init__(self, live: bool, names: list[str], stream: Any = None) -> None:
        self.live = live
        self.names = names
        self.stream = stream or sys.stdout
        self._live: Any = None
        self._lock = threading.Lock()
        self.station: GroundStation | None = None

    def __enter__(self) -> ProgressDisplay:
        if self.live:
            from rich.live import Live

            self._live = Live(self._table(), refresh_per_second=4, transient=False)
            self._live.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._live is not None:
            self._live.update(self._table())
            self._live.__exit__(None, None, None)

    def _table(self) -> Any:
        from rich.table import Table

        table = Table(title="EAMOS mission", expand=False)
        for col in ("drone", "state", "current action", "x, y, z (m)", "done"):
            table.add_column(col)
        views = self.station.snapshot() if self.station else {}
        for name in self.names:
            v = views.get(name) or DroneView(name)
            pos = "" if v.position is None else "{:.1f}, {:.1f}, {:.1f}".format(*v.position)
            table.add_row(name, v.state, v.action, pos, str(v.done_actions))
        return table

    def refresh(self) -> None:
        if self._live is not None:
            self._live.update(self._table())

    def event(self, name: str, view: DroneView, msg: Any) -> None:
        if self.live:
            return
        if isinstance(msg, wire.Progress) and msg.state in ("running", "ok", "failed", "cancelled"):
            line = f"[{time.strftime('%H:%M:%S')}] {name:>8} {msg.state:<9} {msg.action}"
            reason = msg.detail.get("detail") if isinstance(msg.detail, dict) else ""
            if reason and msg.state != "running":
                line += f"  ({reason})"
        elif isinstance(msg, wire.Ready | wire.Resolved):
            line = f"[{time.strftime('%H:%M:%S')}] {name:>8} {type(msg).__name__.lower()}"
        else:
            return
        with self._lock:
            print(line, file=self.stream, flush=True)

    def say(self, text: str) -> None:
        with self._lock:
            if self._live is not None:
                self._live.console.print(text)
            else:
                print(text, file=self.stream, flush=True)


def ground_runtime(
    program: DroneProgram,
    station: GroundStation,
    bind: str,
    drone_endpoints: dict[str, str],
    log_dir: Path | None,
    speedup: float | None,
    keys: Any = None,
) -> DroneRuntime:
    """The ground station's own runtime: its program on the ground adapter, feeding ``station``.

    Not started yet; it receives every drone's telemetry too (for the live table).
    Shared by ``eamos run`` and ``eamos start`` (:mod:`eamos.ops.ground`), which
    passes the fleet keys (``keys``, a :class:`eamos.net.keys.FleetKeys`).
    """
    hal: dict[str, Any] = {"adapter": "ground"}
    if speedup:
        hal["speedup"] = speedup
    adapter_log = make_logger(
        None if log_dir is None else log_dir / "adapter.log", drone=GROUND_STATION
    )
    return DroneRuntime(
        program,
        make_adapter(GROUND_STATION, hal, adapter_log),
        NetSettings(bind, drone_endpoints, keys=keys),
        log_dir,
        ground_handler=station.handle,
        extra_topics=tuple(wire.topic_telemetry(d) for d in drone_endpoints),
    )


@dataclass
class GroundPhases:
    """The ground station's part of a run, wherever the drones are (paper VI-G).

    Wait until every drone is ready (else abort: no start trigger is sent), send
    the start trigger, wait until every participant resolved (or the operator
    stops, or the timeout), then complete or abort, and wait for the reports.
    ``eamos run`` (drones on this machine) and ``eamos start`` (drones over SSH)
    both fly through this.
    """

    ready_timeout_s: float
    timeout_s: float
    live: bool
    stop: threading.Event
    ready_s: float | None = None  # how long the drones took to become ready
    on_ready: Callable[[float], None] | None = None  # told ready_s before the start trigger

    def fly(
        self,
        station: GroundStation,
        display: ProgressDisplay,
        speak: Callable[[str], None],
        alive: Callable[[], list[str]],
    ) -> tuple[str, float]:
        """Run the phases; return ``(outcome, start time)``; outcome ``"ok"`` on success.

        ``alive()`` names the drones whose process still runs (they are waited
        for their final report).
        """
        outcome = "ok"
        started = time.time()
        t0 = time.monotonic()
        if not station.wait_ready(self.ready_timeout_s, self.stop):
            outcome = "not ready: " + (
                ", ".join(station.failures) or "waiting for " + ", ".join(station.not_ready())
            )
            station.abort(outcome)
        else:
            self.ready_s = time.monotonic() - t0
            if self.on_ready is not None:
                self.on_ready(self.ready_s)
            speak("all drones ready: start")
            started = time.time()
            station.start()
            deadline = time.monotonic() + self.timeout_s
            while not station.wait_resolved(1.0 if self.live else 5.0, self.stop):
                display.refresh()
                if self.stop.is_set():
                    outcome = "aborted by the operator"
                    break
                if time.monotonic() > deadline:
                    outcome = (
                        f"timed out after {self.timeout_s:g} s (unresolved: "
                        f"{', '.join(station.unresolved())})"
                    )
                    break
            if outcome == "ok":
                station.complete()
            else:
                speak(f"aborting: {outcome}: every drone lands")
                station.abort(outcome)
        # A drone that never became ready sends no report (eamos-node gives up first).
        views = station.snapshot()
        waiting = [n for n in alive() if views[n].ready]
        if not station.wait_reports(waiting, 60 if outcome == "ok" else 180):
            speak(
                "some drones sent no report: "
                + ", ".join(n for n in waiting if station.snapshot()[n].report is None)
            )
        display.refresh()
        return outcome, started


def build_summary(
    mission: str,
    mission_id: str,
    outcome: str,
    started: float,
    run_dir: Path,
    views: dict[str, DroneView],
    drones: list[str],
    exits: dict[str, int],
    gcs_report: dict[str, Any],
) -> dict[str, Any]:
    """The run summary (``summary.json``): outcome, and every participant's report."""
    duration = time.time() - started
    drone_reports: dict[str, Any] = {}
    for name in drones:
        report = views[name].report or {
            "ok": False,
            "error": "no report",
            "exit_code": exits.get(name),
        }
        report.setdefault("exit_code", exits.get(name))
        drone_reports[name] = report
    ok = (
        outcome == "ok"
        and all(r.get("ok") for r in drone_reports.values())
        and bool(gcs_report.get("ok"))
    )
    return {
        "ok": ok,
        "mission": mission,
        "mission_id": mission_id,
        "outcome": outcome,
        "duration_s": round(duration, 3),
        "started": started,
        "run_dir": str(run_dir),
        "drones": drone_reports,
        "ground_station": gcs_report,
    }


def run_mission(
    opts: RunOptions, stop: threading.Event | None = None, say: Callable[[str], None] | None = None
) -> dict[str, Any]:
    """Run a mission end to end; return the summary (also written to the run folder)."""
    stop = stop or threading.Event()
    compiled = compile_file(opts.mission)
    run_dir = (opts.run_dir or _default_run_dir(compiled)).resolve()
    run_dir.mkdir(parents=True, exist_ok=True)
    try:
        from .compiler import write_artifacts  # type: ignore[attr-defined]

        write_artifacts(compiled, run_dir, svg=opts.svg)
    except ImportError:  # pragma: no cover - artifacts module not available
        (run_dir / "programs").mkdir(exist_ok=True)
        for name, prog in compiled.programs.items():
            prog.save(run_dir / "programs" / f"{name}.program.json")
    names = list(compiled.programs)
    drones = [n for n in names if n != GROUND_STATION]
    ports = free_ports(len(names))
    endpoints = {n: f"tcp://127.0.0.1:{p}" for n, p in zip(names, ports, strict=True)}
    configs_dir = run_dir / "configs"
    configs_dir.mkdir(exist_ok=True)
    configs: dict[str, Path] = {}
    # A fresh CURVE key pair per participant for every run: the links are
    # encrypted and only this run's participants can connect (docs/network.md).
    create_fleet_keys(run_dir / "keys", names, force=True)
    # MAVLink simulated vehicles (hal.sim_vehicle) start first; their nodes get the connection.
    vehicles = start_sim_vehicles(
        {n: opts.fleet.hal_for(n) for n in drones}, run_dir / "logs", opts.speedup
    )
    for name in drones:
        hal = vehicles.hal_for(name)
        if opts.speedup is not None and hal.get("adapter", "sim") == "sim":
            hal["speedup"] = opts.speedup
        check_hal_settings(name, hal, opts.fleet.path)
        peers = {n: e for n, e in endpoints.items() if n != name}
        text = node_config_text(
            name,
            f"../programs/{name}.program.json",
            f"../logs/{name}",
            endpoints[name],
            peers,
            hal,
            opts.ready_timeout_s,
            keys=f"../keys/{name}",
        )
        configs[name] = configs_dir / f"{name}.toml"
        configs[name].write_text(text)

    live = sys.stdout.isatty() if opts.live is None else opts.live
    display = ProgressDisplay(live, drones)
    station = GroundStation(drones, compiled.mission_id, on_change=display.event)
    display.station = station
    speak = say or display.say
    runtime = ground_runtime(
        compiled.programs[GROUND_STATION],
        station,
        endpoints[GROUND_STATION],
        {n: endpoints[n] for n in drones},
        run_dir / "logs" / GROUND_STATION,
        opts.speedup,
        keys=FleetKeys.load(run_dir / "keys" / GROUND_STATION, GROUND_STATION),
    )
    exits: dict[str, int] = {}

    def on_exit(name: str, code: int) -> None:
        exits[name] = code
        view = station.snapshot().get(name)
        if view is not None and view.report is None:
            why = _last_line(run_dir / "logs" / name / "node.out")
            station.fail(name, f"process exited with code {code}" + (f": {why}" if why else ""))

    fleet = LocalFleet(on_exit)
    started = time.time()
    outcome = "ok"
    try:
        runtime.start()
        station.attach(runtime)
        for name in drones:
            fleet.spawn(name, configs[name], run_dir / "logs" / name)
        with display:
            speak(f"mission {compiled.mission.name}: {len(drones)} drone(s), run folder {run_dir}")
            phases = GroundPhases(opts.ready_timeout_s, opts.timeout_s, live, stop)
            outcome, started = phases.fly(
                station, display, speak, alive=lambda: [n for n in drones if n not in exits]
            )
    finally:
        if not fleet.wait(30):
            fleet.terminate()
        vehicles.stop()
        gcs_report = runtime.report() if runtime.executive is not None else {}
        runtime.stop()
    summary = build_summary(
        compiled.mission.name,
        compiled.mission_id,
        outcome,
        started,
        run_dir,
        station.snapshot(),
        drones,
        exits,
        gcs_report,
    )
    (run_dir / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    if opts.summary is not None:
        opts.summary.parent.mkdir(parents=True, exist_ok=True)
        opts.summary.write_text(json.dumps(summary, indent=1) + "\n")
    return summary


def install_stop_handler(stop: threading.Event) -> None:
    """Ctrl-C / SIGTERM set ``stop``: the run aborts, every drone lands, then it exits."""

    def handler(signum: int, frame: FrameType | None) -> None:
        if stop.is_set():
            raise KeyboardInterrupt
        stop.set()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
