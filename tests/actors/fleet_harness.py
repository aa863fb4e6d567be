"""Runs a whole mission in one process: one DroneRuntime per participant, real ZeroMQ.

Endpoints are ``inproc://`` on one shared context, so many fleets can run in one
test session without port clashes; the sockets, bridges and actors are the
real ones.  Drones get :class:`FakeAdapter` unless the test passes adapters.
"""

from __future__ import annotations

import itertools
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zmq

from eamos.actors.runtime import DroneRuntime, NetSettings
from eamos.compiler import compile_mission
from eamos.ground.station import GroundStation
from eamos.hal import make_adapter
from eamos.hal.fake import FakeAdapter
from eamos.logs import make_logger
from eamos.net import wire
from eamos.program.uniform import GROUND_STATION

WAIT_S = 60.0
_fleet_ids = itertools.count()


@dataclass
class Fleet:
    compiled: Any
    station: GroundStation
    runtimes: dict[str, DroneRuntime]
    adapters: dict[str, Any]
    context: zmq.Context[Any]
    reports: dict[str, dict[str, Any]] = field(default_factory=dict)

    def start(self) -> None:
        threads = [
            threading.Thread(target=rt.announce_ready, args=(WAIT_S,))
            for name, rt in self.runtimes.items()
            if name != GROUND_STATION
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join(WAIT_S)
        assert self.station.wait_ready(WAIT_S), f"not ready: {self.station.not_ready()}"
        self.station.start()

    def wait_resolved(self, timeout_s: float = WAIT_S) -> bool:
        return self.station.wait_resolved(timeout_s)

    def finish(self) -> dict[str, dict[str, Any]]:
        # In parallel: each report may wait (bounded) for its vehicle's final sample.
        with ThreadPoolExecutor(len(self.runtimes)) as pool:
            reports = pool.map(DroneRuntime.report, self.runtimes.values())
            self.reports = dict(zip(self.runtimes, reports, strict=True))
        return self.reports

    def close(self) -> None:
        for rt in self.runtimes.values():
            rt.stop()
        self.context.term()

    def actions(self, drone: str) -> list[tuple[str, str]]:
        """(action label, result) in start order."""
        return [
            (f"{a['action']}({', '.join(f'{x:g}' for x in a['args'])})", a["result"])
            for a in self.reports[drone]["actions"]
        ]


def make_fleet(
    source: str,
    adapters: dict[str, Any] | None = None,
    *,
    auto: bool = True,
    log_dir: Path | None = None,
) -> Fleet:
    """Compile ``source`` and build every participant's runtime (not started yet).

    With ``log_dir``, each participant logs to ``log_dir / name`` (else nowhere).
    """
    compiled = compile_mission(source, "test.go")
    names = list(compiled.programs)
    fid = next(_fleet_ids)
    endpoints = {n: f"inproc://fleet{fid}-{n}" for n in names}
    context: zmq.Context[Any] = zmq.Context()
    drones = [n for n in names if n != GROUND_STATION]
    station = GroundStation(drones, compiled.mission_id)
    adapters = dict(adapters or {})
    runtimes: dict[str, DroneRuntime] = {}
    for name in names:
        if name == GROUND_STATION:
            adapter = make_adapter(name, {"adapter": "ground", "speedup": 50}, make_logger(None))
        else:
            adapter = adapters.setdefault(name, FakeAdapter(name, auto=auto))
        runtimes[name] = DroneRuntime(
            compiled.programs[name],
            adapter,
            NetSettings(endpoints[name], endpoints),
            None if log_dir is None else log_dir / name,
            context=context,
            ground_handler=station.handle if name == GROUND_STATION else None,
            extra_topics=tuple(wire.topic_telemetry(d) for d in drones)
            if name == GROUND_STATION
            else (),
        )
    for rt in runtimes.values():
        rt.start()
    station.attach(runtimes[GROUND_STATION])
    return Fleet(compiled, station, runtimes, adapters, context)
