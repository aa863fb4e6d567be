#!/usr/bin/env python3
"""Benchmark of a fleet's size on one machine: a generated relay mission for N drones; prints JSON.

The mission (:func:`relay_mission`): each drone arms and takes off after the
previous one (a relay of cross-drone triggers, D1 to DN), then every drone
flies a 1 m square at once, then the drones land and disarm one after the
other in reverse order (DN to D1).  It is flown by ``eamos run``'s local fleet
(:func:`eamos.ground.fly_local`: simulated quadcopters, CURVE on every link),
each N in a fresh process, and reported per N:

* ``phases_s``: ``compile`` (the mission text to programs), ``startup`` (from
  the fleet's start, keys and processes included, until every drone is ready),
  ``flight`` (the start trigger until every drone resolved), ``shutdown`` (from
  then until the last process ended and the summary was written);
* ``simulated_flight_s``: the flight time the simulated actions alone would take
  (the mission in virtual time, :func:`eamos.virtual.run_virtual`, divided by the
  speedup), and ``flight_ratio``, the measured flight over it;
* ``cpu_s``: CPU seconds (user + system) of the run (:func:`eamos.ground.fly_local`,
  from the fleet's keys to the summary: this process's share and every drone
  process); ``bench_cpu_s``: this process's before it (compiling, writing the
  artifacts and the virtual run that gives ``simulated_flight_s``), not the fleet's;
* ``peak_rss_mb``: the largest sum of the resident memory of this process and
  all its descendants, sampled every 0.25 s (psutil if installed, else ``/proc``);
* ``retransmissions`` (summed over every participant's report),
  ``peer_lost_events`` (``mission.peer.lost`` lines in all the run's logs);
* ``node_ready_s``: from the fleet's start (keys, configs, the ground station's
  runtime, then the processes) to each drone's ``mission.ready`` (its mission
  log), first and last: with one drone, an upper bound of one ``eamos-node``'s
  start-up (imports, program, sockets, CURVE handshakes);
* ``relay_gap_ms``: p50 / p99 / max of the time from the end of one drone's relay
  action to the start of the next drone's (one cross-drone trigger each, both
  relays), from the drones' reports.

* ``telemetry_samples_sent``: telemetry samples all drones sent (their links'
  ``messages_sent``), at ``ground_telemetry_hz`` (the fleet file's ``[net]`` key,
  docs/configuration.md; ``--ground-telemetry-hz``, default the fleet's default).

* ``ground_cpu_s``: this process's CPU seconds during the run (the ground station,
  its keys, configs and summary, and with ``--monitor`` the monitor), a part of
  ``cpu_s``;
* with ``--monitor``: the live browser monitor is served as ``eamos run --monitor``
  serves it (:func:`eamos.monitor.display.start_live_monitor`) with one websocket
  client reading every update in a thread of this process (its CPU counted in
  ``ground_cpu_s`` too), and ``monitor`` gives the bytes and messages the page got;
  the monitor's added CPU is ``ground_cpu_s`` with it minus without, over ``flight``.

``--drones-per-process N|auto`` runs N drones per ``eamos-node`` process
(``eamos run --drones-per-process``; default ``auto``, about one per core, as
``eamos run``; 1: a process per drone); ``processes`` says how many there were.

Usage: ``python scripts/bench_scale.py --json [--drones 10,25,50,100] [--speedup 10]
[--drones-per-process 1] [--ground-telemetry-hz 20] [--monitor]``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

DEFAULT_DRONES = "10,25,50"
DEFAULT_SPEEDUP = 10.0
#: The keys each run's JSON has (the smoke test in tests/scale checks them).
FIELDS = (
    "drones",
    "speedup",
    "ok",
    "outcome",
    "phases_s",
    "simulated_flight_s",
    "flight_ratio",
    "cpu_s",
    "ground_cpu_s",
    "bench_cpu_s",
    "monitor",
    "peak_rss_mb",
    "retransmissions",
    "peer_lost_events",
    "relay_gap_ms",
    "node_ready_s",
    "processes",
    "ground_telemetry_hz",
    "telemetry_samples_sent",
)
PHASES = ("compile", "startup", "flight", "shutdown")


def relay_mission(drones: int) -> str:
    """The relay mission for ``drones`` drones (D1 ... DN) as mission text."""
    names = [f"D{d}" for d in range(1, drones + 1)]
    lines = [f"var {n} Quadcopter" for n in names]
    lines += ["func SEQ_Relay() {", "\tSEQ_Up()", "\tPAR_Squares()", "\tSEQ_Down()", "}"]
    lines.append("func SEQ_Up() {")
    for n in names:
        lines += [f"\t{n}.Arm()", f"\t{n}.Takeoff(1.5)"]
    lines.append("}")
    lines.append("func PAR_Squares() {")
    lines += [f"\tSEQ_Square_{n}()" for n in names]
    lines.append("}")
    for n in names:
        lines.append(f"func SEQ_Square_{n}() {{")
        lines += [f"\t{n}.FlyByX(1)", f"\t{n}.FlyByY(1)", f"\t{n}.FlyByX(-1)", f"\t{n}.FlyByY(-1)"]
        lines.append("}")
    lines.append("func SEQ_Down() {")
    for n in reversed(names):
        lines += [f"\t{n}.Land()", f"\t{n}.Disarm()"]
    lines.append("}")
    return "\n".join(lines) + "\n"


class RssSampler:
    """The largest summed resident memory of this process and its descendants (sampled)."""

    def __init__(self, period_s: float = 0.25) -> None:
        self.period_s = period_s
        self.peak_kib = 0
        self.done = threading.Event()
        try:
            import psutil
        except ImportError:
            self._sample = self._sample_proc
        else:
            me = psutil.Process()

            def sample_psutil() -> int:
                total = 0
                for proc in [me, *me.children(recursive=True)]:
                    try:
                        total += proc.memory_info().rss
                    except psutil.Error:  # ended meanwhile
                        continue
                return total // 1024

            self._sample = sample_psutil
        self.thread = threading.Thread(target=self._loop, name="rss", daemon=True)
        self.thread.start()

    @staticmethod
    def _sample_proc() -> int:
        parents: dict[int, int] = {}
        rss: dict[int, int] = {}
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            try:
                for line in (entry / "status").read_text().splitlines():
                    if line.startswith("PPid:"):
                        parents[int(entry.name)] = int(line.split()[1])
                    elif line.startswith("VmRSS:"):
                        rss[int(entry.name)] = int(line.split()[1])
            except OSError:
                continue
        family = {os.getpid()}
        grew = True
        while grew:
            grew = False
            for pid, ppid in parents.items():
                if ppid in family and pid not in family:
                    family.add(pid)
                    grew = True
        return sum(rss.get(pid, 0) for pid in family)

    def _loop(self) -> None:
        while not self.done.wait(self.period_s):
            self.peak_kib = max(self.peak_kib, self._sample())

    def stop(self) -> int:
        """Stop sampling; the peak in KiB."""
        self.done.set()
        self.thread.join()
        return self.peak_kib


class PhaseClock:
    """A display for :func:`fly_local` that notes when every drone is ready and resolved."""

    refresh_s = 0.5

    def __init__(self, drones: list[str]) -> None:
        self.drones = drones
        self.ready_at: float | None = None
        self.resolved_at: float | None = None
        self._waiting = set(drones)  # not resolved yet

    def __enter__(self) -> PhaseClock:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def watch(self, station: Any) -> None:
        return None  # each event's own view tells (see event)

    def event(self, name: str, view: Any, msg: Any) -> None:
        # Counted from each event's own view: a snapshot of every drone per event would
        # make the benchmark's display cost O(N) per message, measured as the fleet's.
        if view.resolved and view.name in self._waiting:
            self._waiting.discard(view.name)
            if not self._waiting and self.ready_at is not None and self.resolved_at is None:
                self.resolved_at = time.monotonic()

    def refresh(self) -> None:
        return None

    def say(self, text: str) -> None:
        if text.startswith("all drones ready") and self.ready_at is None:
            self.ready_at = time.monotonic()


class MonitorPage:
    """The live monitor served as ``eamos run --monitor`` serves it, and one page's
    websocket reading every update (in a thread of this process)."""

    def __init__(self, run_dir: Path, stop: threading.Event, clock: PhaseClock) -> None:
        from bench_monitor import open_page  # a sibling script: the page bench_monitor reads

        from eamos.monitor.display import TeeDisplay, start_live_monitor

        self.server = start_live_monitor(run_dir, stop, clock.say)
        self.display = TeeDisplay(clock, self.server.hub)  # type: ignore[arg-type]
        self.counts = {"bytes": 0, "messages": 0}
        self._done = threading.Event()
        self._reader = open_page(self.server, self._done, self.counts)

    def close(self) -> dict[str, int]:
        """Stop serving; what the page got."""
        self.server.stop()
        self._done.set()
        self._reader.join(timeout=10.0)
        return {"bytes_to_page": self.counts["bytes"], "messages_to_page": self.counts["messages"]}


def relay_gaps_ms(reports: dict[str, Any], drones: int) -> list[float]:
    """End of one drone's relay action to the start of the next one's, both relays (ms)."""

    def entry(drone: str, action: str) -> Any:
        report = reports.get(drone)
        if report is None:
            return None
        return next((a for a in report.actions if a.action == action), None)

    names = [f"D{d}" for d in range(1, drones + 1)]
    gaps: list[float] = []
    for earlier, later in itertools.pairwise(names):  # up: Takeoff then next Arm
        a, b = entry(earlier, "Takeoff"), entry(later, "Arm")
        if a is not None and b is not None:
            gaps.append((b.start - a.end) * 1000)
    back = list(reversed(names))
    for earlier, later in itertools.pairwise(back):  # down: Disarm then next Land
        a, b = entry(earlier, "Disarm"), entry(later, "Land")
        if a is not None and b is not None:
            gaps.append((b.start - a.end) * 1000)
    return gaps


def percentile(values: list[float], q: float) -> float | None:
    """The ``q`` quantile (0..1) of ``values``, nearest rank; None when empty."""
    if not values:
        return None
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, round(q * len(ordered)) - 1))]


def count_in_logs(log_root: Path, needle: bytes) -> int:
    """How many lines of all files under ``log_root`` contain ``needle``."""
    total = 0
    for path in log_root.rglob("*"):
        if path.is_file():
            try:
                with path.open("rb") as f:
                    total += sum(1 for line in f if needle in line)
            except OSError:
                continue
    return total


def ready_times(log_root: Path, names: list[str]) -> list[float]:
    """Wall-clock time of each drone's ``mission.ready`` line (drones without one left out)."""
    times = []
    for name in names:
        path = log_root / name / "mission.log"
        try:
            lines = path.read_text(encoding="utf-8").splitlines()
        except OSError:
            continue
        for line in lines:
            if '"mission.ready"' in line:
                times.append(float(json.loads(line)["ts"]))
                break
    return times


