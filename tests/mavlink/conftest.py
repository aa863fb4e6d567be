"""Fixtures for the MAVLink tests: simulated vehicles and adapters that are always closed."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, Literal

import pytest

from eamos.hal.mavlink.adapter import MavlinkAdapter, MavlinkSettings
from eamos.hal.sitl.vehicle import SimVehicle, VehicleOptions
from eamos.logs import close_logger, make_logger

from .mavlink_helpers import Flight, RawClient, connections


@pytest.fixture
def make_vehicle(tmp_path: Path) -> Iterator[Callable[..., tuple[SimVehicle, str]]]:
    """``make_vehicle("px4", **options)``: a started vehicle and the client's connection string.

    PX4 vehicles send UDP to a free port (the client listens with ``udpin``),
    ArduPilot vehicles serve TCP (the client dials ``tcp:``), as the SITLs do.
    Its log goes to ``tmp_path / "vehicle-<n>.log"``.
    """
    made: list[SimVehicle] = []

    def factory(autopilot: Literal["px4", "ardupilot"], **options: Any) -> tuple[SimVehicle, str]:
        vehicle_conn, client_conn = connections(autopilot)
        options.setdefault("speedup", 10.0)
        options.setdefault("prearm_delay_s", 1.0)
        options.setdefault("log", tmp_path / f"vehicle-{len(made)}.log")
        vehicle = SimVehicle(VehicleOptions(autopilot, vehicle_conn, **options))
        vehicle.start()
        made.append(vehicle)
        return vehicle, client_conn

    yield factory
    for vehicle in made:
        vehicle.stop()


@pytest.fixture
def make_adapter(tmp_path: Path) -> Iterator[Callable[..., MavlinkAdapter]]:
    """``make_adapter(connection, **settings)``: an unstarted adapter logging to tmp_path."""
    made: list[tuple[MavlinkAdapter, Any]] = []

    def factory(connection: str, drone: str = "D1", **settings: Any) -> MavlinkAdapter:
        settings.setdefault("connect_timeout_s", 10.0)
        settings.setdefault("armable_timeout_s", 20.0)
        settings.setdefault("action_timeout_s", 30.0)
        # Wall seconds, not scaled by the speed-up.  The vehicle runs in this process at
        # speed-up 10 (ten times a real vehicle's messages): on a loaded machine, flights saw
        # longer gaps than the product's 3 s between the HEARTBEATs read and failed "heartbeat
        # lost".  Tests of link loss set their own.
        settings.setdefault("heartbeat_timeout_s", 10.0)
        log = make_logger(tmp_path / f"{drone}-adapter.log", drone=drone)
        adapter = MavlinkAdapter(
            drone, MavlinkSettings.from_mapping({"connection": connection, **settings}), log
        )
        made.append((adapter, log))
        return adapter

    yield factory
    for adapter, log in made:
        adapter.close()
        close_logger(log)


@pytest.fixture
def flight(make_vehicle: Any, make_adapter: Any) -> Callable[..., Flight]:
    """``flight("px4", vehicle={...}, **adapter_settings)``: vehicle + started adapter + sink."""

    def factory(autopilot: str, vehicle: dict[str, Any] | None = None, **settings: Any) -> Flight:
        sim, conn = make_vehicle(autopilot, **(vehicle or {}))
        adapter = make_adapter(conn, **settings)
        return Flight.start(sim, adapter)

    return factory


@pytest.fixture
def raw_client() -> Iterator[Callable[[str], RawClient]]:
    """``raw_client(connection)``: a pymavlink client of our own, closed afterwards."""
    made: list[RawClient] = []

    def factory(connection: str) -> RawClient:
        client = RawClient(connection)
        made.append(client)
        return client

    yield factory
    for client in made:
        client.close()
