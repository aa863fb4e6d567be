#!/usr/bin/env python3
"""Benchmark of a long mission on one drone process: its final report and its memory; prints JSON.

A one-drone mission of N actions (Arm, ``RepeatFor(N - 2)`` of ``PauseFor(0.001)``,
Disarm) flown by ``eamos run``'s local fleet (one ``eamos-node`` process, simulated
at ``--speedup 1000``), for a short and a long N, each in a fresh process.
Printed per N: wall time, actions per second, the actions the ground station's
summary lists and folds (docs/logs.md "Long missions"), the report's size on the
wire (MessagePack, limit 1 MiB), and the drone process's resident memory
(``/proc/<pid>/status`` VmRSS, sampled every 0.2 s).  The slope of the final RSS
between the two N is the memory a drone keeps per action.

Usage: ``python scripts/bench_long_mission.py`` (``--quick``: 1 000 and 5 000 actions).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

MISSION = """\
func SEQ_Long() {{
	Drone1.Arm()
	RepeatFor({repeat}, SEQ_Step)
	Drone1.Disarm()
}}

func SEQ_Step() {{
	Drone1.PauseFor(0.001)
}}
"""


class RssSampler:
    """Samples the resident memory of this run's drone process (``/proc``) every 0.2 s."""

    def __init__(self, marker: str) -> None:
        self.marker = marker.encode()
        self.samples: list[int] = []  # KiB, in time order
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._loop, daemon=True)
        self.thread.start()

    def _rss(self) -> int | None:
        for proc in Path("/proc").iterdir():
            if not proc.name.isdigit():
                continue
            try:
                cmdline = (proc / "cmdline").read_bytes()
                if b"eamos.cli.node" not in cmdline or self.marker not in cmdline:
                    continue
                for line in (proc / "status").read_text().splitlines():
                    if line.startswith("VmRSS:"):
                        return int(line.split()[1])
            except OSError:
                continue
        return None

    def _loop(self) -> None:
        while not self.done.wait(0.2):
            rss = self._rss()
            if rss is not None:
                self.samples.append(rss)

    def stop(self) -> list[int]:
        self.done.set()
        self.thread.join()
        return self.samples


def one_run(actions: int) -> dict[str, object]:
    """Fly the mission of ``actions`` actions here; its figures (run in a fresh process)."""
    from eamos.compiler import compile_mission, write_artifacts
    from eamos.config import FleetConfig
    from eamos.ground import Limits, LocalMission, fly_local, make_display
    from eamos.net import wire

    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(tmp) / "run"
        run_dir.mkdir()
        compiled = compile_mission(MISSION.format(repeat=actions - 2), "long.go")
        write_artifacts(compiled, run_dir, svg=False)
        started = time.monotonic()
        sampler = RssSampler(str(run_dir))
        summary = fly_local(
            LocalMission(compiled.mission.name, compiled.mission_id, compiled.programs),
            run_dir,
            FleetConfig.empty(),
            Limits(120.0, 3600.0),
            threading.Event(),
            speedup=1000.0,
            display=make_display(False, ["Drone1"]),
        )
        wall = time.monotonic() - started
        rss = sampler.stop()
        report = summary.drones["Drone1"].report
        assert report is not None, "no report reached the ground station"
        frames = wire.encode(wire.Report(mission="m", sender="Drone1", report=report.to_json()))
        return {
            "actions": actions,
            "ok": summary.ok,
            "wall_s": round(wall, 2),
            "actions_per_s": round(actions / wall, 1),
            "action_count": report.action_count,
            "listed": len(report.actions),
            "folded": report.folded.count if report.folded else 0,
            "report_wire_bytes": len(frames[-1]),
            # The drone process's resident memory: at its last sample (after the last
            # action, while it reports) and the largest seen.
            "drone_final_rss_kib": rss[-1] if rss else None,
            "drone_peak_rss_kib": max(rss) if rss else None,
        }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1 000 and 5 000 actions")
    parser.add_argument("--one", type=int, help=argparse.SUPPRESS)  # the child's part
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one_run(args.one)))
        return
    sizes = (1_000, 5_000) if args.quick else (2_000, 20_000)
    runs = []
    for n in sizes:
        out = subprocess.run(
            [sys.executable, __file__, "--one", str(n)],
            capture_output=True,
            text=True,
            check=True,
            timeout=3600,
        ).stdout
        runs.append(json.loads(out.strip().splitlines()[-1]))
    small, big = runs
    slope = (
        (big["drone_final_rss_kib"] - small["drone_final_rss_kib"])
        * 1024
        / (big["actions"] - small["actions"])
    )
    print(json.dumps({"runs": runs, "drone_bytes_per_action": round(slope)}, indent=1))


if __name__ == "__main__":
    main()
