#!/usr/bin/env python3
"""Benchmark of resting simulated drones (issue 15 item 3): what hovering costs the machine.

Starts ``--drones`` SimAdapters (in this process, speed-up ``--speedup``), arms them and
takes them off to 5 m, then lets them hover for ``--seconds`` of wall time in a
``Hold``, and reports per drone and in total:

* ``wakeups_per_s``: how often each pacing thread woke (it used to wake every tick,
  whatever the vehicle did: 50 a second at speed-up 1, 200 at speed-up 4 and more);
* ``cpu_s`` / ``cpu_share``: the process CPU time during the hover, and as a share of
  one core;
* ``stepping_wakeups_per_s``: what stepping every tick would have cost, for comparison.

Usage: ``python scripts/bench_sim_rest.py --json [--drones 100] [--seconds 5] [--speedup 1]``.
"""

from __future__ import annotations

import argparse
import json
import threading
import time
from typing import Any

from eamos.hal.api import ActionResult, Telemetry
from eamos.hal.sim.adapter import MIN_WALL_TICK_S, SIM_DT_S, SimAdapter, SimSettings
from eamos.program.uniform import Arm, Command, Hold, Takeoff

WAIT_S = 300.0


def _run_all(sims: list[SimAdapter], command: Command) -> list[ActionResult]:
    """Run ``command`` on every drone; wait for every result (events, not sleeps)."""
    results: list[ActionResult | None] = [None] * len(sims)
    left = threading.Semaphore(0)

    def done_for(i: int) -> Any:
        def done(result: ActionResult) -> None:
            results[i] = result
            left.release()

        return done

    for i, sim in enumerate(sims):
        sim.run(command, done_for(i))
    for _ in sims:
        if not left.acquire(timeout=WAIT_S):
            raise SystemExit(f"{command.action}: not every drone answered within {WAIT_S} s")
    return [r for r in results if r is not None]


def _wall_tick_s(speedup: float) -> float:
    """The wall time between two ticks of a thread that steps every tick (the old pacing)."""
    steps = max(1, round(MIN_WALL_TICK_S * speedup / SIM_DT_S))
    return steps * SIM_DT_S / speedup


def bench(drones: int, seconds: float, speedup: float) -> dict[str, Any]:
    """Hover ``drones`` simulated drones for ``seconds`` of wall time; the figures."""
    settings = SimSettings(speedup=speedup, arm_delay_s=0.0)
    sims = [SimAdapter(f"D{i}", settings) for i in range(drones)]

    def ignore(_: Telemetry) -> None:
        return None

    for sim in sims:
        sim.start(ignore)
    try:
        for command in (Arm(), Takeoff(5.0)):
            bad = [r for r in _run_all(sims, command) if not r.ok]
            if bad:
                raise SystemExit(f"{command.action} failed: {bad[0].reason}")
        hold = Hold(seconds * speedup)
        before = sum(s.wakeups for s in sims)
        cpu0, wall0 = time.process_time(), time.monotonic()
        _run_all(sims, hold)
        cpu, wall = time.process_time() - cpu0, time.monotonic() - wall0
        woke = sum(s.wakeups for s in sims) - before
    finally:
        for sim in sims:
            sim.close()
    return {
        "drones": drones,
        "speedup": speedup,
        "hover_wall_s": round(wall, 3),
        "wakeups_per_s": round(woke / wall / drones, 2),
        "stepping_wakeups_per_s": round(1.0 / _wall_tick_s(speedup), 2),
        "cpu_s": round(cpu, 3),
        "cpu_share": round(cpu / wall, 3),
    }


def main() -> None:
    """Parse the options, run the benchmark, print the figures."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--drones", type=int, default=100)
    p.add_argument("--seconds", type=float, default=5.0)
    p.add_argument("--speedup", type=float, default=1.0)
    p.add_argument("--json", action="store_true", help="print JSON (the only output format)")
    args = p.parse_args()
    print(json.dumps(bench(args.drones, args.seconds, args.speedup), indent=1))


if __name__ == "__main__":
    main()
