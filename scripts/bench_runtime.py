#!/usr/bin/env python3
"""Benchmark of the drone execution environment; prints JSON.

Measures, each in fresh processes:

* ``startup``: time and memory to load a drone program of ~634 MDG nodes (the
  paper's stress test: 733 ms, 4.2 MB heap in Go) and build its runtime (every
  node actor, the HAL actor, both bridges), up to "runtime started".
* ``local_trigger``: cost per node of a one-drone chain of zero-duration actions
  (node actor -> uniform API -> adapter -> next node).
* ``cross_drone``: latency of a trigger between two drone processes over
  loopback TCP (end of an action on one drone to the start of the next action on
  the other), p50 and p99, from an ``eamos run`` with zero-duration actions.
* ``mission_5000``: framework overhead of a 20-drone, >5000-node mission whose
  actions take no time: start trigger to the last drone resolved, plus the whole
  wall time of ``eamos run`` (compile, spawn 20 processes, run, reports).

Usage: ``python scripts/bench_runtime.py --json`` (``--quick`` for a smaller run).
"""

from __future__ import annotations

import argparse
import itertools
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
ACTIONS = ("TurnOn", "PreFlightCheck", "Calibrate")


def stress_mission(drones: int, blocks: int, per_drone: int) -> str:
    """K parallel blocks in sequence; in each, every drone runs a chain of payload actions."""
    lines = [f"var D{d} Quadcopter" for d in range(1, drones + 1)]
    lines.append("func SEQ_Main() {")
    lines += [f"    PAR_B{b}()" for b in range(blocks)]
    lines.append("}")
    for b in range(blocks):
        lines.append(f"func PAR_B{b}() {{")
        lines += [f"    SEQ_B{b}_D{d}()" for d in range(1, drones + 1)]
        lines.append("}")
        for d in range(1, drones + 1):
            lines.append(f"func SEQ_B{b}_D{d}() {{")
            lines += [f"    D{d}.{ACTIONS[i % len(ACTIONS)]}()" for i in range(per_drone)]
            lines.append("}")
    return "\n".join(lines) + "\n"


def chain_mission(n: int) -> str:
    body = "\n".join(f"    D1.{ACTIONS[i % len(ACTIONS)]}()" for i in range(n))
    return f"func SEQ_Chain() {{\n{body}\n}}\n"


def ping_pong_mission(hops: int) -> str:
    body = "\n".join(f"    D{1 + i % 2}.TurnOn()" for i in range(hops))
    return f"func SEQ_PingPong() {{\n{body}\n}}\n"


_STARTUP_CHILD = r"""
import json, sys, time, resource, zmq
from pathlib import Path
def rss_mb():
    for line in open('/proc/self/status'):
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024
import eamos.actors.runtime, eamos.hal.fake, eamos.program.format  # imports are not start-up
from eamos.actors.runtime import DroneRuntime, NetSettings
from eamos.hal.fake import FakeAdapter
from eamos.program.format import load_program
before = rss_mb()
t0 = time.perf_counter()
program = load_program(Path(sys.argv[1]))
t_load = time.perf_counter() - t0
rt = DroneRuntime(program, FakeAdapter(program.drone, auto=True),
                  NetSettings('tcp://127.0.0.1:0', {}), None)
rt.start()
elapsed = time.perf_counter() - t0
after = rss_mb()
rt.stop()
print(json.dumps({"nodes": len(program.nodes), "native_nodes": len(program.native_nodes()),
                  "load_s": round(t_load, 4), "startup_s": round(elapsed, 4),
                  "rss_delta_mb": round(after - before, 1), "rss_mb": round(after, 1)}))
"""


def bench_startup(tmp: Path) -> dict:
    from eamos.compiler import compile_mission

    compiled = compile_mission(stress_mission(20, 10, 25), "stress.go")
    sizes = {name: len(p.nodes) for name, p in compiled.programs.items() if name != "GCS"}
    drone = min(sizes, key=lambda n: abs(sizes[n] - 634))
    path = compiled.programs[drone].save(tmp / f"{drone}.program.json")
    runs = [
        json.loads(
            subprocess.run(
                [sys.executable, "-c", _STARTUP_CHILD, str(path)],
                capture_output=True,
                text=True,
                check=True,
                timeout=300,
            ).stdout
        )
        for _ in range(3)
    ]
    best = min(runs, key=lambda r: r["startup_s"])
    best["meg_nodes"] = compiled.meg.number_of_nodes()
    best["startup_s_runs"] = [r["startup_s"] for r in runs]
    return best


