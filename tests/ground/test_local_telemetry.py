"""``eamos run``'s local fleet, pure parts: telemetry rates by reader, groups, exit reasons."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

from eamos.compiler import compile_file
from eamos.config import FleetConfig, NodeConfig
from eamos.config.fleet import DEFAULT_GROUND_TELEMETRY_HZ, PEER_TELEMETRY_HZ
from eamos.ground.local import (
    exit_reason,
    process_groups,
    telemetry_links,
    telemetry_readers,
    write_node_configs,
)
from eamos.net.keys import create_fleet_keys

REPO = Path(__file__).resolve().parents[2]


def test_a_drone_read_by_a_peer_keeps_the_peers_rate_the_others_the_ground_rate(
    tmp_path: Path,
) -> None:
    # relay_wait: Drone1's conditions read Drone2's position; nobody reads Drone1's.
    programs = compile_file(REPO / "missions" / "relay_wait.go").programs
    assert telemetry_readers(programs) == {"Drone2"}
    drones = ["Drone1", "Drone2"]
    links = telemetry_links(programs, drones, FleetConfig.empty())
    assert links["Drone1"].telemetry_max_hz == DEFAULT_GROUND_TELEMETRY_HZ
    assert links["Drone2"].telemetry_max_hz == PEER_TELEMETRY_HZ
    # The rates reach the node configs the drones load.
    names = ["GCS", *drones]
    endpoints = {n: f"tcp://127.0.0.1:{6000 + i}" for i, n in enumerate(names)}
    create_fleet_keys(tmp_path / "keys", names)
    hals = {d: {"adapter": "sim"} for d in drones}
    configs = write_node_configs(tmp_path, endpoints, hals, 60.0, links=links)
    for drone in drones:
        loaded = NodeConfig.load(configs[drone])
        assert loaded.link.telemetry_max_hz == links[drone].telemetry_max_hz, drone


def test_a_condition_of_the_ground_station_counts_as_a_reader() -> None:
    programs = compile_file(REPO / "missions" / "relay_wait.go").programs
    only_ground = {n: p for n, p in programs.items() if n != "Drone1"}
    assert telemetry_readers(only_ground) == set()
    ground = programs["GCS"]
    read = dataclasses.replace(ground, telemetry_from=("Drone1",))
    assert telemetry_readers({**only_ground, "GCS": read}) == {"Drone1"}


def test_a_dead_shared_process_is_named_for_each_of_its_drones() -> None:
    # The fault tests match the one-drone wording; a shared process names its drones.
    assert exit_reason(-9, ("Drone1",)) == "process exited with code -9"
    assert exit_reason(-9, ("D3", "D4"), "eamos-node D3: boom") == (
        "process exited with code -9 (shared by D3, D4): eamos-node D3: boom"
    )


def test_automatic_groups_give_a_drone_with_its_own_vehicle_a_process_of_its_own() -> None:
    names = [f"D{i}" for i in range(1, 9)]
    groups = process_groups(names, None, alone=["D2", "D7"])
    assert ["D2"] in groups and ["D7"] in groups
    assert sorted(d for g in groups for d in g) == sorted(names)  # each drone once
    shared = [g for g in groups if g not in (["D2"], ["D7"])]
    size = -(-6 // (os.cpu_count() or 1))  # about one process per core for the six others
    assert len(shared) == -(-6 // size) and max(len(g) for g in shared) == size
    assert [g[0] for g in groups] == sorted((g[0] for g in groups), key=names.index)
    # An explicit number is the operator's: it applies to every drone.
    assert process_groups(names, 4, alone=["D2"]) == [names[0:4], names[4:8]]
