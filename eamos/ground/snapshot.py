"""The mission's state now, for the operator: ``snapshot.json`` in the run folder.

The ground station writes it when the operator pauses the mission and at the run's
end, from what the drones already report (their progress and telemetry): per drone
the state of each node it reported and the activation (loop counters) it was in, the
running action, and the vehicle's latest position, velocity (from its last two
samples), battery, armed, landed and lat/lon (``from``: ``telemetry``, or ``report`` once
its final report gave where its last action left it); per arc between drones the
triggers sent and received so far (:mod:`.links`, from the same progress and the
run folder's programs); per run the operator's commands so far.
docs/operations.md ("Operator in the loop") describes the fields.
"""

from __future__ import annotations

import json
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from eamos.actors.continuation import activations
from eamos.logs import report_write_error
from eamos.program.format import DroneProgram, ProgramError, load_program

from .links import LinkCounts, LinkGraph
from .station import DroneView
from .summary import operator_commands

__all__ = ["SNAPSHOT_FILE", "mission_snapshot", "write_run_file", "write_snapshot"]

SNAPSHOT_FILE = "snapshot.json"


def drone_snapshot(view: DroneView) -> dict[str, Any]:
    """One participant's part of the snapshot (pure: from its view)."""
    nodes: dict[str, dict[str, Any]] = {}
    for event in view.events:
        node, state = event.get("node"), event.get("state")
        if isinstance(node, str) and node and isinstance(state, str):
            nodes[node] = {"state": state, "iteration": list(event.get("iteration") or [])}
    entries = activations(view.events)
    running = [
        {k: v for k, v in a.items() if k != "state"} for a in entries if a["state"] == "running"
    ]
    vehicle: dict[str, Any] | None = None
    if view.samples:
        last = view.samples[-1]
        vehicle = {
            "t": last.time_s,
            "x": last.x_m,
            "y": last.y_m,
            "z": last.z_m,
            "lat": last.lat_deg,
            "lon": last.lon_deg,
            "battery": last.battery_pct,
            "armed": last.armed,
            "landed": last.landed,
            "velocity": velocity(view.samples),
            "from": "telemetry",
        }
    final = view.report.final if view.report is not None else None
    if final is not None:  # its report came: where its last action left it, exactly
        vehicle = {
            **(vehicle or {}),
            "x": final.x,
            "y": final.y,
            "z": final.z,
            "battery": final.battery,
            "armed": final.armed,
            "landed": final.landed,
            "velocity": [0.0, 0.0, 0.0],
            "from": "report",
        }
    return {
        "state": view.state,
        "mode": view.mode,  # its autopilot's own flight mode ("": not a MAVLink drone)
        "link": view.link,
        "resolved": view.resolved,
        "action": view.action,
        "running": running,
        "nodes": nodes,
        "activations": entries,
        "vehicle": vehicle,
        # The fastest horizontal speed it held so far (m/s; 0: none yet): the look-ahead's.
        "cruise_mps": round(view.cruise_mps, 3),
        # Its airborne flight so far and the battery it used: the look-ahead's drain measure.
        "flown": view.flown.to_json(),
    }


def velocity(samples: list[Any]) -> list[float] | None:
    """(vx, vy, vz) m/s from the last two samples (None: fewer, or no time between them)."""
    if len(samples) < 2:
        return None
    a, b = samples[-2], samples[-1]
    dt = b.time_s - a.time_s
    if dt <= 0:
        return None
    return [
        round((b.x_m - a.x_m) / dt, 3),
        round((b.y_m - a.y_m) / dt, 3),
        round((b.z_m - a.z_m) / dt, 3),
    ]


def trigger_arcs(
    programs: Mapping[str, DroneProgram], views: Mapping[str, DroneView], started: bool
) -> list[dict[str, Any]]:
    """Per arc between drones: the triggers sent and received so far (pure).

    Counted as the monitor counts them (:class:`~.links.LinkCounts`): from each node's
    reported states, the start trigger and the participants that resolved.
    """
    counts = LinkCounts(LinkGraph.from_programs(programs.values()))
    if started:
        counts.started()
    for view in views.values():
        for event in view.events:
            node, state = event.get("node"), event.get("state")
            if isinstance(node, str) and isinstance(state, str):
                counts.progress(node, state, tuple(event.get("iteration") or ()))
        if view.resolved:
            counts.resolved(view.name)
    return counts.per_arc()


def run_programs(run_dir: Path) -> dict[str, DroneProgram]:
    """The run folder's compiled programs by participant (those it can read)."""
    out: dict[str, DroneProgram] = {}
    for path in sorted((Path(run_dir) / "programs").glob("*.program.json")):
        try:
            out[path.name.removesuffix(".program.json")] = load_program(path)
        except ProgramError:
            continue  # a snapshot without that program's arcs, not no snapshot
    return out


def mission_snapshot(
    views: Mapping[str, DroneView],
    why: str,
    mission_id: str,
    paused: bool,
    programs: Mapping[str, DroneProgram] | None = None,
    started: bool = True,
) -> dict[str, Any]:
    """The whole snapshot (pure but for the time it is taken); ``arcs`` only with programs."""
    return {
        "why": why,
        "t": time.time(),
        "mission_id": mission_id,
        "paused": paused,
        "participants": {name: drone_snapshot(view) for name, view in views.items()},
        "arcs": trigger_arcs(programs, views, started) if programs else [],
        "operator_commands": list(operator_commands(views)),
    }


def write_snapshot(
    run_dir: Path,
    views: Mapping[str, DroneView],
    why: str,
    mission_id: str,
    paused: bool,
    started: bool = True,
) -> Path | None:
    """Write ``run_dir/snapshot.json`` (whole, replaced atomically); None if it could not."""
    doc = mission_snapshot(views, why, mission_id, paused, run_programs(run_dir), started)
    return write_run_file(Path(run_dir) / SNAPSHOT_FILE, doc, "the run goes on")


def write_run_file(path: Path, doc: Mapping[str, Any], going_on: str) -> Path | None:
    """Write ``doc`` as JSON to ``path`` (whole, replaced atomically); None if it could not
    (said once, with ``going_on``: what carries on regardless)."""
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(json.dumps(doc, indent=1) + "\n")
        tmp.replace(path)
    except OSError as exc:
        report_write_error(path, exc, going_on)
        return None
    return path