def eamos_run(tmp: Path, name: str, source: str, timeout_s: float = 900) -> dict:
    mission = tmp / f"{name}.go"
    mission.write_text(source)
    fleet = tmp / "fake_fleet.toml"
    fleet.write_text('[defaults.hal]\nadapter = "fake"\n')
    summary = tmp / f"{name}.summary.json"
    t0 = time.perf_counter()
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "eamos.cli",
            "run",
            str(mission),
            "--fleet",
            str(fleet),
            "--plain",
            "--no-svg",
            "--run-dir",
            str(tmp / name),
            "--summary",
            str(summary),
            "--ready-timeout",
            "300",
            "--timeout",
            str(timeout_s),
        ],
        capture_output=True,
        text=True,
        timeout=timeout_s + 300,
        cwd=REPO,
    )
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"eamos run {name} failed: {proc.stdout[-2000:]} {proc.stderr[-2000:]}")
    data = json.loads(summary.read_text())
    data["_wall_s"] = wall
    return data


def bench_local(tmp: Path, n: int) -> dict:
    data = eamos_run(tmp, "chain", chain_mission(n))
    acts = sorted(data["drones"]["D1"]["actions"], key=lambda a: a["start"])
    span = acts[-1]["end"] - acts[0]["start"]
    return {"nodes": n, "seconds": round(span, 4), "per_node_us": round(span / (n - 1) * 1e6, 1)}


def bench_cross(tmp: Path, hops: int) -> dict:
    data = eamos_run(tmp, "pingpong", ping_pong_mission(hops))
    acts = sorted(
        (a for d in ("D1", "D2") for a in data["drones"][d]["actions"]), key=lambda a: a["start"]
    )
    lat = [(b["start"] - a["end"]) * 1e3 for a, b in itertools.pairwise(acts)]
    lat.sort()
    return {
        "hops": len(lat),
        "p50_ms": round(statistics.median(lat), 3),
        "p99_ms": round(lat[int(0.99 * (len(lat) - 1))], 3),
        "max_ms": round(lat[-1], 3),
    }


def bench_mission(tmp: Path, drones: int, blocks: int, per_drone: int) -> dict:
    from eamos.compiler import compile_mission

    source = stress_mission(drones, blocks, per_drone)
    meg_nodes = compile_mission(source, "m.go").meg.number_of_nodes()
    data = eamos_run(tmp, "stress", source)
    starts = [a["start"] for r in data["drones"].values() for a in r["actions"]]
    ends = [a["end"] for r in data["drones"].values() for a in r["actions"]]
    return {
        "drones": drones,
        "meg_nodes": meg_nodes,
        "actions": len(starts),
        "overhead_s": round(data["duration_s"], 3),
        "first_to_last_action_s": round(max(ends) - min(starts), 3),
        "eamos_run_wall_s": round(data["_wall_s"], 2),
        "triggers_sent": sum(r["triggers_sent"] for r in data["drones"].values()),
    }


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--json", action="store_true", help="print only the JSON result")
    parser.add_argument("--quick", action="store_true", help="smaller sizes (a smoke run)")
    args = parser.parse_args()
    out: dict = {}
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        steps = [
            ("startup", lambda: bench_startup(tmp)),
            ("local_trigger", lambda: bench_local(tmp, 200 if args.quick else 2000)),
            ("cross_drone", lambda: bench_cross(tmp, 100 if args.quick else 1000)),
            (
                "mission_5000",
                lambda: bench_mission(tmp, 4 if args.quick else 20, 5 if args.quick else 10, 25),
            ),
        ]
        for name, step in steps:
            if not args.json:
                print(f"... {name}", file=sys.stderr, flush=True)
            out[name] = step()
    out["targets"] = {"startup_s": 0.2, "cross_drone_p99_ms": 2.0, "mission_5000_overhead_s": 5.0}
    print(json.dumps(out, indent=None if args.json else 1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
