"""Missions and geofences on the simulated vehicle through MAVSDK's gRPC package.

``mavsdk-grpc`` (MAVSDK-Python's gRPC wrapper, imported as ``mavsdk_grpc``,
whose wheel ships ``mavsdk_server``: the package ``mavsdk`` was called up to
its 3.x releases) uploads a mission and a geofence, downloads them again and
clears them, on both personalities: the MAVLink mission protocol as MAVSDK's
Mission and Geofence plugins speak it (for ArduPilot it adds and strips the
home item 0 itself).  Before the vehicle answered the protocol these uploads
timed out.  Skips visibly when the package is missing (the ``test`` extra
installs it; CI treats skips as failures).
"""

from __future__ import annotations

import asyncio
import math
import socket
import subprocess
from collections.abc import Awaitable, Callable
from importlib import resources
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip(
    "mavsdk_grpc",
    reason="mavsdk-grpc (MAVSDK-Python's gRPC package with mavsdk_server) is not installed: "
    "pip install 'eamos[test]' or pip install mavsdk-grpc",
)

from mavsdk_grpc import System
from mavsdk_grpc.geofence import Circle, FenceType, GeofenceData, Point, Polygon
from mavsdk_grpc.mission import MissionError, MissionItem, MissionPlan

from eamos.hal.kinematics import GeoFrame
from eamos.hal.sitl.missions import FENCE, FENCE_POLYGON_INCLUSION
from eamos.hal.sitl.vehicle import SimVehicle, VehicleOptions

from .mavlink_helpers import connections

pytestmark = pytest.mark.timeout(240)
#: Bound of one whole MAVSDK session (wall seconds).
SESSION_S = 150.0
HOME = (46.6103, 14.2640, 450.0)


def free_tcp_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def waypoint(lat: float, lon: float, height: float) -> MissionItem:
    nan = float("nan")
    return MissionItem(
        lat,
        lon,
        height,
        nan,  # speed: none (no DO_CHANGE_SPEED item)
        True,
        nan,
        nan,
        MissionItem.CameraAction.NONE,
        nan,
        nan,
        nan,
        nan,
        nan,
        MissionItem.VehicleAction.NONE,
    )


def mavsdk_server() -> str:
    """The ``mavsdk_server`` binary the wheel ships."""
    binary = resources.files("mavsdk_grpc.bin") / "mavsdk_server"
    assert binary.is_file(), f"{binary}: the mavsdk-grpc wheel ships no mavsdk_server here"
    return str(binary)


Body = Callable[[Any, SimVehicle], Awaitable[None]]


