"""The simulated vehicle flown by a client we did not write: MAVSDK (the native ``mavsdk`` 4.x).

MAVSDK is strict about PX4-like behaviour (heartbeats, SYS_STATUS health and
pre-arm bits, HOME_POSITION, parameters for the take-off altitude,
AUTO.TAKEOFF, DO_REPOSITION, OFFBOARD with its own 20 Hz setpoint stream,
EXTENDED_SYS_STATE), so a full flight through it is evidence that the
vehicle is faithful.  Skips visibly when ``mavsdk`` is not installed (the
``test`` extra installs it; CI treats skips as failures).
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip(
    "mavsdk.asyncio",
    reason="mavsdk (MAVSDK-Python 4.x, native) is not installed: "
    "pip install 'eamos[test]' or pip install mavsdk",
)

from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.offboard import OffboardAsync, PositionNedYaw
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync

from eamos.hal.sitl.vehicle import SimVehicle, VehicleOptions

from .mavlink_helpers import RawClient, connections

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(180)]
#: Bound of one whole MAVSDK flight (wall seconds).
FLIGHT_S = 120.0
M_PER_DEG_LAT = 111_320.0


async def first(stream: Any, predicate: Callable[[Any], bool]) -> Any:
    """The first item of a MAVSDK subscription that matches (bounded by the flight timeout)."""
    async for item in stream:
        if predicate(item):
            return item
    raise AssertionError("stream ended")


def settled(pv: Any) -> bool:
    """A PositionVelocityNed of a vehicle (nearly) at rest."""
    v = pv.velocity
    return bool(abs(v.north_m_s) + abs(v.east_m_s) + abs(v.down_m_s) < 0.1)


def fly(vehicle: SimVehicle, url: str, body: Callable[[Any], Awaitable[None]]) -> float:
    """Connect MAVSDK to ``url``, start the vehicle, run ``body(system)``; the wall duration."""

    async def main() -> None:
        config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
        async with Mavsdk(config) as mavsdk:
            await mavsdk.add_any_connection(url)
            if not url.startswith("tcpout"):
                vehicle.start()  # PX4 style: the vehicle sends to the listening client
            system = await mavsdk.first_autopilot(timeout_s=30.0)
            assert system is not None, "MAVSDK found no autopilot"
            await body(system)

    t0 = time.monotonic()
    station: RawClient | None = None
    if url.startswith("tcpout"):
        vehicle.start()  # ArduPilot style: the vehicle must listen before MAVSDK dials
        # ArduCopter streams nothing unasked (not even SYS_STATUS, which MAVSDK's health
        # needs) and MAVSDK asks only for what it subscribes to: a ground station on the
        # same link asks for all streams, as MAVProxy or QGroundControl would.
        host, port = vehicle.address
        station = RawClient(f"tcp:{host}:{port}")
        station.heartbeat()
        station.mav.request_data_stream_send(vehicle.options.sysid, 1, 0, 4, 1)
    try:
        asyncio.run(asyncio.wait_for(main(), FLIGHT_S))
    finally:
        if station is not None:
            station.close()
        vehicle.stop()
    return time.monotonic() - t0


def test_mavsdk_flies_the_px4_personality(tmp_path: Path):
    vehicle_conn, client_conn = connections("px4")
    port = client_conn.rsplit(":", 1)[1]
    vehicle = SimVehicle(
        VehicleOptions(
            "px4", vehicle_conn, speedup=5.0, prearm_delay_s=2.0, log=tmp_path / "vehicle.log"
        )
    )
    seen: dict[str, Any] = {}

    async def body(system: Any) -> None:
        telemetry, action, offboard = (
            TelemetryAsync(system),
            ActionAsync(system),
            OffboardAsync(system),
        )
        health = await first(
            telemetry.subscribe_health(),
            lambda h: h.is_armable and h.is_global_position_ok and h.is_home_position_ok,
        )
        seen["health"] = health
        await action.set_takeoff_altitude(3.0)  # PARAM_SET MIS_TAKEOFF_ALT
        assert await action.get_takeoff_altitude() == pytest.approx(3.0)
        await action.arm()
        await first(telemetry.subscribe_armed(), bool)
        await action.takeoff()  # NAV_TAKEOFF -> AUTO.TAKEOFF, then HOLD
        await first(telemetry.subscribe_position(), lambda p: p.relative_altitude_m > 2.8)
        await first(telemetry.subscribe_in_air(), bool)
        home = await telemetry.home()
        target_lat = home.latitude_deg + 5.0 / M_PER_DEG_LAT
        # DO_REPOSITION (after MAVSDK puts the vehicle in HOLD).
        await action.goto_location(
            target_lat, home.longitude_deg, home.absolute_altitude_m + 3.0, 0.0
        )
        await first(
            telemetry.subscribe_position(),
            lambda p: abs(p.latitude_deg - target_lat) * M_PER_DEG_LAT < 0.3,
        )
        here = await first(telemetry.subscribe_position_velocity_ned(), settled)
        # OFFBOARD: MAVSDK streams the setpoint itself once one is set.
        north, east, down = here.position.north_m, here.position.east_m, here.position.down_m
        await offboard.set_position_ned(PositionNedYaw(north, east + 2.0, down, 0.0))
        await offboard.start()
        seen["mode"] = await first(
            telemetry.subscribe_flight_mode(), lambda m: m.name == "OFFBOARD"
        )
        await first(
            telemetry.subscribe_position_velocity_ned(),
            lambda pv: abs(pv.position.east_m - (east + 2.0)) < 0.3 and settled(pv),
        )
        await offboard.stop()
        await action.land()
        await first(telemetry.subscribe_landed_state(), lambda s: s.name == "ON_GROUND")
        await first(telemetry.subscribe_armed(), lambda armed: not armed)

    duration = fly(vehicle, f"udpin://127.0.0.1:{port}", body)
    assert seen["health"].is_local_position_ok
    x, y, z = vehicle.position
    assert (x, y, z) == pytest.approx((5.0, 2.0, 0.0), abs=0.4)
    assert not vehicle.armed
    log = (tmp_path / "vehicle.log").read_text()
    for command in ('"command": 22,', '"command": 192,', '"command": 21,', '"command": 400,'):
        assert command in log  # takeoff, reposition, land, arm went through MAVLink commands
    print(f"MAVSDK PX4 flight: {duration:.1f} s wall at speed-up 5")


def test_mavsdk_flies_the_ardupilot_personality(tmp_path: Path):
    vehicle_conn, client_conn = connections("ardupilot")
    port = client_conn.rsplit(":", 1)[1]
    vehicle = SimVehicle(
        VehicleOptions(
            "ardupilot", vehicle_conn, speedup=5.0, prearm_delay_s=2.0, log=tmp_path / "vehicle.log"
        )
    )

    async def body(system: Any) -> None:
        telemetry, action = TelemetryAsync(system), ActionAsync(system)
        await first(telemetry.subscribe_health(), lambda h: h.is_armable)
        # ArduPilot streams little until asked (as its SITL does).
        await telemetry.set_rate_position(5.0)
        await action.set_takeoff_altitude(2.0)  # kept by MAVSDK for ArduPilot
        await action.arm()
        await action.takeoff()  # GUIDED, then NAV_TAKEOFF with param7 = 2 m
        await first(telemetry.subscribe_position(), lambda p: p.relative_altitude_m > 1.8)
        await action.land()
        await first(telemetry.subscribe_armed(), lambda armed: not armed)

    duration = fly(vehicle, f"tcpout://127.0.0.1:{port}", body)
    assert vehicle.position[2] == pytest.approx(0.0, abs=0.05)
    assert vehicle.mode == "LAND" and not vehicle.armed
    print(f"MAVSDK ArduPilot flight: {duration:.1f} s wall at speed-up 5")
