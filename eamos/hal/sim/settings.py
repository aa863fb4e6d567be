"""Settings of one simulated quadcopter (:class:`SimSettings`) and its scripted pilot's path.

Shared by the pure simulator core (:mod:`eamos.hal.sim.core`) and its wall-clock
pacer (:mod:`eamos.hal.sim.adapter`); see :mod:`eamos.hal.sim.adapter` for what each setting does.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from types import MappingProxyType
from typing import Any

from eamos.hal.kinematics import GeoFrame, Limits
from eamos.hal.settings import (
    COMMON_KEYS,
    DISARM_AFTER_LANDING_S,
    as_number,
    check_keys,
    did_you_mean,
    field_error,
    number,
    require_mapping,
    string_list,
)
from eamos.program.plugins import PLUGIN_DEADLINE_S
from eamos.program.uniform import ACTIONS, DRONE_TYPES

#: The longest deadline a plugin's "sim" implementation may be given (an hour).
PLUGIN_DEADLINE_MAX_S = 3600.0
#: Every setting is bounded (docs/configuration.md, "Ranges"): a value far out (a speed of
#: 1e-9 m/s, an acceleration of 1e308) leaves the drone armed on the ground or spins its
#: simulator.  The simulator's step (its SIM_DT_S) caps the telemetry rate.
SIM_STEP_S = 0.02
MAX_SPEEDUP = 1000.0
MIN_SPEED_MPS = 0.05
MAX_DRAIN = 6000.0  # percent per minute: an empty battery in a hundredth of a minute
#: The largest ``disturbance_drain_factor`` (a battery draining twenty times its model).
MAX_DRAIN_FACTOR = 20.0
#: Scripted pilot: coordinates within this many metres of home, waypoints at most.
MAX_PILOT_M = 10_000.0
MAX_WAYPOINTS = 10_000
#: A drone's home in the fleet frame within this many metres of the origin.
MAX_HOME_M = 1_000_000.0


@dataclass(frozen=True)
class BatteryModel:
    """How a simulated drone's battery drains (percent per minute), and its charge at start.

    On the ground it drains ``drain_idle_pct_per_min``; in the air
    ``drain_airborne_pct_per_min`` (hovering) plus ``drain_per_mps_pct_per_min``
    per m/s of speed plus ``drain_climb_per_mps_pct_per_min`` per m/s of climb
    (:meth:`eamos.hal.kinematics.Quadcopter.drain_pct_per_min`).  Each field is a
    ``[hal]`` setting of the simulated adapter of the same name (docs/safety.md).
    """

    battery_pct: float = 100.0
    drain_airborne_pct_per_min: float = 4.0
    drain_per_mps_pct_per_min: float = 0.5
    drain_climb_per_mps_pct_per_min: float = 2.0
    drain_idle_pct_per_min: float = 0.1

    def settings(self) -> dict[str, float]:
        """The fields that differ from the simulator's default model, as ``[hal]`` settings.

        Only those are written into a drone's merged ``[hal]`` table, so a drone
        whose type has the default model gets exactly the table it had before
        types had models.
        """
        default = BatteryModel()
        return {
            f.name: getattr(self, f.name)
            for f in fields(self)
            if getattr(self, f.name) != getattr(default, f.name)
        }


#: The built-in battery model of each built-in drone type (docs/safety.md, "Per drone type").
#: The paper gives no battery figures for its DroneType1..3, so they fly the
#: Quadcopter's model; a fleet file's ``[types.NAME.hal]`` changes any of them.
BATTERY_MODELS: Mapping[str, BatteryModel] = MappingProxyType(
    {name: BatteryModel() for name in DRONE_TYPES}
)


@dataclass(frozen=True)
class Waypoint:
    """One point of the scripted pilot's path (metres from home, hold in sim seconds)."""

    x_m: float
    y_m: float
    z_m: float
    hold_s: float = 0.0


