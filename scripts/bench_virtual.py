#!/usr/bin/env python3
"""Benchmark of the virtual-time driver (eamos.virtual); prints JSON.

For every mission in missions/ (experiment D with its scripted pilot from
configs/experiment_d_pilot.toml): the CPU seconds ``run_virtual`` takes, the
virtual seconds the mission lasts, and their ratio (how much faster than real
time the mission runs), best of three, in this process.

Usage: ``python scripts/bench_virtual.py --json``.
"""

from __future__ import annotations

import argparse
import json
import time
import tomllib
from pathlib import Path

from eamos.compiler import compile_file
from eamos.hal.sim import SimSettings
from eamos.virtual import run_virtual, sim_vehicles

REPO = Path(__file__).resolve().parents[1]
FLEETS = {"experiment_d": REPO / "configs" / "experiment_d_pilot.toml"}


def vehicle_settings(mission: str) -> dict[str, SimSettings] | None:
    """Per-drone simulator settings from the mission's fleet file (the pilot of experiment D)."""
    path = FLEETS.get(mission)
    if path is None:
        return None
    fleet = tomllib.loads(path.read_text(encoding="utf-8"))
    return {
        name: SimSettings.from_mapping({**fleet.get("defaults", {}).get("hal", {}), **d["hal"]})
        for name, d in fleet.get("drones", {}).items()
        if "hal" in d
    }


def measure(path: Path, repeat: int = 3) -> dict[str, object]:
    """CPU seconds (best of ``repeat``) and virtual seconds of one mission."""
    compiled = compile_file(path)
    settings = vehicle_settings(path.stem)
    best = float("inf")
    for _ in range(repeat):
        t0 = time.process_time()
        run = run_virtual(compiled.programs, sim_vehicles(settings))
        best = min(best, time.process_time() - t0)
    return {
        "drones": len(compiled.programs) - 1,
        "ok": run.ok,
        "virtual_s": round(run.duration_s, 2),
        "cpu_s": round(best, 4),
        "faster_than_real_time": round(run.duration_s / best) if best > 0 else None,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print JSON (the default)")
    parser.parse_args()
    results = {p.stem: measure(p) for p in sorted((REPO / "missions").glob("*.go"))}
    print(json.dumps(results))


if __name__ == "__main__":
    main()
