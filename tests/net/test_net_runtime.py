"""Whole missions over CURVE links with loss, stale telemetry, and the ground station's view.

Every participant is a real :class:`DroneRuntime` with its own ZeroMQ context
(as in its own process) on loopback TCP; loss is injected at each sender (see
``link_helpers``).  The namespace tests (``tests/netfaults``) do the same with
real processes, real packet loss and partitions.
"""

from __future__ import annotations

import dataclasses
import random
import threading
from pathlib import Path
from typing import Any

import pytest
import zmq

from eamos.actors.runtime import DroneRuntime, NetSettings
from eamos.compiler import compile_mission
from eamos.ground.station import GroundStation
from eamos.hal import make_adapter
from eamos.hal.fake import FakeAdapter
from eamos.logs import make_logger, read_log
from eamos.net import wire
from eamos.net.keys import FleetKeys, create_fleet_keys
from eamos.net.link import LinkSettings, PeerStatus
from eamos.program.uniform import GROUND_STATION

from .link_helpers import FAST, WAIT_S, Lossy, eventually, free_port

pytestmark = pytest.mark.timeout(180)

EXPERIMENT_C = Path(__file__).resolve().parents[2] / "missions" / "experiment_c.go"


class Fleet:
    """Runtimes of one mission, secure by default, each on its own context."""

    def __init__(
        self,
        tmp: Path,
        source: str,
        adapters: dict[str, Any] | None = None,
        *,
        secure: bool = True,
        settings: LinkSettings = FAST,
    ) -> None:
        self.compiled = compile_mission(source, "m.go")
        names = list(self.compiled.programs)
        self.drones = [n for n in names if n != GROUND_STATION]
        endpoints = {n: f"tcp://127.0.0.1:{free_port()}" for n in names}
        keys = create_fleet_keys(tmp / "keys", names) if secure else None
        self.station = GroundStation(self.drones, self.compiled.mission_id, give_up_s=None)
        self.adapters = dict(adapters or {})
        self.contexts: list[zmq.Context[Any]] = []
        self.runtimes: dict[str, DroneRuntime] = {}
        for name in names:
            if name == GROUND_STATION:
                adapter = make_adapter(
                    name, {"adapter": "ground", "speedup": 50}, make_logger(None)
                )
            else:
                adapter = self.adapters.setdefault(name, FakeAdapter(name, auto=True))
            ctx: zmq.Context[Any] = zmq.Context()
            self.contexts.append(ctx)
            self.runtimes[name] = DroneRuntime(
                self.compiled.programs[name],
                adapter,
                NetSettings(
                    endpoints[name],
                    endpoints,
                    keys=FleetKeys.load(keys / name, name) if keys else None,
                    link=settings,
                ),
                tmp / "logs" / name,
                context=ctx,
                ground_handler=self.station.handle if name == GROUND_STATION else None,
                extra_topics=tuple(wire.topic_telemetry(d) for d in self.drones)
                if name == GROUND_STATION
                else (),
            )
        for runtime in self.runtimes.values():
            runtime.start()
        self.station.attach(self.runtimes[GROUND_STATION])

    def start(self) -> None:
        threads = [
            threading.Thread(target=self.runtimes[d].announce_ready, args=(WAIT_S,))
            for d in self.drones
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join(WAIT_S)
        assert self.station.wait_ready(WAIT_S), self.station.not_ready()
        self.station.start()

    def close(self) -> None:
        for runtime in self.runtimes.values():
            runtime.stop()
        for ctx in self.contexts:
            ctx.term()


@pytest.fixture
def fleets(tmp_path: Path) -> Any:
    made: list[Fleet] = []

    def make(source: str, adapters: dict[str, Any] | None = None, **kw: Any) -> Fleet:
        fleet = Fleet(tmp_path / f"fleet{len(made)}", source, adapters, **kw)
        made.append(fleet)
        return fleet

    yield make
    for fleet in made:
        fleet.close()


@pytest.mark.parametrize("secure", [True, False], ids=["curve", "plain"])
def test_mission_completes_exactly_once_with_a_third_of_messages_lost(
    fleets: Any, secure: bool
) -> None:
    """Experiment C (Table 7: Drone3 15 in / 12 out) with 30 % of every reliable message lost."""
    fleet = fleets(EXPERIMENT_C.read_text(), secure=secure)
    rng = random.Random(5)
    lossy = {name: Lossy(rt.link) for name, rt in fleet.runtimes.items() if rt.link is not None}
    for loss in lossy.values():
        # Everything that must arrive (triggers, ready, start, resolved, acks ...).
        loss.drop = lambda m: (
            type(m)
            in (
                *wire.RELIABLE_TO,
                *wire.RELIABLE_BROADCAST,
                wire.Ack,
            )
            and rng.random() < 0.3
        )
    fleet.start()
    assert fleet.station.wait_resolved(WAIT_S), fleet.station.unresolved()
    fleet.station.complete()
    reports = {name: rt.report() for name, rt in fleet.runtimes.items()}
    for name, report in reports.items():
        assert report["ok"], name
        # Table 7: each trigger counted once, however often it was sent.
        assert report["triggers_sent"] == report["external_out"], name
        assert report["triggers_received"] == report["external_in"], name
        assert report["net"]["secure"] is secure
    assert reports["Drone3"]["external_in"] == 15 and reports["Drone3"]["external_out"] == 12
    assert sum(loss.dropped for loss in lossy.values()) > 10
    assert sum(r["retransmissions"] for r in reports.values()) > 0


STALE_MISSION = """
func SEQ_M() {
    PAR_Arm()
    Drone2.PauseUntil(Drone1.X() > 4)
    Drone2.Disarm()
}
func PAR_Arm() {
    Drone1.Arm()
    Drone2.Arm()
}
"""


def test_a_condition_never_decides_on_stale_telemetry(fleets: Any) -> None:
    """Drone2 waits on Drone1's X.  Drone1's last sample says X = 5, but it is stale."""
    settings = dataclasses.replace(FAST, telemetry_stale_s=0.5, telemetry_max_hz=1000.0)
    d1, d2 = FakeAdapter("Drone1", auto=True), FakeAdapter("Drone2", auto=False)
    fleet = fleets(STALE_MISSION, {"Drone1": d1, "Drone2": d2}, settings=settings)
    link1 = fleet.runtimes["Drone1"].link
    assert link1 is not None
    fleet.start()
    arm = d2.wait_started("Arm", timeout=WAIT_S)
    d1.push_telemetry(x_m=5.0)  # would satisfy the condition ...
    board = fleet.runtimes["Drone2"].board
    assert eventually(lambda: known_x(board) == 5.0)
    muted = Lossy(link1)
    muted.drop = lambda m: isinstance(m, wire.TelemetrySample)  # ... but then goes quiet
    mission_log = tmp_log(fleet, "Drone2")
    assert eventually(
        lambda: any(e["event"] == "mission.telemetry.stale" for e in read_log(mission_log))
    )
    assert known_x(board) is None  # withdrawn, not kept
    d2.finish(arm)  # now Drone2 reaches the pause, with only a stale X = 5 known
    # The pause must wait for fresh data rather than pass on the old value.
    with pytest.raises(TimeoutError):
        d2.wait_started("Disarm", timeout=1.5)
    muted.drop = lambda m: False  # telemetry flows again (the refresh repeats X = 5)
    disarm = d2.wait_started("Disarm", timeout=WAIT_S)
    d2.finish(disarm)
    assert fleet.station.wait_resolved(WAIT_S), fleet.station.unresolved()


def known_x(board: Any) -> Any:
    """Drone1's X as Drone2's telemetry board knows it."""
    return board.proxy().latest.get(timeout=WAIT_S).get("Drone1", {}).get("X")


def tmp_log(fleet: Fleet, name: str) -> Path:
    log_dir = fleet.runtimes[name].log_dir
    assert log_dir is not None
    return log_dir / "mission.log"


# -- the ground station's view of links (no network) ---------------------------------------


def test_ground_station_waits_for_a_silent_drone_then_gives_up() -> None:
    station = GroundStation(["D1", "D2"], "m", give_up_s=0.5)
    for name in ("D2", GROUND_STATION):
        station.handle(wire.Resolved("m", name))
    station.handle(PeerStatus("D1", "lost", 3.0, 1))
    assert station.lost_links() == ["D1"]
    # Lost 3 s ago with give_up_s = 0.5: given up at once, the others may complete.
    assert station.wait_resolved(5.0)
    assert station.snapshot()["D1"].state == "lost" and station.failures
    # It comes back before the end: waited for again.
    station.handle(PeerStatus("D1", "back", 4.0, 2))
    assert not station.failures and station.snapshot()["D1"].link == "back"
    assert not station.wait_resolved(0.3)
    station.handle(PeerStatus("D1", "lost", 0.0, 1))  # an older event arriving late: ignored
    assert station.snapshot()["D1"].link == "back"
    station.handle(wire.Resolved("m", "D1"))
    assert station.wait_resolved(1.0)


def test_ground_station_without_give_up_waits_for_the_partitioned_drone() -> None:
    station = GroundStation(["D1"], "m")
    station.handle(wire.Resolved("m", GROUND_STATION))
    station.handle(PeerStatus("D1", "lost", 60.0, 1))
    assert not station.wait_resolved(0.6)
    events = station.snapshot()["D1"].events
    assert events[-1]["link"] == "lost"
