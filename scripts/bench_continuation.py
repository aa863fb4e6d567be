#!/usr/bin/env python3
"""Benchmark of a virtual run going on from a mission's snapshot; prints JSON.

What a look-ahead would pay each cycle: for each mission, an uninterrupted virtual run
is stopped half-way and its snapshot made as the ground station makes it
(:func:`snapshot_at`, :func:`eamos.ground.snapshot.drone_snapshot` of the progress
events the drones would have reported); then timed, the median of ``--repeat``:

* ``continue``: one :class:`~eamos.virtual.VirtualMission` run from the snapshot;
* ``check``: ``check_mission(continuation=...)``, every branch it explores (as
  ``eamos check MISSION --from RUN_DIR``, compilation excluded).

Missions: experiment C (3 drones) and ``missions/fleets/fleet100.go`` (100 drones).
Each result gives the remaining virtual seconds and how much faster than real time
the continuation flies them.

Usage: ``python scripts/bench_continuation.py --json [--repeat N]``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path
from typing import Any

from eamos.check import check_mission
from eamos.check.explore import run_once
from eamos.compiler import compile_file
from eamos.ground.snapshot import drone_snapshot
from eamos.ground.station import DroneView
from eamos.hal.sim import SimSettings
from eamos.virtual import VirtualMission, VirtualRun, continuation

REPO = Path(__file__).resolve().parents[1]
MISSIONS = {
    "experiment_c": REPO / "missions" / "experiment_c.go",
    "fleet100": REPO / "missions" / "fleets" / "fleet100.go",
}
#: The wall-clock time the uninterrupted run "started" (the snapshot's times count from it).
EPOCH = 1_800_000_000.0


def snapshot_at(compiled: Any, run: VirtualRun, tracks: dict[str, Any], t: float) -> dict[str, Any]:
    """The snapshot a ground station would write at virtual time ``t`` of ``run``.

    Each action that began by ``t`` reported ``running`` (with where its drone's
    track was then), and, if it ended by ``t``, its result; each vehicle is where its
    track is at ``t``, with the velocity of the next tenth of a second.
    """
    participants = {}
    for drone, outcome in run.drones.items():
        view = DroneView(drone)
        for r in outcome.actions:
            if r.start > t:
                continue
            began: dict[str, Any] = {"node": r.node, "action": r.action, "iteration": r.iteration}
            if drone in tracks:
                began["position"] = list(tracks[drone].at(r.start))
            view.events.append({"t": EPOCH + r.start, "state": "running", **began})
            if r.end <= t:
                view.events.append(
                    {"t": EPOCH + r.end, "state": r.result, "node": r.node,
                     "action": r.action, "iteration": r.iteration, "detail": r.reason}
                )  # fmt: skip
        part = drone_snapshot(view)
        if drone in tracks:
            x, y, z = tracks[drone].at(t)
            x2, y2, z2 = tracks[drone].at(t + 0.1)
            part["vehicle"] = {
                "x": x, "y": y, "z": z, "armed": True, "landed": z <= 0.0, "battery": 99.0,
                "velocity": [(x2 - x) / 0.1, (y2 - y) / 0.1, (z2 - z) / 0.1],
            }  # fmt: skip
        participants[drone] = part
    return {"why": "pause", "t": EPOCH + t, "mission_id": compiled.mission_id, "paused": True,
            "participants": participants}  # fmt: skip


def timed(fn: Any, repeat: int) -> tuple[float, float, Any]:
    """The median wall and CPU seconds of ``repeat`` calls of ``fn``, and its last result."""
    walls, cpus = [], []
    result = None
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        result = fn()
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
    return statistics.median(walls), statistics.median(cpus), result


def measure(name: str, path: Path, repeat: int) -> dict[str, Any]:
    compiled = compile_file(path)
    settings = {d: SimSettings() for d in compiled.programs}
    full, tracks = run_once(compiled, settings, {}, 1800.0)
    t = full.duration_s / 2
    past = continuation(snapshot_at(compiled, full, tracks, t))
    run_wall, run_cpu, rest = timed(
        lambda: VirtualMission(compiled.programs, continuation=past).run(), repeat
    )
    check_wall, check_cpu, report = timed(
        lambda: check_mission(compiled, continuation=past), repeat
    )
    remaining = rest.duration_s
    return {
        "mission": name,
        "drones": len(compiled.programs) - 1,
        "mission_s": round(full.duration_s, 2),
        "snapshot_at_s": round(t, 2),
        "replayed_actions": len(rest.replayed),
        "remaining_virtual_s": round(remaining, 2),
        "continue": {
            "ok": rest.ok,
            "wall_s": round(run_wall, 4),
            "cpu_s": round(run_cpu, 4),
            "times_real_time": round(remaining / run_wall, 1) if run_wall > 0 else None,
        },
        "check": {
            "runs": len(report.runs),
            "errors": len(report.errors),
            "wall_s": round(check_wall, 4),
            "cpu_s": round(check_cpu, 4),
        },
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print JSON (the only output)")
    parser.add_argument("--repeat", type=int, default=5, help="timed repetitions (median)")
    args = parser.parse_args()
    results = [measure(name, path, args.repeat) for name, path in MISSIONS.items()]
    print(json.dumps({"benchmark": "continuation", "results": results}, indent=2))


if __name__ == "__main__":
    main()