def session(autopilot: str, tmp_path: Path, body: Body) -> None:
    """A vehicle of ``autopilot``, our own ``mavsdk_server`` connected to it and a MAVSDK
    System talking to that server; run ``body(system, vehicle)``."""
    vehicle_conn, client_conn = connections(autopilot)
    port = client_conn.rsplit(":", 1)[1]
    vehicle = SimVehicle(
        VehicleOptions(
            autopilot,  # type: ignore[arg-type]
            vehicle_conn,
            speedup=5.0,
            prearm_delay_s=1.0,
            home=HOME,
            log=tmp_path / "vehicle.log",
        )
    )
    url = f"udpin://127.0.0.1:{port}" if autopilot == "px4" else f"tcpout://127.0.0.1:{port}"
    grpc_port = free_tcp_port()

    async def main() -> None:
        # Our own server process (the System class would start one it never stops).
        drone = System(mavsdk_server_address="127.0.0.1", port=grpc_port)
        await drone.connect()
        async for state in drone.core.connection_state():
            if state.is_connected:
                break
        await body(drone, vehicle)

    vehicle.start()  # ArduPilot style: its TCP server listens before mavsdk_server dials
    with (tmp_path / "mavsdk_server.log").open("wb") as out:
        server = subprocess.Popen(
            [mavsdk_server(), "-p", str(grpc_port), url], stdout=out, stderr=subprocess.STDOUT
        )
        try:
            asyncio.run(asyncio.wait_for(main(), SESSION_S))
        finally:
            server.terminate()
            try:
                server.wait(10)
            except subprocess.TimeoutExpired:
                server.kill()
                server.wait(10)
            vehicle.stop()


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_mavsdk_grpc_uploads_downloads_and_clears_a_mission(autopilot: str, tmp_path: Path):
    frame = GeoFrame(*HOME)
    plan = [frame.to_lla(x, y, 0.0)[:2] for x, y in ((0.0, 0.0), (10.0, 0.0), (10.0, 10.0))]
    got: dict[str, Any] = {}

    async def body(drone: Any, vehicle: SimVehicle) -> None:
        items = [waypoint(lat, lon, 5.0) for lat, lon in plan]
        await drone.mission.upload_mission(MissionPlan(items))
        got["stored"] = vehicle.mission_items()
        got["raw"] = await drone.mission_raw.download_mission()
        try:
            got["down"] = (await drone.mission.download_mission()).mission_items
        except MissionError as exc:
            got["down"] = exc
        await drone.mission.clear_mission()
        got["after_clear"] = await drone.mission_raw.download_mission()

    session(autopilot, tmp_path, body)
    assert len(got["stored"]) == 3
    raw = got["raw"]
    assert [(i.x, i.y) for i in raw[1:]] == [
        (round(lat * 1e7), round(lon * 1e7)) for lat, lon in plan[1:]
    ]
    if autopilot == "px4":
        assert [i.frame for i in raw] == [6, 6, 6]  # as uploaded
        down = got["down"]
        assert [(round(i.latitude_deg, 6), round(i.longitude_deg, 6)) for i in down] == [
            (round(lat, 6), round(lon, 6)) for lat, lon in plan
        ]
        assert all(i.relative_altitude_m == pytest.approx(5.0) for i in down)
    else:
        # ArduCopter reports its home as item 0 (frame GLOBAL, altitude AMSL) and the
        # others without _INT frames; MAVSDK's Mission plugin cannot read that back
        # ("Waypoint frame not supported"), exactly as against ArduCopter SITL.
        assert (raw[0].frame, raw[0].x, raw[0].z) == (0, round(HOME[0] * 1e7), HOME[2])
        assert [i.frame for i in raw[1:]] == [3, 3]
        assert isinstance(got["down"], MissionError)
        assert str(got["down"]).startswith("UNSUPPORTED")
    assert got["after_clear"] == []


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_mavsdk_grpc_uploads_downloads_and_clears_a_geofence(autopilot: str, tmp_path: Path):
    frame = GeoFrame(*HOME)
    corners = [frame.to_lla(x, y, 0.0)[:2] for x, y in ((-20, -20), (20, -20), (20, 20), (-20, 20))]
    centre = frame.to_lla(50.0, 0.0, 0.0)[:2]
    got: dict[str, Any] = {}

    async def body(drone: Any, vehicle: SimVehicle) -> None:
        polygon = Polygon([Point(lat, lon) for lat, lon in corners], FenceType.INCLUSION)
        circle = Circle(Point(*centre), 5.0, FenceType.EXCLUSION)
        await drone.geofence.upload_geofence(GeofenceData([polygon], [circle]))
        got["fence"] = vehicle.geofence
        got["items"] = vehicle.mission_items(FENCE)
        got["down"] = await drone.geofence.download_geofence()
        await drone.geofence.clear_geofence()
        got["cleared"] = vehicle.geofence

    session(autopilot, tmp_path, body)
    fence = got["fence"]
    assert len(fence.inclusion) == 1 and len(fence.circles_out) == 1
    # The polygon is where MAVSDK put it, in the vehicle's local frame (metres).
    for (x, y), (ex, ey) in zip(
        fence.inclusion[0], ((-20, -20), (20, -20), (20, 20), (-20, 20)), strict=True
    ):
        assert math.hypot(x - ex, y - ey) < 0.05
    assert fence.horizontal_breach((0.0, 0.0)) is None
    assert fence.horizontal_breach((30.0, 0.0)) == "polygon"
    assert [i.command for i in got["items"]][:4] == [FENCE_POLYGON_INCLUSION] * 4
    down = got["down"]
    assert len(down.polygons) == 1 and len(down.polygons[0].points) == 4
    assert down.polygons[0].points[0].latitude_deg == pytest.approx(corners[0][0], abs=1e-7)
    assert len(down.circles) == 1 and down.circles[0].radius == pytest.approx(5.0)
    assert got["cleared"].empty
