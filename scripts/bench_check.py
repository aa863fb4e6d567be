#!/usr/bin/env python3
"""Benchmark of the pre-flight check (``eamos check``); prints JSON.

* experiment D with its scripted pilot (configs/experiment_d_pilot.toml): every
  branch the check explores within ``--max-runs`` (default 64; the pilot's
  properties are unknowable, so every loop iteration and wait is a choice point);
* the 20-drone, 5000-action stress mission of scripts/bench_runtime.py
  (``stress_mission(20, 10, 25)``: 5000 payload actions).

For each: wall and CPU seconds of ``check_mission`` (compilation excluded; the
median of ``--repeat`` checks, default 3, and the first one's), the
runs explored, the virtual seconds flown in all runs, and how much faster than
real time that is.  Targets: the stress mission checked in under 5 s, virtual
time at least 200 times faster than real time.

Usage: ``python scripts/bench_check.py --json [--max-runs N]``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

from eamos.check import check_mission
from eamos.compiler import compile_file, compile_mission
from eamos.config import FleetConfig

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))

from bench_runtime import stress_mission  # noqa: E402  (a sibling script)


def measure(compiled, fleet: FleetConfig | None, max_runs: int, repeat: int) -> dict[str, object]:
    """Wall and CPU seconds of ``repeat`` checks (the first, cold, and the median), and
    what one explored."""
    walls, cpus = [], []
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        report = check_mission(compiled, fleet, max_runs=max_runs)
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
    wall, cpu = statistics.median(walls), statistics.median(cpus)
    virtual = sum(r.duration_s for r in report.runs)
    return {
        "drones": len(compiled.programs) - 1,
        "meg_nodes": compiled.meg.number_of_nodes(),
        "runs": len(report.runs),
        "unexplored_runs": report.unexplored,
        "errors": len(report.errors),
        "warnings": len(report.warnings),
        "virtual_s": round(virtual, 2),
        "checks": repeat,
        "first_wall_s": round(walls[0], 3),
        "wall_s": round(wall, 3),  # the median
        "cpu_s": round(cpu, 3),
        "faster_than_real_time": round(virtual / wall) if wall > 0 else None,
        # CPU seconds too: on a loaded machine wall time also counts other processes.
        "faster_than_real_time_cpu": round(virtual / cpu) if cpu > 0 else None,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print JSON (the default)")
    parser.add_argument("--max-runs", type=int, default=64, help="runs explored per mission")
    parser.add_argument("--repeat", type=int, default=3, help="checks per mission (median)")
    args = parser.parse_args()
    pilot = FleetConfig.load(REPO / "configs" / "experiment_d_pilot.toml")
    results = {
        "experiment_d": measure(
            compile_file(REPO / "missions" / "experiment_d.go"), pilot, args.max_runs, args.repeat
        ),
        "stress_20x5000": measure(
            compile_mission(stress_mission(20, 10, 25), "stress.go"),
            None,
            args.max_runs,
            args.repeat,
        ),
    }
    results["targets"] = {
        "stress_under_5_s": results["stress_20x5000"]["wall_s"] < 5.0,  # type: ignore[operator]
        "virtual_200x": all(
            (r["faster_than_real_time"] or 0) >= 200  # type: ignore[index,operator]
            for k, r in results.items()
            if k != "targets"
        ),
    }
    print(json.dumps(results))


if __name__ == "__main__":
    main()
