#!/usr/bin/env python3
"""Benchmark of interrupts on MAVLink vehicles (issue 16): how fast and how far a cancel stops.

For each personality of ``eamos-sim-vehicle`` (PX4, ArduPilot) and each speed
(the drone type's ``horizontal_speed_mps``, default 2 and 5 m/s) it flies
``DoUntil(D1.X() > 5, FlyByX(20))`` as the runtime does (telemetry callback ->
cancel on another thread -> Land) at speed-up 1 and reports:

* ``seen_x_m``: x of the telemetry sample in which the condition was seen;
* ``reaction_s``: wall time from that sample to the vehicle decelerating
  (speed below 95 % of cruise);
* ``rest_x_m`` / ``overshoot_m``: where it came to rest, and how far past the
  condition's 5 m; ``touchdown_x_m``: where it landed;
* ``bound_m``: the tests' stated bound (v * 0.3 s + v^2 / 2a + 0.6 m).

Usage: ``python scripts/bench_braking.py --json [--speeds 2 5]``.
"""

from __future__ import annotations

import argparse
import json
import socket
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from eamos.ground.vehicles import free_port
from eamos.hal.api import ActionResult, Telemetry
from eamos.hal.mavlink.adapter import MavlinkAdapter, MavlinkSettings
from eamos.hal.sitl.vehicle import SimVehicle, VehicleOptions
from eamos.hal.sitl.wire import AutopilotName
from eamos.logs import close_logger, make_logger
from eamos.program.uniform import decode_command

STOP_DECEL = {"px4": 5.0, "ardupilot": 7.5}
WAIT_S = 120.0


def act(adapter: MavlinkAdapter, action: str, *args: float) -> ActionResult:
    """Run one action to its end."""
    done = threading.Event()
    box: list[ActionResult] = []

    def finished(result: ActionResult) -> None:
        box.append(result)
        done.set()

    adapter.run(decode_command(action, args), finished)
    if not done.wait(WAIT_S):
        raise RuntimeError(f"{action} did not end")
    return box[0]


def fly(autopilot: AutopilotName, speed: float, log_dir: Path) -> dict[str, Any]:
    """One DoUntil flight; its figures."""
    if autopilot == "px4":
        port = free_port(socket.SOCK_DGRAM)
        vconn, aconn = f"udpout:127.0.0.1:{port}", f"udpin:127.0.0.1:{port}"
    else:
        port = free_port(socket.SOCK_STREAM)
        vconn, aconn = f"tcpin:127.0.0.1:{port}", f"tcp:127.0.0.1:{port}"
    vehicle = SimVehicle(
        VehicleOptions(autopilot, vconn, prearm_delay_s=1.0, log=log_dir / f"{autopilot}.log")
    )
    log = make_logger(log_dir / f"adapter-{autopilot}-{speed:g}.log")
    settings = MavlinkSettings.from_mapping({"connection": aconn, "horizontal_speed_mps": speed})
    adapter = MavlinkAdapter("D1", settings, log)
    seen = threading.Event()
    box: dict[str, Any] = {}

    def watch(sample: Telemetry) -> None:
        handle = box.get("handle")
        if handle is not None and not seen.is_set() and sample.x_m > 5.0:
            box["seen_at"], box["seen_x"] = time.monotonic(), sample.x_m
            seen.set()
            threading.Thread(target=adapter.cancel, args=(handle,)).start()

    vehicle.start()
    try:
        adapter.start(watch)
        for action, args in (("Arm", ()), ("Takeoff", (2.0,))):
            result = act(adapter, action, *args)
            if not result.ok:
                raise RuntimeError(f"{action}: {result}")
        done = threading.Event()
        box["handle"] = adapter.run(decode_command("FlyByX", (20.0,)), lambda r: done.set())
        if not seen.wait(WAIT_S):
            raise RuntimeError("condition never seen")
        cruise = speed * 0.95
        vehicle.wait_until(lambda v: v.speed_mps < cruise, WAIT_S)
        reaction = time.monotonic() - box["seen_at"]
        done.wait(WAIT_S)
        land = act(adapter, "Land")  # waits for the brake to settle first
        rest_x = None
        for line in (log_dir / f"adapter-{autopilot}-{speed:g}.log").read_text().splitlines():
            event = json.loads(line)
            if event.get("event") == "adapter.brake.done":
                rest_x = event["x_m"]
        vehicle.wait_until(lambda v: not v.armed, WAIT_S)
        touchdown = vehicle.position[0]
    finally:
        adapter.close()
        close_logger(log)
        vehicle.stop()
    bound = speed * 0.3 + speed**2 / (2 * STOP_DECEL[autopilot]) + 0.6
    return {
        "autopilot": autopilot,
        "speed_mps": speed,
        "seen_x_m": round(box["seen_x"], 2),
        "reaction_s": round(reaction, 3),
        "rest_x_m": rest_x,
        "overshoot_m": None if rest_x is None else round(rest_x - 5.0, 2),
        "touchdown_x_m": round(touchdown, 2),
        "bound_m": round(bound, 2),
        "land": land.status,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print JSON (the default)")
    parser.add_argument("--speeds", type=float, nargs="+", default=[2.0, 5.0])
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        runs = [
            fly(autopilot, speed, Path(tmp))
            for autopilot in ("px4", "ardupilot")  # type: AutopilotName
            for speed in args.speeds
        ]
    print(json.dumps({"benchmark": "braking", "speedup": 1, "runs": runs}, indent=2))


if __name__ == "__main__":
    main()
