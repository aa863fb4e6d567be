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

#: Periodic jobs (setpoints, telemetry samples) never run more often than this (wall Hz).
MAX_WALL_HZ = 100.0
#: The longest duration a setting may give (a day): a wait of 1e308 s cannot even be
#: asked of the system (docs/configuration.md, "Ranges").
DAY_S = 86_400.0


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
    #: Completion: within ``tolerance_m`` of the target (scaled down for short moves,
    #: completion.py) and slower than ``settle_speed_mps`` on average over ``settle_s``;
    #: None: the autopilot's own (autopilots.Autopilot, measured on the SITLs).
    tolerance_m: float | None = None
    settle_speed_mps: float | None = None
    settle_s: float | None = None
    #: Rates in vehicle time (scaled by ``speedup``, at most MAX_WALL_HZ on the wall clock).
    setpoint_hz: float = 20.0
    telemetry_hz: float = 10.0
    #: The drone type's speeds, set on the vehicle (params.py) and restored at close.
    horizontal_speed_mps: float = 2.0
    climb_speed_mps: float = 1.0
    descent_speed_mps: float = 0.7
    set_speeds: bool = True
    #: Re-arm before a take-off when the vehicle disarmed itself since our Arm.
    rearm: bool = True
    #: A flying vehicle is landed by close() (False: it is left, with an error logged).
    land_on_close: bool = True
    #: The vehicle's clock rate (a SITL at speed-up K): timeouts and waits shrink by K.
    speedup: float = 1.0
    #: How long a cancel may take to bring the vehicle to rest (vehicle seconds).
    brake_timeout_s: float = 30.0
    #: MAVLink 2 signing: the fleet's key file (signing.py); provision it with SETUP_SIGNING.
    signing_key: str | None = None
    signing_setup: bool = False
    #: "required": with a key, a vehicle that does not sign is refused; "off": this
    #: vehicle's link is not signed even when the fleet has a key (PX4 main cannot sign).
    signing: Literal["required", "off"] = "required"
    #: How long a vehicle may take to sign after SETUP_SIGNING (signing_setup), vehicle s.
    signing_timeout_s: float = 10.0
    #: Where this drone's home is in the fleet frame (north, east m): eamos run writes the
    #: fleet's (FleetConfig.homes), as the check, the monitor and the report place it.
    home_m: tuple[float, float] | None = None
    #: The fleet's home_lla for this drone (lat, lon[, alt]): compared with the vehicle's own.
    home_lla: tuple[float, ...] | None = None
    #: The fleet's [safety] geofence (fleet frame) and ceiling (m above home), put on the
    #: vehicle before its first arming (geofence.py) unless ``fence = false``.
    geofence_m: tuple[tuple[float, float], ...] = ()
    max_altitude_m: float | None = None
    fence: bool = True

    def scaled(self, seconds: float) -> float:
        """``seconds`` of vehicle time in wall seconds (``speedup``)."""
        return seconds / self.speedup

    def wall_period(self, hz: float) -> float:
        """The wall-clock period of a job that runs ``hz`` times per vehicle second
        (a SITL at speed-up 10 sends ten times as many samples per wall second), but
        never more often than :data:`MAX_WALL_HZ`."""
        return 1.0 / min(hz * self.speedup, MAX_WALL_HZ)

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

        def optional(key: str) -> float | None:
            return num(key, gt=0, le=100) if key in mapping else None

        def text(key: str) -> str | None:
            value = mapping.get(key)
            if value is not None and not (isinstance(value, str) and value):
                raise field_error(f"{prefix}.{key}", f"expected a file path, got {value!r}")
            return value

        def flag(key: str) -> bool:
            value = mapping.get(key, getattr(cls, key))
            if not isinstance(value, bool):
                raise field_error(f"{prefix}.{key}", f"expected true or false, got {value!r}")
            return value

        def choice(key: str, options: tuple[str, ...]) -> Any:
            value = mapping.get(key, getattr(cls, key))
            if value not in options:
                raise field_error(
                    f"{prefix}.{key}", f"expected one of {', '.join(options)}; got {value!r}"
                )
            return value

        def points(key: str, count: int | None) -> tuple[tuple[float, ...], ...]:
            """``[[a, b], ...]`` (``count`` None) or one ``[a, b(, c)]`` as a 1-tuple."""
            value: Any = mapping.get(key)
            rows: Any = value if count is None else [value]
            lengths = (2,) if count is None else (2, count)

            def number_row(row: Any) -> bool:
                return (
                    isinstance(row, list | tuple)
                    and len(row) in lengths
                    and all(isinstance(c, int | float) and not isinstance(c, bool) for c in row)
                )

            if not isinstance(rows, list | tuple) or not all(number_row(r) for r in rows):
                shape = "[[north_m, east_m], ...]" if count is None else "[a, b] or [a, b, c]"
                raise field_error(f"{prefix}.{key}", f"expected {shape}, got {value!r}")
            return tuple(tuple(float(c) for c in row) for row in rows)

        home_m = points("home_m", 2)[0] if "home_m" in mapping else None
        home_lla = points("home_lla", 3)[0] if "home_lla" in mapping else None
        fence = points("geofence_m", None) if "geofence_m" in mapping else ()
        if 0 < len(fence) < 3:
            raise field_error(f"{prefix}.geofence_m", "a polygon needs at least 3 points")
        return cls(
            connection=connection,
            system_id=integer("system_id", 1, 255, None),
            component_id=integer("component_id", 0, 255, 1) or 0,
            source_system=integer("source_system", 1, 255, 245) or 245,
            source_component=integer("source_component", 0, 255, 191) or 0,
            autopilot=choice("autopilot", ("auto", "px4", "ardupilot")),
            takeoff_mode=choice("takeoff_mode", ("offboard", "auto")),
            connect_timeout_s=num("connect_timeout_s", gt=0, le=DAY_S),
            armable_timeout_s=num("armable_timeout_s", gt=0, le=DAY_S),
            command_timeout_s=num("command_timeout_s", gt=0, le=DAY_S),
            command_retries=integer("command_retries", 1, 100, 3) or 3,
            heartbeat_timeout_s=num("heartbeat_timeout_s", gt=0, le=DAY_S),
            action_timeout_s=num("action_timeout_s", gt=0, le=DAY_S),
            tolerance_m=optional("tolerance_m"),
            settle_speed_mps=optional("settle_speed_mps"),
            settle_s=num("settle_s", ge=0, le=60) if "settle_s" in mapping else None,
            setpoint_hz=num("setpoint_hz", gt=2, le=100),
            telemetry_hz=num("telemetry_hz", ge=10, le=100),
            horizontal_speed_mps=num("horizontal_speed_mps", gt=0, le=50),
            climb_speed_mps=num("climb_speed_mps", gt=0, le=20),
            descent_speed_mps=num("descent_speed_mps", gt=0, le=20),
            set_speeds=flag("set_speeds"),
            rearm=flag("rearm"),
            land_on_close=flag("land_on_close"),
            speedup=num("speedup", gt=0, le=1000),
            brake_timeout_s=num("brake_timeout_s", gt=0, le=DAY_S),
            signing_key=text("signing_key"),
            signing_setup=flag("signing_setup"),
            signing=choice("signing", ("required", "off")),
            signing_timeout_s=num("signing_timeout_s", gt=0, le=DAY_S),
            home_m=None if home_m is None else (home_m[0], home_m[1]),
            home_lla=home_lla,
            geofence_m=tuple((p[0], p[1]) for p in fence),
            max_altitude_m=optional("max_altitude_m"),
            fence=flag("fence"),
        )
