#!/usr/bin/env python3
"""Benchmark: one cycle of the live look-ahead (``eamos.check.lookahead``), as JSON.

For each mission: fly it whole in virtual time, take the snapshot a ground station
would write halfway through (``bench_continuation.snapshot_at``, each drone's track seen
from its own home, as its telemetry says), then time :func:`look_ahead` on it: the
median wall and CPU seconds of a cycle, and how many times faster than the mission's
remaining time that is (the issue's target: a cycle under 1 s, at least 200 times).

    python scripts/bench_lookahead.py [--repeat 5]

Missions: experiment C (3 drones) and ``missions/team_relay.go`` widened to 20 drones
(``var Team [20]Quadcopter``, landing in two halves of ten); each must pass the check.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

from bench_continuation import snapshot_at, timed

from eamos.check import check_mission
from eamos.check.explore import run_once, sim_settings
from eamos.check.lookahead import look_ahead
from eamos.compiler import compile_file
from eamos.config import FleetConfig, fleet_order
from eamos.program.uniform import GROUND_STATION

ROOT = Path(__file__).resolve().parents[1]


class LocalTrack:
    """A fleet-frame track seen from its drone's home (what the drone's telemetry says)."""

    def __init__(self, track: Any, home: tuple[float, float]) -> None:
        self.track, self.home = track, home

    def at(self, t: float) -> tuple[float, float, float]:
        x, y, z = self.track.at(t)
        return x - self.home[0], y - self.home[1], z


def flown(compiled: Any, fleet: FleetConfig, overrides: dict[str, Any] | None = None) -> Any:
    """The mission flown whole in virtual time with the fleet's models (``overrides``:
    settings per drone to change, such as a disturbance): (run, tracks seen locally)."""
    fleet = fleet.for_mission(compiled.programs, compiled.mission.types)
    drones = fleet_order(compiled.programs)
    homes = fleet.homes(drones)
    settings = {}
    for d in drones:
        st = dataclasses.replace(sim_settings(fleet, d)[0], home_m=homes[d])
        settings[d] = dataclasses.replace(st, **(overrides or {}).get(d, {}))
    run, tracks = run_once(compiled, settings, homes, 3600.0)
    return run, {d: LocalTrack(tracks[d], homes[d]) for d in tracks}


def measure(name: str, compiled: Any, repeat: int) -> dict[str, Any]:
    fleet = FleetConfig.empty()
    assert check_mission(compiled, fleet).ok, f"{name}: the pre-flight check refuses it"
    run, tracks = flown(compiled, fleet)
    t = run.duration_s / 2
    doc = json.loads(json.dumps(snapshot_at(compiled, run, tracks, t)))
    wall, cpu, ahead = timed(lambda: look_ahead(compiled, fleet, doc), repeat)
    remaining = run.duration_s - t
    return {
        "mission": name,
        "drones": len([d for d in run.drones if d != GROUND_STATION]),
        "remaining_s": round(remaining, 1),
        "cycle_wall_s": round(wall, 4),
        "cycle_cpu_s": round(cpu, 4),
        "faster_than_flight": round(remaining / wall, 1),
        "runs": ahead.runs,
        "predictions": len(ahead.predictions),
        "predicted_end_in_s": ahead.end_in_s,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="cycles timed per mission")
    args = parser.parse_args(argv)
    relay = (ROOT / "missions" / "team_relay.go").read_text()
    with tempfile.TemporaryDirectory() as folder:
        wide = Path(folder) / "team_relay_20.go"
        # Twenty drones, landing in two halves of ten.
        wide.write_text(
            relay.replace("[4]Quadcopter", "[20]Quadcopter").replace(
                "Team[2*half : 2*half+2]", "Team[10*half : 10*half+10]"
            )
        )
        missions = [
            ("experiment_c", compile_file(ROOT / "missions" / "experiment_c.go")),
            ("team_relay_20", compile_file(wide)),
        ]
    out = [measure(name, compiled, args.repeat) for name, compiled in missions]
    json.dump({"look_ahead": out}, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