@dataclass(frozen=True)
class SimSettings:
    """Settings of one simulated vehicle; build with :meth:`from_mapping`."""

    speedup: float = 1.0
    horizontal_speed_mps: float = 2.0
    climb_speed_mps: float = 1.0
    descent_speed_mps: float = 0.7
    accel_mps2: float = 2.0
    tolerance_m: float = 0.1
    settle_speed_mps: float = 0.2
    arm_delay_s: float = 2.0
    # Told to take off, the vehicle leaves the ground this long later (motors spooling up,
    # an autopilot's take-off ramp); a landing is reported this long after touchdown (an
    # autopilot's land detector).  0 for a simulated drone; the pre-flight check's model
    # of a MAVLink drone sets the measured ones (eamos.config.types.MAVLINK_MODELS).
    liftoff_delay_s: float = 0.0
    land_detect_s: float = 0.0
    # A disturbance the pre-flight check cannot know (wind against it, a weak motor): the
    # vehicle flies horizontally at this fraction of its speeds.  The check models the drone
    # without it (eamos.check.explore.sim_settings); the live look-ahead measures it.
    disturbance_speed_factor: float = 1.0
    # Another it cannot know (a cold or aged battery): in the air the battery drains this
    # many times faster than its model says.  Checked without, measured by the look-ahead.
    disturbance_drain_factor: float = 1.0
    # Disarm by itself this long after a touchdown ending a flight, as PX4 (COM_DISARM_LAND)
    # and ArduCopter do; 0: never (eamos.hal.sim.landing).
    disarm_after_landing_s: float = DISARM_AFTER_LANDING_S
    telemetry_hz: float = 10.0
    home_lat_deg: float = 46.6103
    home_lon_deg: float = 14.2640
    home_alt_m: float = 0.0
    # The battery model: BatteryModel's fields (one default, kept in one place).
    battery_pct: float = BatteryModel.battery_pct
    drain_airborne_pct_per_min: float = BatteryModel.drain_airborne_pct_per_min
    drain_per_mps_pct_per_min: float = BatteryModel.drain_per_mps_pct_per_min
    drain_climb_per_mps_pct_per_min: float = BatteryModel.drain_climb_per_mps_pct_per_min
    drain_idle_pct_per_min: float = BatteryModel.drain_idle_pct_per_min
    action_timeout_s: float = 120.0
    # Wall-clock seconds a plugin action's "sim" implementation may compute its outcome
    # (docs/plugins.md): not simulated time, so not scaled by speedup.
    plugin_deadline_s: float = PLUGIN_DEADLINE_S
    reject_actions: tuple[str, ...] = ()
    pilot: tuple[Waypoint, ...] = ()
    # Where this drone stands in the fleet frame: metres (north, east) from the
    # fleet's origin (home_lat_deg, home_lon_deg).  Its X/Y/Z stay relative to
    # its own home, as on a real autopilot; its latitude and longitude show
    # where it really is, so drones of one fleet do not all start on one spot.
    home_m: tuple[float, float] = (0.0, 0.0)

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], prefix: str = "hal") -> SimSettings:
        """Validate ``mapping`` (the drone's ``hal`` settings) into settings.

        Raises :class:`AdapterError` ``"hal.<field>: <problem>"`` for a bad value
        or an unknown key (with a "did you mean" suggestion).
        """
        mapping = require_mapping(mapping, prefix)
        names = [f.name for f in fields(cls)]
        check_keys(mapping, set(names) | COMMON_KEYS, prefix)

        def num(key: str, **bounds: float) -> float:
            return number(mapping, key, getattr(cls, key), prefix, **bounds)

        reject: tuple[str, ...] = ()
        if "reject_actions" in mapping:
            path = f"{prefix}.reject_actions"
            reject = tuple(string_list(mapping["reject_actions"], path))
            for i, name in enumerate(reject):
                if name not in ACTIONS:
                    raise field_error(
                        f"{path}[{i}]", f"unknown action {name!r}{did_you_mean(name, ACTIONS)}"
                    )
        pilot = _pilot_path(mapping["pilot"], f"{prefix}.pilot") if "pilot" in mapping else ()
        home_m = (
            _home_m(mapping["home_m"], f"{prefix}.home_m") if "home_m" in mapping else (0.0, 0.0)
        )
        return cls(
            speedup=num("speedup", gt=0, le=MAX_SPEEDUP),
            horizontal_speed_mps=num("horizontal_speed_mps", ge=MIN_SPEED_MPS, le=50),
            climb_speed_mps=num("climb_speed_mps", ge=MIN_SPEED_MPS, le=20),
            descent_speed_mps=num("descent_speed_mps", ge=MIN_SPEED_MPS, le=20),
            accel_mps2=num("accel_mps2", ge=0.1, le=50),
            tolerance_m=num("tolerance_m", ge=0.01, le=10),
            settle_speed_mps=num("settle_speed_mps", gt=0, le=5),
            arm_delay_s=num("arm_delay_s", ge=0, le=600),
            liftoff_delay_s=num("liftoff_delay_s", ge=0, le=600),
            land_detect_s=num("land_detect_s", ge=0, le=600),
            disturbance_speed_factor=num("disturbance_speed_factor", ge=0.05, le=1),
            disturbance_drain_factor=num("disturbance_drain_factor", ge=1, le=MAX_DRAIN_FACTOR),
            disarm_after_landing_s=num("disarm_after_landing_s", ge=0, le=3600),
            telemetry_hz=num("telemetry_hz", ge=0.1, le=1 / SIM_STEP_S),
            home_lat_deg=num("home_lat_deg", ge=-90, le=90),
            home_lon_deg=num("home_lon_deg", ge=-180, le=180),
            home_alt_m=num("home_alt_m", ge=-1000, le=10_000),
            battery_pct=num("battery_pct", ge=0, le=100),
            drain_airborne_pct_per_min=num("drain_airborne_pct_per_min", ge=0, le=MAX_DRAIN),
            drain_per_mps_pct_per_min=num("drain_per_mps_pct_per_min", ge=0, le=MAX_DRAIN),
            drain_climb_per_mps_pct_per_min=num(
                "drain_climb_per_mps_pct_per_min", ge=0, le=MAX_DRAIN
            ),
            drain_idle_pct_per_min=num("drain_idle_pct_per_min", ge=0, le=MAX_DRAIN),
            action_timeout_s=num("action_timeout_s", gt=0, le=86_400),
            plugin_deadline_s=num("plugin_deadline_s", gt=0, le=PLUGIN_DEADLINE_MAX_S),
            reject_actions=reject,
            pilot=pilot,
            home_m=home_m,
        )

    @property
    def limits(self) -> Limits:
        """The kinematic limits these settings describe (disturbances included)."""
        drain = self.disturbance_drain_factor
        return Limits(
            horizontal_speed_mps=self.horizontal_speed_mps * self.disturbance_speed_factor,
            climb_speed_mps=self.climb_speed_mps,
            descent_speed_mps=self.descent_speed_mps,
            accel_mps2=self.accel_mps2,
            drain_airborne_pct_per_min=self.drain_airborne_pct_per_min * drain,
            drain_per_mps_pct_per_min=self.drain_per_mps_pct_per_min * drain,
            drain_climb_per_mps_pct_per_min=self.drain_climb_per_mps_pct_per_min * drain,
            drain_idle_pct_per_min=self.drain_idle_pct_per_min,
        )

    @property
    def frame(self) -> GeoFrame:
        """The local/global frame around this vehicle's own home (``home_m`` from the origin)."""
        origin = GeoFrame(self.home_lat_deg, self.home_lon_deg, self.home_alt_m)
        if self.home_m == (0.0, 0.0):
            return origin
        lat, lon, _ = origin.to_lla(self.home_m[0], self.home_m[1], 0.0)
        return GeoFrame(lat, lon, self.home_alt_m)


