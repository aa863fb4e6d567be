"""Settings of the MAVLink adapter (a drone's ``hal`` section with ``adapter = "mavlink"``).

Kept apart from the adapter so that the vehicle, the flight logic and the fleet
checks can read them without importing the adapter.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any, Literal

from eamos.hal.mavlink.autopilots import TakeoffMode
from eamos.hal.mavlink.link import check_connection
from eamos.hal.settings import COMMON_KEYS, check_keys, field_error, number, require_mapping


@dataclass(frozen=True)
class MavlinkSettings:
    """Settings of the MAVLink adapter; build with :meth:`from_mapping`."""

    connection: str
    system_id: int | None = None
    component_id: int = 1
    source_system: int = 245
    source_component: int = 191
    autopilot: Literal["auto", "px4", "ardupilot"] = "auto"
    takeoff_mode: TakeoffMode = "offboard"
    connect_timeout_s: float = 30.0
    armable_timeout_s: float = 60.0
    command_timeout_s: float = 1.5
    command_retries: int = 3
    heartbeat_timeout_s: float = 3.0
    action_timeout_s: float = 120.0
    tolerance_m: float = 0.3
    settle_speed_mps: float = 0.3
    setpoint_hz: float = 20.0
    telemetry_hz: float = 10.0

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], prefix: str = "hal") -> MavlinkSettings:
        """Validate a drone's ``hal`` settings; errors read ``"hal.<field>: <problem>"``."""
        mapping = require_mapping(mapping, prefix)
        check_keys(mapping, {f.name for f in fields(cls)} | COMMON_KEYS, prefix)
        if "connection" not in mapping:
            raise field_error(
                f"{prefix}.connection",
                'missing; e.g. "udpin:0.0.0.0:14540" (PX4 SITL), "tcp:127.0.0.1:5760" '
                '(ArduPilot SITL) or "/dev/ttyACM0,921600" (serial)',
            )
        connection = mapping["connection"]
        if not isinstance(connection, str):
            raise field_error(f"{prefix}.connection", f"expected a string, got {connection!r}")
        problem = check_connection(connection)
        if problem:
            raise field_error(f"{prefix}.connection", f"{problem}; got {connection!r}")

        def num(key: str, **bounds: float) -> float:
            return number(mapping, key, getattr(cls, key), prefix, **bounds)

        def integer(key: str, low: int, high: int, default: int | None) -> int | None:
            if key not in mapping:
                return default
            value = mapping[key]
            if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
                raise field_error(
                    f"{prefix}.{key}", f"expected an integer from {low} to {high}, got {value!r}"
                )
            return value

        def choice(key: str, options: tuple[str, ...]) -> Any:
            value = mapping.get(key, getattr(cls, key))
            if value not in options:
                raise field_error(
                    f"{prefix}.{key}", f"expected one of {', '.join(options)}; got {value!r}"
                )
            return value

        return cls(
            connection=connection,
            system_id=integer("system_id", 1, 255, None),
            component_id=integer("component_id", 0, 255, 1) or 0,
            source_system=integer("source_system", 1, 255, 245) or 245,
            source_component=integer("source_component", 0, 255, 191) or 0,
            autopilot=choice("autopilot", ("auto", "px4", "ardupilot")),
            takeoff_mode=choice("takeoff_mode", ("offboard", "auto")),
            connect_timeout_s=num("connect_timeout_s", gt=0),
            armable_timeout_s=num("armable_timeout_s", gt=0),
            command_timeout_s=num("command_timeout_s", gt=0),
            command_retries=integer("command_retries", 1, 100, 3) or 3,
            heartbeat_timeout_s=num("heartbeat_timeout_s", gt=0),
            action_timeout_s=num("action_timeout_s", gt=0),
            tolerance_m=num("tolerance_m", gt=0),
            settle_speed_mps=num("settle_speed_mps", gt=0),
            setpoint_hz=num("setpoint_hz", gt=2, le=100),
            telemetry_hz=num("telemetry_hz", gt=0, le=100),
        )
