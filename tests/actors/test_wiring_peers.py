"""connected_peers: each drone connects to the peers it works with, the ground station to all."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from eamos.actors.wiring import connected_peers, destinations, watched_peers
from eamos.compiler import compile_file, compile_mission

REPO = Path(__file__).resolve().parents[2]


def relay_mission(n: int) -> str:
    spec = importlib.util.spec_from_file_location(
        "bench_scale", REPO / "scripts" / "bench_scale.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_scale"] = module
    spec.loader.exec_module(module)
    return str(module.relay_mission(n))


def test_a_relay_drone_connects_to_its_neighbours_and_the_ground_station() -> None:
    programs = dict(compile_mission(relay_mission(6), "relay.go").programs)
    peers = connected_peers(programs)
    assert peers["GCS"] == ["D1", "D2", "D3", "D4", "D5", "D6"]
    # Its neighbours in both relays, and D6: its last takeoff starts every square,
    # and every square ends in D6's landing.
    assert peers["D3"] == ["D2", "D4", "D6", "GCS"]
    assert peers["D1"] == ["D2", "D6", "GCS"]
    assert peers["D6"] == ["D1", "D2", "D3", "D4", "D5", "GCS"]
    # Fewer links than all-to-all (7 * 6).
    assert sum(len(p) for p in peers.values()) == 6 + 6 + 3 + 4 + 4 + 4 + 3


@pytest.mark.parametrize("path", sorted((REPO / "missions").glob("*.go")), ids=lambda p: p.stem)
def test_every_sender_and_receiver_of_a_mission_are_connected_both_ways(path: Path) -> None:
    programs = dict(compile_file(path).programs)
    peers = connected_peers(programs)
    for name, program in programs.items():
        watched = watched_peers(program, whole_fleet=False)
        assert set(watched or programs) - {name} <= set(peers[name])
        for dest in destinations(program):
            # The sender hears the receiver's acks; the receiver hears the sender.
            assert dest in peers[name] and name in peers[dest], (name, dest)
        for source in program.telemetry_from:
            assert source in peers[name]


def test_an_interrupted_drone_connects_to_the_drone_that_interrupts_it() -> None:
    for path in sorted((REPO / "missions").glob("*.go")):
        programs = dict(compile_file(path).programs)
        for name, program in programs.items():
            for node in program.native_nodes():
                for target in node.interrupt_drones:
                    if target != name:
                        assert name in connected_peers(programs)[target]
