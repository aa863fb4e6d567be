"""``eamos-node`` given the ground station's program: the ground station from a config alone.

It waits until every drone is ready, sends the start trigger, shows progress
and lost/returned links on stdout, completes (or aborts after
``mission_timeout_s``), collects the reports and writes ``summary.json`` in
its log folder.  So a whole fleet runs from configs alone, each participant
on its own host, with no ``eamos run`` process anywhere (the fault tests do
this).
"""

from __future__ import annotations

import threading
import time

from eamos.actors.drone import net_settings
from eamos.config import NodeConfig
from eamos.program.format import DroneProgram
from eamos.program.uniform import GROUND_STATION

from .display import Display, PlainDisplay
from .flight import Limits, fly, ground_runtime
from .station import GroundStation
from .summary import RunSummary, summarize


def run_ground_node(
    config: NodeConfig,
    program: DroneProgram,
    stop: threading.Event,
    display: Display | None = None,
) -> RunSummary:
    """Be the ground station of ``program``'s mission; return the summary (also written).

    ``display`` defaults to plain lines on stdout.
    """
    config.log_dir.mkdir(parents=True, exist_ok=True)
    drones = [n for n in program.fleet if n != GROUND_STATION]
    shown = display or PlainDisplay()
    station = GroundStation(
        drones,
        program.mission_id,
        on_change=shown.event,
        give_up_s=config.peer_give_up_s,
        deployment=config.deployment,
    )
    shown.watch(station)
    runtime = ground_runtime(program, station, net_settings(config), config.log_dir, config.hal)
    limits = Limits(config.ready_timeout_s, config.mission_timeout_s)
    outcome = "not started"
    started = time.time()
    gcs_report = None
    try:
        runtime.start()
        station.attach(runtime)
        with shown:
            flight = fly(station, shown, stop, limits)
        outcome, started = flight.outcome, flight.started
        gcs_report = runtime.drone_report()
    finally:
        runtime.stop()
    summary = summarize(
        program.mission,
        program.mission_id,
        outcome,
        started,
        time.time(),
        config.log_dir,
        station.snapshot(),
        drones,
        list(station.failures),
        gcs_report,
    )
    summary.write(config.log_dir / "summary.json")
    shown.say(f"mission {program.mission} {'finished' if summary.ok else 'FAILED'}: {outcome}")
    return summary
