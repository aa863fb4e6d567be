#!/usr/bin/env python3
"""Benchmark of applying an amendment to a flying fleet (issue 31); prints JSON.

A fleet of N drones, each flying a lane (Arm, Takeoff, out, back, Land), runs in one
process: one :class:`~eamos.actors.runtime.DroneRuntime` per participant on real
ZeroMQ sockets (``inproc://``), each drone's vehicle the adapter seam's fake held in
its ``Arm`` so that every later node is still to come.  The ground station's
:class:`~eamos.ground.amend.AmendmentApplier` then applies an amendment that splits the
way back of half the drones in two: prepare to each, every answer, commit to each,
every answer.  Reported per fleet size: the wall and CPU seconds of the whole apply (the
median of ``--repeat`` fleets), and of the check that came before it in ``eamos amend``
(``check_amendment`` from a snapshot of the same moment), for comparison.

Usage: ``python scripts/bench_amend.py --json [--drones 4,20,100] [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import zmq

from eamos.actors.runtime import DroneRuntime, NetSettings
from eamos.actors.wiring import connected_peers
from eamos.check import check_amendment
from eamos.compiler import compile_mission
from eamos.compiler.amendment import rekey
from eamos.config import FleetConfig
from eamos.ground.amend import JUDGED_AGAINST, AmendmentApplier, judged_against
from eamos.ground.station import GroundStation
from eamos.hal import make_adapter
from eamos.hal.fake import FakeAdapter
from eamos.logs import make_logger
from eamos.net import wire
from eamos.program.uniform import GROUND_STATION

WAIT_S = 120.0


def lanes(drones: int, split: int = 0) -> str:
    """N drones flying a lane each, at once; the first ``split`` fly their way back in two."""
    names = [f"Drone{i}" for i in range(1, drones + 1)]
    out = ["package Lanes", ""]
    out += [f"var {n} Quadcopter" for n in names]
    out += ["", "func PAR_Lanes() {", *(f"\tSEQ_{n}()" for n in names), "}"]
    for i, n in enumerate(names):
        back = [f"\t{n}.FlyByX(-6)", f"\t{n}.FlyByX(-6)"] if i < split else [f"\t{n}.FlyByX(-12)"]
        out += ["", f"func SEQ_{n}() {{", f"\t{n}.Arm()", f"\t{n}.Takeoff(2)"]
        out += [f"\t{n}.FlyByX(12)", *back, f"\t{n}.Land()", "}"]
    return "\n".join(out) + "\n"


def one_fleet(drones: int) -> dict[str, float]:
    """Apply the amendment once to a fresh fleet held in its Arms: seconds it took."""
    compiled = compile_mission(lanes(drones), "lanes.go")
    amended = rekey(compiled.programs, compile_mission(lanes(drones, drones // 2), "lanes.go"))
    names = list(compiled.programs)
    endpoints = {n: f"inproc://amend-{drones}-{n}" for n in names}
    context: zmq.Context[Any] = zmq.Context()
    # A whole fleet in one process: more sockets than one context's default 1023.
    context.set(zmq.MAX_SOCKETS, 16 * (drones + 1) + 64)
    fleet = [n for n in names if n != GROUND_STATION]
    station = GroundStation(fleet, compiled.mission_id)
    # Each drone links to the peers it works with, as a run's configs say (not to all).
    peers_of = connected_peers(dict(compiled.programs))
    fakes = {n: FakeAdapter(n, auto=False) for n in fleet}
    runtimes = {}
    for name in names:
        adapter = (
            make_adapter(name, {"adapter": "ground"}, make_logger(None))
            if name == GROUND_STATION
            else fakes[name]
        )
        runtimes[name] = DroneRuntime(
            compiled.programs[name],
            adapter,
            NetSettings(endpoints[name], {p: endpoints[p] for p in [name, *peers_of[name]]}),
            None,
            context=context,
            ground_handler=station.handle if name == GROUND_STATION else None,
        )
    try:
        for runtime in runtimes.values():
            runtime.start()
        station.attach(runtimes[GROUND_STATION])
        # Each drone announces itself once the peers it sends to listen: all at once.
        with ThreadPoolExecutor(len(fleet)) as pool:
            assert all(pool.map(lambda n: runtimes[n].announce_ready(WAIT_S), fleet))
        assert station.wait_ready(WAIT_S), station.not_ready()
        station.start()
        for fake in fakes.values():
            fake.wait_started("Arm", WAIT_S)
        with tempfile.TemporaryDirectory() as tmp:
            run_dir = Path(tmp)
            staged = run_dir / "amendments" / "1"
            (run_dir / "programs").mkdir(parents=True)
            (staged / "programs").mkdir(parents=True)
            for name, program in compiled.programs.items():
                program.save(run_dir / "programs" / f"{name}.program.json")
                amended.programs[name].save(staged / "programs" / f"{name}.program.json")
            doc = {"accepted": True, JUDGED_AGAINST: judged_against(compiled.programs)}
            (staged / "amendment.json").write_text(json.dumps(doc))
            applier = AmendmentApplier(station, run_dir)
            w0, c0 = time.perf_counter(), time.process_time()
            why = applier.apply("1", "bench")
            wall, cpu = time.perf_counter() - w0, time.process_time() - c0
            assert why == "", why
            applied = json.loads((staged / "applied.json").read_text())["drones"]
        snapshot = snapshot_doc(station)
        c0 = time.process_time()
        w0 = time.perf_counter()
        report = check_amendment(
            compiled.programs,
            compile_mission(lanes(drones, drones // 2), "lanes.go"),
            snapshot,
            FleetConfig.empty(),
        )
        check_wall, check_cpu = time.perf_counter() - w0, time.process_time() - c0
        assert report.accepted, report.lines("lanes.go")
    finally:
        for runtime in runtimes.values():
            runtime.stop()
        context.destroy(linger=0)  # whatever a failed start left open
    return {
        "apply_wall_s": wall,
        "apply_cpu_s": cpu,
        "drones_switched": len(applied),
        "check_wall_s": check_wall,
        "check_cpu_s": check_cpu,
    }


def snapshot_doc(station: GroundStation) -> dict[str, Any]:
    """The mission's snapshot now, as the ground station writes it (``snapshot.json``)."""
    from eamos.ground.snapshot import mission_snapshot

    doc: dict[str, Any] = mission_snapshot(
        station.snapshot(), "bench", station.mission_id, False, None, True
    )
    return doc


def main() -> None:
    _, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))  # a fleet's sockets in one process
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--drones", default="4,20,100", help="fleet sizes, comma-separated")
    parser.add_argument("--repeat", type=int, default=3, help="fleets per size (median)")
    parser.add_argument("--json", action="store_true", help="print JSON (the only output)")
    args = parser.parse_args()
    results = []
    for drones in (int(n) for n in args.drones.split(",")):
        runs = [one_fleet(drones) for _ in range(args.repeat)]
        med = {k: round(statistics.median(r[k] for r in runs), 4) for k in runs[0]}
        results.append({"drones": drones, **med, "repeat": args.repeat})
    print(json.dumps({"amend": results, "wire_version": wire.WIRE_VERSION}, indent=1))


if __name__ == "__main__":
    main()
