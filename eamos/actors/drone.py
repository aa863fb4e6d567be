"""One drone's part of a mission, from its config: what ``eamos-node`` does on a drone.

Load the program, start the drone runtime, report ready to the ground station
once every participant it sends to listens, execute until the ground station
declares the mission complete (or aborts), send the final report (and wait,
bounded, until it is acknowledged).  A ``stop`` event (a signal) aborts the
mission on this drone: the vehicle lands before this returns.
"""

from __future__ import annotations

import enum
import json
import sys
import threading

from eamos.config import ConfigError, NodeConfig
from eamos.hal import make_adapter
from eamos.logs import close_logger, make_logger
from eamos.net import wire
from eamos.program.format import DroneProgram, load_program
from eamos.program.uniform import GROUND_STATION

from .runtime import DroneRuntime, NetSettings

REPORT_ACK_TIMEOUT_S = 10.0
"""How long a drone waits for the ground station to acknowledge its final report."""


class DroneEnd(enum.Enum):
    """How a drone's part ended (the command line maps it to an exit code)."""

    DONE = "done"  # the mission part finished, the report says ok
    FAILED = "failed"  # the mission failed or was aborted on this drone
    UNREACHABLE = "unreachable"  # the peers never listened: the mission never started


def load_node_program(config: NodeConfig) -> DroneProgram:
    """The program ``config`` names; ConfigError when it is another drone's."""
    program = load_program(config.program)
    if program.drone != config.drone:
        raise ConfigError(
            f"{config.path}: drone: is {config.drone!r} but the program is for {program.drone!r}"
        )
    return program


def net_settings(config: NodeConfig) -> NetSettings:
    """The runtime's network settings from a node config (keys, or plain on loopback)."""
    return NetSettings(config.bind, config.peers, keys=config.keys, link=config.link)


def run_drone(config: NodeConfig, program: DroneProgram, stop: threading.Event) -> DroneEnd:
    """Run one drone until the mission completes or is aborted."""
    config.log_dir.mkdir(parents=True, exist_ok=True)
    adapter_log = make_logger(config.log_dir / "adapter.log", drone=config.drone)
    adapter = make_adapter(config.drone, config.hal, adapter_log)
    runtime = DroneRuntime(program, adapter, net_settings(config), config.log_dir)
    try:
        runtime.start()
        if not runtime.announce_ready(config.ready_timeout_s, stop):
            if stop.is_set():
                return DroneEnd.FAILED
            print(
                f"eamos-node {config.drone}: peers never subscribed: "
                f"{', '.join(runtime.destinations())} "
                f"(waited {config.ready_timeout_s:g} s)",
                file=sys.stderr,
            )
            return DroneEnd.UNREACHABLE
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
        report = runtime.drone_report()
        data = report.to_json()
        (config.log_dir / "report.json").write_text(json.dumps(data, indent=1) + "\n")
        runtime.send(wire.Report(mission=program.mission_id, sender=config.drone, report=data))
        # The report is the last word: retransmitted until acknowledged (bounded).
        if runtime.link is not None and not runtime.link.flush(
            REPORT_ACK_TIMEOUT_S, peers=[GROUND_STATION]
        ):
            runtime.log.warning("mission.report.unacknowledged", timeout_s=REPORT_ACK_TIMEOUT_S)
        return DroneEnd.DONE if report.ok else DroneEnd.FAILED
    finally:
        runtime.stop()
        close_logger(adapter_log)