def _home_m(value: Any, path: str) -> tuple[float, float]:
    if isinstance(value, str) or not isinstance(value, list | tuple) or len(value) != 2:
        raise field_error(path, f"expected [north_m, east_m], got {value!r}")
    return (
        as_number(value[0], f"{path}[0]", ge=-MAX_HOME_M, le=MAX_HOME_M),
        as_number(value[1], f"{path}[1]", ge=-MAX_HOME_M, le=MAX_HOME_M),
    )


def _pilot_path(value: Any, path: str) -> tuple[Waypoint, ...]:
    if isinstance(value, str) or not isinstance(value, list | tuple):
        raise field_error(path, f"expected a list of waypoints, got {value!r}")
    if len(value) > MAX_WAYPOINTS:
        raise field_error(path, f"at most {MAX_WAYPOINTS} waypoints, got {len(value)}")
    points = []
    for i, raw in enumerate(value):
        where = f"{path}[{i}]"
        item = require_mapping(raw, where)
        check_keys(item, ("x_m", "y_m", "z_m", "hold_s"), where)
        for key in ("x_m", "y_m", "z_m"):
            if key not in item:
                raise field_error(f"{where}.{key}", "missing")
        points.append(
            Waypoint(
                x_m=as_number(item["x_m"], f"{where}.x_m", ge=-MAX_PILOT_M, le=MAX_PILOT_M),
                y_m=as_number(item["y_m"], f"{where}.y_m", ge=-MAX_PILOT_M, le=MAX_PILOT_M),
                # The pilot flies; landing is the mission's (or abort's) business.
                z_m=as_number(item["z_m"], f"{where}.z_m", gt=0, le=MAX_PILOT_M),
                hold_s=as_number(item.get("hold_s", 0.0), f"{where}.hold_s", ge=0, le=86_400),
            )
        )
    return tuple(points)


__all__ = ["BATTERY_MODELS", "BatteryModel", "SimSettings", "Waypoint"]
