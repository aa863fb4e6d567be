"""``eamos-node --config drone1.toml``: run one drone's mission program.

Loads the config and the program, starts the drone runtime, reports ready to
the ground station once every participant it sends to listens, executes
until the ground station declares the mission complete (or aborts), sends its
report (and waits, bounded, until it is acknowledged), and exits.
SIGINT/SIGTERM abort the mission on this drone: the vehicle lands before the
process exits.

Given the ground station's program (``drone = "GCS"``), it runs the ground
station instead: waits until every drone is ready, sends the start trigger,
shows progress and lost/returned links on stdout, completes (or aborts after
``mission_timeout_s``), collects the reports and writes ``summary.json`` in its
log folder.  So a whole fleet runs from configs alone, each participant on its
own host, with no ``eamos run`` process anywhere (the fault tests do this).

Exit codes: 0 mission part done, 1 mission failed or aborted, 2 bad config
or program, 3 the vehicle or network could not be used.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
import traceback
from pathlib import Path
from types import FrameType
from typing import Any

from . import __version__
from .actors.ground import DroneView, GroundStation
from .actors.runtime import DroneRuntime, DroneRuntimeError, NetSettings
from .config import ConfigError, NodeConfig
from .hal import AdapterError, make_adapter
from .logs import close_logger, make_logger
from .net import wire
from .net.link import PeerStatus
from .program.format import DroneProgram, ProgramError, load_program
from .program.uniform import GROUND_STATION

REPORT_ACK_TIMEOUT_S = 10.0
"""How long a drone waits for the ground station to acknowledge its final report."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="eamos-node",
        description="Run one drone's part of an EAMOS mission (its compiled drone program).",
        epilog="The config names the drone, its program, its out-bridge endpoint, its peers' "
        "endpoints, the hardware adapter and the log folder; see eamos/config.py.",
    )
    parser.add_argument("--config", required=True, type=Path, help="the drone's TOML config file")
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="show tracebacks of internal errors"
    )
    parser.add_argument("--version", action="version", version=f"eamos {__version__}")
    return parser


def run_node(config: NodeConfig, stop: threading.Event | None = None) -> int:
    """Run one drone until the mission completes or is aborted; return the exit code."""
    program = load_program(config.program)
    if program.drone != config.drone:
        raise ConfigError(
            f"{config.path}: drone: is {config.drone!r} but the program is for {program.drone!r}"
        )
    config.log_dir.mkdir(parents=True, exist_ok=True)
    stop = stop or threading.Event()
    if program.drone == GROUND_STATION:
        return run_ground(config, program, stop)
    adapter_log = make_logger(config.log_dir / "adapter.log", drone=config.drone)
    adapter = make_adapter(config.drone, config.hal, adapter_log)
    runtime = DroneRuntime(program, adapter, net_settings(config), config.log_dir)
    try:
        runtime.start()
        if not runtime.announce_ready(config.ready_timeout_s, stop):
            if stop.is_set():
                return 1
            print(
                f"eamos-node {config.drone}: peers never subscribed: "
                f"{', '.join(runtime.destinations())} "
                f"(waited {config.ready_timeout_s:g} s)",
                file=sys.stderr,
            )
            return 3
        while not (runtime.completed.is_set() or runtime.aborted.is_set()):
            if stop.is_set():
                runtime.abort("stopped by signal")
                break
            # Bounded only so a signal (which sets `stop`) is noticed; the runtime's
            # events are set by the in-bridge thread.
            runtime.completed.wait(0.5)
        if runtime.aborted.is_set():
            landed = runtime.wait_landed(config.land_timeout_s)
            if not landed:
                runtime.log.error("mission.abort.not_landed", timeout_s=config.land_timeout_s)
        report = runtime.report()
        (config.log_dir / "report.json").write_text(json.dumps(report, indent=1) + "\n")
        runtime.send(wire.Report(mission=program.mission_id, sender=config.drone, report=report))
        # The report is the last word: retransmitted until acknowledged (bounded).
        if runtime.link is not None and not runtime.link.flush(
            REPORT_ACK_TIMEOUT_S, peers=[GROUND_STATION]
        ):
            runtime.log.warning("mission.report.unacknowledged", timeout_s=REPORT_ACK_TIMEOUT_S)
        return 0 if report["ok"] else 1
    finally:
        runtime.stop()
        close_logger(adapter_log)


def net_settings(config: NodeConfig) -> NetSettings:
    """The runtime's network settings from a node config (keys, or plain on loopback)."""
    return NetSettings(config.bind, config.peers, keys=config.keys, link=config.link)


