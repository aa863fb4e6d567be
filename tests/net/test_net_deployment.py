"""Issue 28, item 13: a node starts only on the Start of its own deployment.

Every participant is a real :class:`DroneRuntime` on loopback TCP with CURVE
keys (as in ``test_net_runtime``); the drones are built as ``eamos-node``
builds them, with a start gate for deployment ``B``.  The ground station of
another roll-out (deployment ``A``: same mission, same keys, same endpoints)
starts and fires its initial node: the drones refuse its Start, act on
nothing (its triggers are held), refuse its Complete, and say so once.  The
Start of their own deployment then starts them, with the held triggers.
"""

from __future__ import annotations

import functools
import threading
from pathlib import Path
from typing import Any

import pytest
import zmq

from eamos.actors.runtime import DroneRuntime, NetSettings, StartGateSettings
from eamos.compiler import compile_mission
from eamos.ground.station import GroundStation
from eamos.hal import make_adapter
from eamos.hal.fake import FakeAdapter
from eamos.logs import make_logger, read_log
from eamos.net import wire
from eamos.net.keys import FleetKeys, create_fleet_keys
from eamos.program.uniform import GROUND_STATION

from .link_helpers import FAST, WAIT_S, eventually, free_port

pytestmark = pytest.mark.timeout(180)

TWO = """
func SEQ_M() {
    PAR_Arm()
    Drone1.Takeoff(1)
}
func PAR_Arm() {
    Drone1.Arm()
    Drone2.Arm()
}
"""


def events(runtime: DroneRuntime, name: str) -> list[dict[str, Any]]:
    assert runtime.log_dir is not None
    return [e for e in read_log(runtime.log_dir / "mission.log") if e["event"] == name]


def started_logged(runtime: DroneRuntime) -> bool:
    return bool(events(runtime, "mission.start"))


def test_a_node_takes_only_its_own_deployments_start(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    compiled = compile_mission(TWO, "m.go")
    names = list(compiled.programs)
    drones = [n for n in names if n != GROUND_STATION]
    endpoints = {n: f"tcp://127.0.0.1:{free_port()}" for n in names}
    keys = create_fleet_keys(tmp_path / "keys", names)
    running: dict[str, int] = {d: 0 for d in drones}
    station = GroundStation(drones, compiled.mission_id, deployment="A")
    adapters = {d: FakeAdapter(d, auto=True) for d in drones}
    contexts: list[zmq.Context[Any]] = []
    runtimes: dict[str, DroneRuntime] = {}

    def mark(drone: str) -> Any:
        return lambda: running.__setitem__(drone, running[drone] + 1)

    try:
        for name in names:
            ctx: zmq.Context[Any] = zmq.Context()
            contexts.append(ctx)
            gcs = name == GROUND_STATION
            runtimes[name] = DroneRuntime(
                compiled.programs[name],
                make_adapter(name, {"adapter": "ground", "speedup": 50}, make_logger(None))
                if gcs
                else adapters[name],
                NetSettings(
                    endpoints[name], endpoints, keys=FleetKeys.load(keys / name, name), link=FAST
                ),
                tmp_path / "logs" / name,
                context=ctx,
                ground_handler=station.handle if gcs else None,
                extra_topics=tuple(wire.topic_telemetry(d) for d in drones) if gcs else (),
                start_gate=None if gcs else StartGateSettings("B", mark(name)),
            )
            runtimes[name].start()
        station.attach(runtimes[GROUND_STATION])
        threads = [
            threading.Thread(target=runtimes[d].announce_ready, args=(WAIT_S,)) for d in drones
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join(WAIT_S)
        assert station.wait_ready(WAIT_S), station.not_ready()
        # Another roll-out's ground station: its Start, its initial node's triggers.
        station.start()
        assert eventually(lambda: all(events(runtimes[d], "mission.start.refused") for d in drones))
        station.complete()  # ... and its Complete
        assert eventually(
            lambda: all(events(runtimes[d], "mission.complete.refused") for d in drones)
        )
        for d in drones:
            assert adapters[d].calls_of("run") == [], d  # nothing moved
            assert not runtimes[d].completed.is_set() and not runtimes[d].aborted.is_set()
            assert running[d] == 0 and not events(runtimes[d], "mission.start")
            refused = events(runtimes[d], "mission.start.refused")[0]
            assert (refused["deployment"], refused["own"]) == ("A", "B")
        err = capfd.readouterr().err
        for d in drones:
            line = f"eamos-node {d}: refused a Start of deployment A: this node was rolled out"
            assert err.count(line) == 1, err  # said once, not per retransmission
        # Its own deployment's Start: the held triggers run now, the mission completes.
        runtimes[GROUND_STATION].send(
            wire.Start(compiled.mission_id, GROUND_STATION, deployment="B")
        )
        assert station.wait_resolved(WAIT_S), station.unresolved()
        assert [c.action for c in adapters["Drone1"].calls_of("run")] == ["Arm", "Takeoff"]
        assert [c.action for c in adapters["Drone2"].calls_of("run")] == ["Arm"]
        for d in drones:
            log_has_start = functools.partial(started_logged, runtimes[d])
            assert eventually(log_has_start)
            (started,) = events(runtimes[d], "mission.start")
            assert started["deployment"] == "B" and started["released"] >= 1
            assert running[d] == 1  # recorded once, before the first trigger reached a node
    finally:
        for runtime in runtimes.values():
            runtime.stop()
        for ctx in contexts:
            ctx.term()
