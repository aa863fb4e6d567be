#!/usr/bin/env python3
"""Benchmark of the browser monitor; prints JSON.

* ``hub_load``: a synthetic fleet (20 drones, 20 Hz telemetry each, and an action
  progress per drone every second, whose node waits for the same node of the
  drone before it: the live link counts work too) fed through the monitor's hub and served by
  its web server to one websocket client, for ``--seconds``: what one event
  costs the ground station's thread (p50/p99 µs in ``Hub.event``), the process's
  CPU (the feeder's own share measured without a server and subtracted), the
  bytes and messages per second to the browser, coalesced updates and dropped
  frames.
* ``trigger_latency``: the cross-drone trigger latency (p50/p99, ms; a ping-pong
  of zero-duration actions between D1 and D2, as ``bench_runtime.py``'s
  ``cross_drone``) of ``eamos run`` without the monitor, and with ``--monitor``
  and a websocket client connected.
* ``trigger_latency_20_drones_20hz``: the same ping-pong while 18 simulated drones
  fly (telemetry at 20 Hz each, all of it reaching the ground station and the
  monitor), without and with the monitor and a page; with the ``eamos run``
  process's CPU seconds (the ground station, plus the monitor's server).

Usage: ``python scripts/bench_monitor.py [--quick] [--no-fleet]``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from eamos.ground.links import LinkArc, LinkGraph  # noqa: E402
from eamos.monitor.hub import Hub  # noqa: E402
from eamos.monitor.server import MonitorServer  # noqa: E402
from eamos.monitor.setup import MissionSetup, NodeInfo, ParticipantSetup  # noqa: E402
from eamos.net import wire  # noqa: E402


def synthetic_setup(drones: int, nodes: int) -> MissionSetup:
    """Each drone a chain of actions; node i of each drone also waits for node i of the
    drone before it (a cross-drone arc), so the live link counts do their work."""
    parts = []
    owner, kinds, arcs = {}, {}, []
    for d in range(1, drones + 1):
        name = f"D{d}"
        infos = tuple(
            NodeInfo(f"n{d}_{i}", "action", f"FlyByX({i})", name, "FlyByX") for i in range(nodes)
        )
        parts.append(ParticipantSetup(name, "#ffe066", (float(d), 0.0), infos, ""))
        for i in range(nodes):
            owner[f"n{d}_{i}"], kinds[f"n{d}_{i}"] = name, "action"
            if i:
                arcs.append(LinkArc(f"n{d}_{i - 1}", f"n{d}_{i}", "seq", False))
            if d > 1:
                arcs.append(LinkArc(f"n{d - 1}_{i}", f"n{d}_{i}", "seq", True))
    graph = LinkGraph(owner, kinds, {k: () for k in owner}, tuple(arcs))
    return MissionSetup("bench", "m", tuple(parts), links=graph)


def _feed(hub: Hub | None, drones: int, hz: float, seconds: float) -> list[float]:
    """Telemetry at ``hz`` per drone and one progress per drone per second; event costs (s)."""
    costs: list[float] = []
    period = 1.0 / hz
    start = time.monotonic()
    for tick in itertools.count():
        due = start + tick * period
        if due - start >= seconds:
            break
        # Pacing a synthetic load (a benchmark, not product code).
        time.sleep(max(0.0, due - time.monotonic()))
        for d in range(1, drones + 1):
            name = f"D{d}"
            t = tick * period
            msg: Any = wire.TelemetrySample(
                mission="m", sender=name, time_s=t, x_m=t, y_m=0.1 * d, z_m=1.5, lat_deg=0.0,
                lon_deg=0.0, alt_m=1.5, battery_pct=90.0, armed=True, landed=False,
            )  # fmt: skip
            msgs = [msg]
            if tick % int(hz) == 0:
                node = f"n{d}_{(tick // int(hz)) % 10}"
                msgs.append(
                    wire.Progress(mission="m", sender=name, state="running", node=node,
                                  action="FlyByX", detail={"iteration": []})
                )  # fmt: skip
            for m in msgs:
                t0 = time.perf_counter()
                if hub is not None:
                    hub.event(name, m)
                costs.append(time.perf_counter() - t0)
    return costs


def read_page(port: int, stop: threading.Event, counts: dict[str, int]) -> None:
    """One page of the monitor at ``port``: count the bytes and messages its websocket
    gets until ``stop`` is set or the server stops."""
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    with connect(f"ws://127.0.0.1:{port}/ws") as ws:
        while not stop.is_set():
            try:
                text = ws.recv(timeout=0.5)
            except TimeoutError:
                continue
            except ConnectionClosed:  # the server stopped (the run ended)
                return
            counts["bytes"] += len(text)
            counts["messages"] += 1


def open_page(
    server: MonitorServer,
    stop: threading.Event,
    counts: dict[str, int],
    timeout_s: float = 30.0,
) -> threading.Thread:
    """:func:`read_page` of ``server`` in a thread, once the server counts it connected
    (a benchmark's bounded wait); the thread."""
    reader = threading.Thread(target=read_page, args=(server.port, stop, counts), daemon=True)
    reader.start()
    deadline = time.monotonic() + timeout_s
    while server.clients() == 0:
        if time.monotonic() > deadline:
            raise RuntimeError("the monitor's websocket did not connect")
        time.sleep(0.01)
    return reader


def bench_hub(drones: int, hz: float, seconds: float) -> dict[str, Any]:
    cpu0, wall0 = time.process_time(), time.monotonic()
    _feed(None, drones, hz, seconds)
    feeder_cpu = time.process_time() - cpu0
    feeder_wall = time.monotonic() - wall0

    hub = Hub(synthetic_setup(drones, 10))
    server = MonitorServer(hub).start()
    counts = {"bytes": 0, "messages": 0}
    stop = threading.Event()
    reader = open_page(server, stop, counts)
    cpu0, wall0 = time.process_time(), time.monotonic()
    costs = _feed(hub, drones, hz, seconds)
    server.stop(drain_s=5.0)
    cpu, wall = time.process_time() - cpu0, time.monotonic() - wall0
    stop.set()
    reader.join(timeout=10)
    costs.sort()
    stats = hub.stats()
    return {
        "drones": drones,
        "telemetry_hz": hz,
        "seconds": round(wall, 2),
        "events": stats["events"],
        "event_cost_p50_us": round(costs[len(costs) // 2] * 1e6, 1),
        "event_cost_p99_us": round(costs[int(0.99 * (len(costs) - 1))] * 1e6, 1),
        "server_cpu_percent": round(100 * (cpu - feeder_cpu * wall / feeder_wall) / wall, 1),
        "process_cpu_percent": round(100 * cpu / wall, 1),
        "bytes_per_s_to_browser": round(counts["bytes"] / wall),
        "messages_per_s_to_browser": round(counts["messages"] / wall, 1),
        "patches": stats["patches"],
        "coalesced": stats["coalesced"],
        "dropped": stats["dropped"],
    }


def ping_pong(hops: int) -> str:
    body = "\n".join(f"    D{1 + i % 2}.TurnOn()" for i in range(hops))
    return f"func SEQ_PingPong() {{\n{body}\n}}\n"


def _latency(summary: dict[str, Any]) -> dict[str, Any]:
    acts = sorted(
        (a for d in ("D1", "D2") for a in summary["drones"][d]["actions"]), key=lambda a: a["start"]
    )
    lat = sorted((b["start"] - a["end"]) * 1e3 for a, b in itertools.pairwise(acts))
    return {**_percentiles(lat), "_samples": lat}


def _percentiles(lat: list[float]) -> dict[str, Any]:
    lat = sorted(lat)
    return {
        "hops": len(lat),
        "p50_ms": round(statistics.median(lat), 3),
        "p99_ms": round(lat[int(0.99 * (len(lat) - 1))], 3),
    }


def run_once(
    tmp: Path,
    name: str,
    hops: int,
    monitor: bool,
    source: str | None = None,
    fleet: Path | None = None,
) -> dict[str, Any]:
    mission = tmp / f"{name}.go"
    mission.write_text(source or ping_pong(hops))
    if fleet is None:
        fleet = tmp / "fake.toml"
        fleet.write_text('[defaults.hal]\nadapter = "fake"\n')
    argv = [sys.executable, "-m", "eamos.cli", "run", str(mission), "--fleet", str(fleet),
            "--plain", "--no-svg", "--no-check", "--run-dir", str(tmp / name),
            "--summary", str(tmp / f"{name}.json"), "--timeout", "600"]  # fmt: skip
    if monitor:
        argv.append("--monitor")
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert proc.stdout is not None
    counts = {"bytes": 0, "messages": 0}
    stop = threading.Event()
    reader = None
    out = []
    cpu = 0.0
    for line in proc.stdout:
        out.append(line)
        if line.startswith("mission ") and " in " in line:  # the end: the ground's CPU so far
            cpu = _cpu_s(proc.pid)
        found = re.search(r"monitor: http://127\.0\.0\.1:(\d+)/", line)
        if found:
            reader = threading.Thread(
                target=read_page, args=(int(found.group(1)), stop, counts), daemon=True
            )
            reader.start()
    code = proc.wait()
    stop.set()
    if reader is not None:
        reader.join(timeout=10)
    if code not in (0, 1):
        raise RuntimeError("".join(out[-30:]))
    result = _latency(json.loads((tmp / f"{name}.json").read_text()))
    result["ground_process_cpu_s"] = round(cpu, 2)
    if monitor:
        result["bytes_to_browser"] = counts["bytes"]
    return result


def loaded_mission(drones: int, hops: int) -> str:
    """D1/D2 play ping-pong while D3..DN fly (their telemetry flowing at 20 Hz)."""
    flyers = [f"D{d}" for d in range(3, drones + 1)]
    pong = [f"D{1 + i % 2}.TurnOn()" for i in range(hops)]

    def block(name: str, body: list[str]) -> str:
        return f"func {name}() {{\n" + "\n".join(f"    {b}" for b in body) + "\n}\n"

    text = block("SEQ_Load", ["PAR_Up()", "PAR_Fly()", "PAR_Down()"])
    text += block("PAR_Up", [f"SEQ_U{d}()" for d in flyers])
    text += block("PAR_Fly", ["SEQ_PingPong()", *(f"SEQ_F{d}()" for d in flyers)])
    text += block("PAR_Down", [f"SEQ_D{d}()" for d in flyers])
    text += block("SEQ_PingPong", pong)
    for d in flyers:
        text += block(f"SEQ_U{d}", [f"{d}.Arm()", f"{d}.Takeoff(2)"])
        text += block(f"SEQ_F{d}", [f"{d}.FlyByX(40)", f"{d}.FlyByX(-40)"])
        text += block(f"SEQ_D{d}", [f"{d}.Land()", f"{d}.Disarm()"])
    return text


def _cpu_s(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` (Linux /proc)."""
    import os

    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def bench_latency(hops: int) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        return {
            "without_monitor": _public(run_once(Path(tmp), "plain", hops, False)),
            "with_monitor": _public(run_once(Path(tmp), "monitored", hops, True)),
        }


def _public(result: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in result.items() if not k.startswith("_")}


def bench_loaded(drones: int, hops: int, rounds: int = 1) -> dict[str, Any]:
    """The ping-pong latency while the other drones fly with 20 Hz telemetry, +/- monitor.

    With ``rounds`` > 1 the two runs alternate (without, with; then with, without; ...),
    so a slow spell of a shared machine does not fall on one side only; the medians of
    the rounds' p99 and their ratio are reported beside each round.
    """
    out: dict[str, Any] = {"drones": drones, "telemetry_hz": 20}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        fleet = folder / "loaded.toml"
        fleet.write_text(
            # The ground station (and the monitor) take every drone's 20 Hz, not the default 2 Hz.
            '[net]\nground_telemetry_hz = 20\n[defaults.hal]\nadapter = "fake"\n'
            + "".join(
                f'[drones.D{d}.hal]\nadapter = "sim"\ntelemetry_hz = 20\n'
                for d in range(3, drones + 1)
            )
        )
        source = loaded_mission(drones, hops)
        runs: dict[str, list[dict[str, Any]]] = {"without_monitor": [], "with_monitor": []}
        order = [("without_monitor", False), ("with_monitor", True)]
        for i in range(rounds):
            for name, monitor in order if i % 2 == 0 else order[::-1]:
                result = run_once(folder, f"{name}{i}", hops, monitor, source=source, fleet=fleet)
                runs[name].append(result)
    for name, results in runs.items():
        out[name] = _public(results[0]) if rounds == 1 else [_public(r) for r in results]
    if rounds > 1:
        med = {n: statistics.median(r["p99_ms"] for r in rs) for n, rs in runs.items()}
        out["p99_ms_median"] = med
        out["p99_ratio_with_to_without"] = round(med["with_monitor"] / med["without_monitor"], 3)
        # All rounds' hops together: a p99 over rounds x hops samples is steadier than
        # any one round's (whose p99 rests on its ten slowest hops).
        pooled = {n: _percentiles([x for r in rs for x in r["_samples"]]) for n, rs in runs.items()}
        out["pooled"] = pooled
        out["pooled_p99_ratio_with_to_without"] = round(
            pooled["with_monitor"]["p99_ms"] / pooled["without_monitor"]["p99_ms"], 3
        )
        out["ground_cpu_s_median"] = {
            n: statistics.median(r["ground_process_cpu_s"] for r in rs) for n, rs in runs.items()
        }
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs")
    parser.add_argument("--seconds", type=float, default=None, help="hub_load duration")
    parser.add_argument(
        "--no-fleet", action="store_true", help="skip the 20-process loaded run (heavy)"
    )
    parser.add_argument(
        "--rounds", type=int, default=1, help="alternate the loaded runs this many times"
    )
    args = parser.parse_args()
    seconds = args.seconds or (3.0 if args.quick else 10.0)
    out: dict[str, Any] = {
        "hub_load": bench_hub(20, 20.0, seconds),
        "trigger_latency": bench_latency(100 if args.quick else 400),
    }
    if not args.no_fleet:
        out["trigger_latency_20_drones_20hz"] = bench_loaded(
            8 if args.quick else 20, 300 if args.quick else 1000, args.rounds
        )
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