def one_run(
    drones: int,
    speedup: float,
    timeout_s: float,
    per_process: int | None,
    keep: str = "",
    ground_telemetry_hz: float | None = None,
    monitor: bool = False,
) -> dict[str, Any]:
    """Fly the relay mission with ``drones`` drones here (run in a fresh process)."""
    import dataclasses

    from eamos.compiler import compile_mission, write_artifacts
    from eamos.config import FleetConfig
    from eamos.ground import Limits, LocalMission, fly_local
    from eamos.ground.local import process_groups
    from eamos.virtual import run_virtual, sim_vehicles

    sampler = RssSampler()
    with tempfile.TemporaryDirectory(prefix="bench_scale-") as tmp:
        run_dir = Path(keep) / f"run-{drones}" if keep else Path(tmp) / "run"
        run_dir.mkdir(parents=True)
        t0 = time.monotonic()
        compiled = compile_mission(relay_mission(drones), "relay.go")
        compile_s = time.monotonic() - t0
        write_artifacts(compiled, run_dir, svg=False)
        virtual = run_virtual(compiled.programs, sim_vehicles(None))
        names = [f"D{d}" for d in range(1, drones + 1)]
        clock = PhaseClock(names)
        fleet = FleetConfig.empty()
        if ground_telemetry_hz is not None:
            fleet = dataclasses.replace(fleet, ground_telemetry_hz=ground_telemetry_hz)
        stop = threading.Event()
        page = MonitorPage(run_dir, stop, clock) if monitor else None
        started = time.monotonic()
        started_wall = time.time()
        before = resource.getrusage(resource.RUSAGE_SELF)
        try:
            summary = fly_local(
                LocalMission(compiled.mission.name, compiled.mission_id, compiled.programs),
                run_dir,
                fleet,
                Limits(ready_timeout_s=max(60.0, 3.0 * drones), timeout_s=timeout_s),
                stop,
                speedup=speedup,
                display=page.display if page is not None else clock,  # type: ignore[arg-type]
                drones_per_process=per_process,
            )
        finally:
            watched = page.close() if page is not None else None
        ended = time.monotonic()
        peak_kib = sampler.stop()
        me = resource.getrusage(resource.RUSAGE_SELF)
        kids = resource.getrusage(resource.RUSAGE_CHILDREN)  # the reaped drone processes
        ground_cpu = me.ru_utime + me.ru_stime - before.ru_utime - before.ru_stime
        reports = {n: r.report for n, r in summary.drones.items() if r.report is not None}
        retrans = sum(r.retransmissions for r in reports.values())
        if summary.ground_station is not None:
            retrans += summary.ground_station.retransmissions
        gaps = relay_gaps_ms(reports, drones)
        ready = [t - started_wall for t in ready_times(run_dir / "logs", names)]
        ready_at = clock.ready_at
        resolved_at = clock.resolved_at
        simulated = virtual.duration_s / speedup
        flight = None if ready_at is None or resolved_at is None else resolved_at - ready_at
        return {
            "drones": drones,
            "speedup": speedup,
            "ok": summary.ok,
            "outcome": summary.outcome,
            "phases_s": {
                "compile": round(compile_s, 3),
                "startup": None if ready_at is None else round(ready_at - started, 3),
                "flight": None if flight is None else round(flight, 3),
                "shutdown": round(ended - (resolved_at or ready_at or started), 3),
            },
            "simulated_flight_s": round(simulated, 3),
            "flight_ratio": None if flight is None else round(flight / simulated, 2),
            "cpu_s": round(ground_cpu + kids.ru_utime + kids.ru_stime, 2),
            "ground_cpu_s": round(ground_cpu, 2),
            "bench_cpu_s": round(before.ru_utime + before.ru_stime, 2),
            "monitor": watched,
            "peak_rss_mb": round(peak_kib / 1024, 1),
            "retransmissions": retrans,
            "peer_lost_events": count_in_logs(run_dir / "logs", b'"mission.peer.lost"'),
            "relay_gap_ms": {
                "count": len(gaps),
                "p50": None if not gaps else round(statistics.median(gaps), 2),
                "p99": None if not gaps else round(percentile(gaps, 0.99) or 0.0, 2),
                "max": None if not gaps else round(max(gaps), 2),
            },
            "node_ready_s": {
                "first": round(min(ready), 3) if ready else None,
                "last": round(max(ready), 3) if ready else None,
            },
            "processes": len(process_groups(names, per_process)),  # eamos-node processes
            "ground_telemetry_hz": fleet.ground_telemetry_hz,
            "telemetry_samples_sent": sum(
                int(r.net.get("messages_sent", {}).get("TelemetrySample", 0))
                for r in reports.values()
            ),
        }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print JSON (the default)")
    parser.add_argument(
        "--drones", default=DEFAULT_DRONES, help=f"fleet sizes, comma-separated ({DEFAULT_DRONES})"
    )
    parser.add_argument(
        "--speedup", type=float, default=DEFAULT_SPEEDUP, help="simulated time speed-up"
    )
    parser.add_argument(
        "--timeout", type=float, default=900.0, help="the mission's timeout per run (s)"
    )
    parser.add_argument(
        "--drones-per-process",
        default="auto",
        metavar="N|auto",
        help="drones per eamos-node process (default auto: about one process per core)",
    )
    parser.add_argument(
        "--ground-telemetry-hz",
        type=float,
        default=None,
        metavar="HZ",
        help="the fleet's [net] ground_telemetry_hz (default: the fleet file's default)",
    )
    parser.add_argument(
        "--keep", default="", metavar="DIR", help="keep each run folder as DIR/run-N (a new DIR)"
    )
    parser.add_argument(
        "--monitor", action="store_true", help="serve the live monitor to one websocket page"
    )
    parser.add_argument("--one", type=int, help=argparse.SUPPRESS)  # the child's part
    args = parser.parse_args()
    if args.one:
        per_process = None if args.drones_per_process == "auto" else int(args.drones_per_process)
        result = one_run(
            args.one,
            args.speedup,
            args.timeout,
            per_process,
            args.keep,
            args.ground_telemetry_hz,
            args.monitor,
        )
        print(json.dumps(result))
        return
    runs = []
    for n in (int(s) for s in args.drones.split(",") if s.strip()):
        proc = subprocess.run(
            [
                sys.executable,
                __file__,
                "--one",
                str(n),
                "--speedup",
                str(args.speedup),
                "--timeout",
                str(args.timeout),
                "--drones-per-process",
                args.drones_per_process,
                "--keep",
                args.keep,
                *(
                    ["--ground-telemetry-hz", str(args.ground_telemetry_hz)]
                    if args.ground_telemetry_hz is not None
                    else []
                ),
                *(["--monitor"] if args.monitor else []),
            ],
            capture_output=True,
            text=True,
            timeout=args.timeout + 600,
        )
        lines = proc.stdout.strip().splitlines()
        if proc.returncode != 0 or not lines:
            runs.append({"drones": n, "ok": False, "error": proc.stderr.strip()[-2000:]})
            continue
        runs.append(json.loads(lines[-1]))
    print(json.dumps({"runs": runs}, indent=1))


if __name__ == "__main__":
    main()