def _print_event(name: str, view: DroneView, msg: Any) -> None:
    """Progress lines of the ground station (stdout, one per event worth seeing)."""
    stamp = time.strftime("%H:%M:%S")
    if isinstance(msg, wire.Progress) and msg.state in ("running", "ok", "failed", "cancelled"):
        line = f"[{stamp}] {name:>8} {msg.state:<9} {msg.action}"
    elif isinstance(msg, wire.Ready | wire.Resolved):
        line = f"[{stamp}] {name:>8} {type(msg).__name__.lower()}"
    elif isinstance(msg, PeerStatus):
        line = f"[{stamp}] {name:>8} link {msg.state}" + (
            f" (silent {msg.silent_s:.1f} s)" if msg.state in ("lost", "back") else ""
        )
    else:
        return
    print(line, flush=True)


def run_ground(config: NodeConfig, program: DroneProgram, stop: threading.Event) -> int:
    """Run the ground station's part: ready, start, watch, complete, collect reports."""
    drones = [n for n in program.fleet if n != GROUND_STATION]
    station = GroundStation(
        drones, program.mission_id, on_change=_print_event, give_up_s=config.peer_give_up_s
    )
    adapter_log = make_logger(config.log_dir / "adapter.log", drone=config.drone)
    hal = dict(config.hal) if config.hal.get("adapter") == "ground" else {"adapter": "ground"}
    runtime = DroneRuntime(
        program,
        make_adapter(GROUND_STATION, hal, adapter_log),
        net_settings(config),
        config.log_dir,
        ground_handler=station.handle,
        extra_topics=tuple(wire.topic_telemetry(d) for d in drones),
    )
    outcome = "ok"
    started = time.time()
    gcs_report: dict[str, Any] = {}
    try:
        runtime.start()
        station.attach(runtime)
        if not station.wait_ready(config.ready_timeout_s, stop):
            outcome = "not ready: " + (
                ", ".join(station.failures) or "waiting for " + ", ".join(station.not_ready())
            )
            station.abort(outcome)
        else:
            print(f"[{time.strftime('%H:%M:%S')}] all drones ready: start", flush=True)
            started = time.time()
            station.start()
            deadline = time.monotonic() + config.mission_timeout_s
            while not station.wait_resolved(1.0, stop):
                if stop.is_set():
                    outcome = "aborted by the operator"
                    break
                if time.monotonic() > deadline:
                    outcome = (
                        f"timed out after {config.mission_timeout_s:g} s (unresolved: "
                        f"{', '.join(station.unresolved())})"
                    )
                    break
            if outcome == "ok":
                station.complete()
            else:
                station.abort(outcome)
        views = station.snapshot()
        waiting = [d for d in drones if views[d].ready and views[d].state != "lost"]
        station.wait_reports(waiting, 60 if outcome == "ok" else 180)
        gcs_report = runtime.report()
    finally:
        runtime.stop()
        close_logger(adapter_log)
    views = station.snapshot()
    reports = {
        d: views[d].report or {"ok": False, "error": "no report", "link": views[d].link}
        for d in drones
    }
    summary = {
        "ok": outcome == "ok"
        and all(r.get("ok") for r in reports.values())
        and bool(gcs_report.get("ok")),
        "mission": program.mission,
        "mission_id": program.mission_id,
        "outcome": outcome,
        "duration_s": round(time.time() - started, 3),
        "started": started,
        "failures": list(station.failures),
        "links": {d: views[d].link for d in drones},
        "drones": reports,
        "ground_station": gcs_report,
    }
    (config.log_dir / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    print(f"mission {program.mission} {'finished' if summary['ok'] else 'FAILED'}: {outcome}")
    return 0 if summary["ok"] else 1


def main(argv: list[str] | None = None) -> int:
    """Console entry point of ``eamos-node``."""
    args = build_parser().parse_args(argv)
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        config = NodeConfig.load(args.config)
        return run_node(config, stop)
    except (ConfigError, ProgramError) as exc:
        print(f"eamos-node: {exc}", file=sys.stderr)
        return 2
    except (AdapterError, DroneRuntimeError) as exc:
        print(f"eamos-node: {exc}", file=sys.stderr)
        return 3
    except Exception as exc:  # an internal error: one line, the trace only with -v
        if args.verbose:
            traceback.print_exc()
        print(f"eamos-node: internal error: {exc!r} (run with -v for details)", file=sys.stderr)
        return 4


if __name__ == "__main__":
    sys.exit(main())
