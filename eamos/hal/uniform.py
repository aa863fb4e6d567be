"""The uniform API: every action and property a mission may use, with units.

This is the single source of truth shared by the compiler (which checks a
mission against a drone's type) and the hardware layer (whose adapters
implement the actions).  Frame: X north, Y east, Z up, metres, relative to
the drone's home (where it was when its adapter started).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ActionSpec:
    """One uniform action: its name, argument names with units, and meaning."""

    name: str
    params: tuple[str, ...]
    doc: str
    # Payload actions have no physical motion; adapters acknowledge them.
    payload: bool = False


@dataclass(frozen=True)
class PropertySpec:
    """One uniform property, read in conditions as ``Drone.Name()``."""

    name: str
    unit: str
    doc: str
    type: str = "number"  # "number" or "bool"


ACTIONS: dict[str, ActionSpec] = {
    a.name: a
    for a in (
        ActionSpec("Arm", (), "Arm the motors; waits until the vehicle is armable."),
        ActionSpec("Disarm", (), "Disarm the motors; only on the ground."),
        ActionSpec("Takeoff", ("height_m",), "Climb vertically to height_m above home."),
        ActionSpec("Land", (), "Descend at the current X/Y until landed."),
        ActionSpec("FlyByX", ("distance_m",), "Fly distance_m along X (north) from here."),
        ActionSpec("FlyByY", ("distance_m",), "Fly distance_m along Y (east) from here."),
        ActionSpec("FlyByZ", ("distance_m",), "Climb (or descend if negative) distance_m."),
        ActionSpec(
            "FlyToXYZ", ("x_m", "y_m", "z_m"), "Fly to the local point (x_m, y_m, z_m) from home."
        ),
        ActionSpec(
            "FlyToLLA",
            ("lat_deg", "lon_deg", "alt_m"),
            "Fly to a WGS84 latitude/longitude (degrees) at alt_m metres above home.",
        ),
        ActionSpec(
            "PauseFor", ("duration_s",), "Hold position (or stay on the ground) duration_s."
        ),
        ActionSpec("TurnOn", (), "Power on the payload/companion systems.", payload=True),
        ActionSpec("PreFlightCheck", (), "Run the pre-flight checks.", payload=True),
        ActionSpec("Calibrate", (), "Calibrate the sensors.", payload=True),
        ActionSpec("TurnOnCamera", (), "Power on the camera.", payload=True),
        ActionSpec("AdjustCamera", (), "Point the camera to its default attitude.", payload=True),
    )
}

PROPERTIES: dict[str, PropertySpec] = {
    p.name: p
    for p in (
        PropertySpec("X", "m", "Position north of home."),
        PropertySpec("Y", "m", "Position east of home."),
        PropertySpec("Z", "m", "Height above home (up is positive)."),
        PropertySpec("Lat", "deg", "WGS84 latitude."),
        PropertySpec("Lon", "deg", "WGS84 longitude."),
        PropertySpec("Alt", "m", "Altitude above home, from the global position."),
        PropertySpec("Battery", "%", "Remaining battery, 0 to 100."),
        PropertySpec("Armed", "", "True while the motors are armed.", type="bool"),
    )
}

#: The actions that move the vehicle (one at a time; cancelling one holds position).
MOTION_ACTIONS = frozenset(
    {"Takeoff", "Land", "FlyByX", "FlyByY", "FlyByZ", "FlyToXYZ", "FlyToLLA"}
)

#: Telemetry field carrying each property (see :class:`eamos.hal.api.Telemetry`).
PROPERTY_FIELDS: dict[str, str] = {
    "X": "x_m",
    "Y": "y_m",
    "Z": "z_m",
    "Lat": "lat_deg",
    "Lon": "lon_deg",
    "Alt": "alt_m",
    "Battery": "battery_pct",
    "Armed": "armed",
}

_FLIGHT = frozenset(
    {
        "Arm",
        "Disarm",
        "Takeoff",
        "Land",
        "FlyByX",
        "FlyByY",
        "FlyByZ",
        "FlyToXYZ",
        "FlyToLLA",
        "PauseFor",
    }
)
_ALL_ACTIONS = frozenset(ACTIONS)
_ALL_PROPERTIES = frozenset(PROPERTIES)


@dataclass(frozen=True)
class DroneType:
    """What a kind of drone can do: the actions and properties it offers."""

    name: str
    actions: frozenset[str]
    properties: frozenset[str]
    doc: str = ""


#: The ground station: it only waits (and hosts conditions); it never flies.
GROUND_STATION = "GCS"
GROUND_TYPE = DroneType(
    "GroundStation", frozenset({"PauseFor"}), frozenset(), "The ground station."
)

DEFAULT_DRONE_TYPE = "Quadcopter"

DRONE_TYPES: dict[str, DroneType] = {
    t.name: t
    for t in (
        DroneType(
            "Quadcopter",
            _ALL_ACTIONS,
            _ALL_PROPERTIES,
            "A multicopter with every uniform action and property (the default type).",
        ),
        # The three types of the paper's Listing 1.  Their payloads differ: only
        # DroneType2 carries the camera, DroneType3 has no calibration routine.
        DroneType(
            "DroneType1",
            _FLIGHT | {"TurnOn", "PreFlightCheck", "Calibrate"},
            _ALL_PROPERTIES,
            "Listing 1's Drone1: flight actions, power, pre-flight check, calibration.",
        ),
        DroneType(
            "DroneType2",
            _FLIGHT | {"TurnOn", "PreFlightCheck", "Calibrate", "TurnOnCamera", "AdjustCamera"},
            _ALL_PROPERTIES,
            "Listing 1's Drone2: as DroneType1 plus a camera.",
        ),
        DroneType(
            "DroneType3",
            _FLIGHT | {"TurnOn", "PreFlightCheck"},
            _ALL_PROPERTIES,
            "Listing 1's Drone3: flight actions, power and pre-flight check.",
        ),
    )
}
