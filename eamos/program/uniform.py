"""The uniform API: every action and property a mission may use, with units.

This is the single source of truth shared by the compiler (which checks a
mission against a drone's type) and the hardware layer (whose adapters
implement the actions).  Frame: X north, Y east, Z up, metres, relative to
the drone's home (where it was when its adapter started).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields


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
        ActionSpec("Takeoff", ("height_m",), "Climb vertically to `height_m` metres above home."),
        ActionSpec("Land", (), "Descend at the current X/Y until landed."),
        ActionSpec(
            "FlyByX",
            ("distance_m",),
            "Fly `distance_m` metres along X (north; negative: south) from here.",
        ),
        ActionSpec(
            "FlyByY",
            ("distance_m",),
            "Fly `distance_m` metres along Y (east; negative: west) from here.",
        ),
        ActionSpec("FlyByZ", ("distance_m",), "Climb `distance_m` metres (descend if negative)."),
        ActionSpec(
            "FlyToXYZ",
            ("x_m", "y_m", "z_m"),
            "Fly to the local point (`x_m`, `y_m`, `z_m`) from home.",
        ),
        ActionSpec(
            "FlyToLLA",
            ("lat_deg", "lon_deg", "alt_m"),
            "Fly to a WGS84 latitude/longitude (degrees) at `alt_m` metres above home.",
        ),
        ActionSpec(
            "PauseFor",
            ("duration_s",),
            "Hold position (or stay on the ground) for `duration_s` seconds.",
        ),
        ActionSpec(
            "ReturnHome",
            (),
            "Fly back above home at the current height, land there and disarm (like RTL).",
        ),
        ActionSpec(
            "Hold",
            ("duration_s",),
            "Hover where the drone is, in the autopilot's hold mode, for `duration_s` seconds.",
        ),
        ActionSpec(
            "Yaw",
            ("heading_deg",),
            "Turn on the spot to the compass heading `heading_deg` (0 north, 90 east).",
        ),
        ActionSpec(
            "SetSpeed",
            ("speed_m_s",),
            "Fly later horizontal moves at `speed_m_s` metres per second.",
        ),
        ActionSpec(
            "Orbit",
            ("radius_m", "turns"),
            "Circle clockwise `turns` times around the point `radius_m` metres ahead "
            "(along the heading), at the current height, facing it; whole turns end where "
            "it started.",
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
    {
        "Takeoff",
        "Land",
        "FlyByX",
        "FlyByY",
        "FlyByZ",
        "FlyToXYZ",
        "FlyToLLA",
        "ReturnHome",
        "Yaw",
        "Orbit",
    }
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


# --- Commands: an action decoded once -------------------------------------------------------
#
# The mission and the wire carry actions as a name and a tuple of numbers.  The uniform API
# decodes them once, here, into a typed command; adapters dispatch on the command's class and
# never compare action names again.


class CommandError(ValueError):
    """An action name or argument list that no adapter can run."""


@dataclass(frozen=True)
class Command:
    """One uniform action with its arguments, checked against :data:`ACTIONS`."""

    @property
    def action(self) -> str:
        """The uniform action's name (``"FlyByX"``, ``"Arm"``, ...)."""
        return type(self).__name__

    @property
    def args(self) -> tuple[float, ...]:
        """The arguments in the order of the action's parameters: the number fields, in order.

        Subclasses whose fields are not the parameters themselves (``FlyBy``'s
        axis, a payload's or plugin's name) say their own.
        """
        return tuple(getattr(self, f.name) for f in fields(self))

    @property
    def moves(self) -> bool:
        """True for the actions that move the vehicle (one at a time per drone)."""
        return self.action in MOTION_ACTIONS


@dataclass(frozen=True)
class Arm(Command):
    """Arm the motors."""


@dataclass(frozen=True)
class Disarm(Command):
    """Disarm the motors (on the ground only)."""


@dataclass(frozen=True)
class Takeoff(Command):
    """Climb vertically to ``height_m`` above home."""

    height_m: float


@dataclass(frozen=True)
class Land(Command):
    """Descend at the current X/Y until landed."""


@dataclass(frozen=True)
class FlyBy(Command):
    """A relative move: ``FlyByX``/``FlyByY``/``FlyByZ`` (one axis non-zero)."""

    axis: str  # "X", "Y" or "Z"
    distance_m: float

    @property
    def action(self) -> str:
        return f"FlyBy{self.axis}"

    @property
    def args(self) -> tuple[float, ...]:
        return (self.distance_m,)

    def offset_m(self) -> tuple[float, float, float]:
        """The move as a (dx, dy, dz) vector in the mission frame."""
        return (
            self.distance_m if self.axis == "X" else 0.0,
            self.distance_m if self.axis == "Y" else 0.0,
            self.distance_m if self.axis == "Z" else 0.0,
        )


@dataclass(frozen=True)
class FlyToXYZ(Command):
    """Fly to a local point from home."""

    x_m: float
    y_m: float
    z_m: float


@dataclass(frozen=True)
class FlyToLLA(Command):
    """Fly to a WGS84 point at ``alt_m`` above home."""

    lat_deg: float
    lon_deg: float
    alt_m: float


@dataclass(frozen=True)
class PauseFor(Command):
    """Hold position (or stay on the ground) for ``duration_s``."""

    duration_s: float


@dataclass(frozen=True)
class ReturnHome(Command):
    """Fly back above home at the current height, land and disarm (RTL)."""


@dataclass(frozen=True)
class Hold(Command):
    """Hover in the autopilot's hold mode for ``duration_s``."""

    duration_s: float


@dataclass(frozen=True)
class Yaw(Command):
    """Turn on the spot to the compass heading ``heading_deg`` (0 north, 90 east)."""

    heading_deg: float


@dataclass(frozen=True)
class SetSpeed(Command):
    """Fly later horizontal moves at ``speed_m_s``."""

    speed_m_s: float


@dataclass(frozen=True)
class Orbit(Command):
    """Circle ``turns`` times (clockwise) around the point ``radius_m`` ahead."""

    radius_m: float
    turns: float


@dataclass(frozen=True)
class Payload(Command):
    """A payload action (no motion): ``TurnOn``, ``Calibrate``, ``TurnOnCamera``, ..."""

    name: str

    @property
    def action(self) -> str:
        return self.name

    @property
    def args(self) -> tuple[float, ...]:
        return ()


@dataclass(frozen=True)
class PluginAction(Command):
    """An action provided by a plugin (:mod:`eamos.program.plugins`), with its arguments.

    ``params`` are the plugin's parameter names, ``values`` the numbers in that
    order; adapters find the implementation by ``name`` for their family.
    """

    name: str
    params: tuple[str, ...] = ()
    values: tuple[float, ...] = ()

    @property
    def action(self) -> str:
        return self.name

    @property
    def args(self) -> tuple[float, ...]:
        return self.values

    @property
    def moves(self) -> bool:
        return False

    def value(self, param: str) -> float:
        """The argument given for parameter ``param`` (KeyError if the plugin has none)."""
        if param not in self.params:
            raise KeyError(f"{self.name} has no parameter {param!r}")
        return self.values[self.params.index(param)]


def decode_command(
    action: str,
    args: tuple[float, ...] | list[float],
    plugins: Mapping[str, ActionSpec] | None = None,
) -> Command:
    """Decode an action name and its arguments into a :class:`Command`.

    ``plugins`` are the plugin actions the caller's adapter knows (by name,
    ``PluginRegistry.specs()``); one of them decodes into a :class:`PluginAction`
    checked against the plugin's parameter list.  Raises :class:`CommandError`
    for an unknown action, a wrong number of arguments, or an argument that is
    not a finite number.
    """
    spec = ACTIONS.get(action)
    plugin = None
    if spec is None and plugins is not None:
        spec = plugin = plugins.get(action)
    if spec is None:
        raise CommandError(f"unknown action {action!r}")
    if len(args) != len(spec.params):
        raise CommandError(
            f"{action} takes {len(spec.params)} argument(s) ({', '.join(spec.params) or 'none'}),"
            f" got {len(args)}"
        )
    values: list[float] = []
    for name, value in zip(spec.params, args, strict=True):
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise CommandError(f"{action}: {name} must be a number, got {value!r}")
        number = float(value)
        if number != number or number in (float("inf"), float("-inf")):
            raise CommandError(f"{action}: {name} must be finite, got {value!r}")
        values.append(number)
    if plugin is not None:
        return PluginAction(action, plugin.params, tuple(values))
    if spec.payload:
        return Payload(action)
    if action.startswith("FlyBy"):
        return FlyBy(action[-1], values[0])
    command: type[Command] = _COMMAND_CLASSES[action]
    return command(*values)


_COMMAND_CLASSES: dict[str, type[Command]] = {
    c.__name__: c
    for c in (
        Arm,
        Disarm,
        Takeoff,
        Land,
        FlyToXYZ,
        FlyToLLA,
        PauseFor,
        ReturnHome,
        Hold,
        Yaw,
        SetSpeed,
        Orbit,
    )
}


def target_xyz(
    command: Command, base: tuple[float, float, float]
) -> tuple[float, float, float] | None:
    """Where a move goes in the mission frame, starting from ``base`` (x, y, z metres).

    ``Takeoff`` climbs straight up from ``base``; ``FlyBy*`` adds its offset;
    ``FlyToXYZ`` is absolute.  ``None`` for commands without a local target
    (``FlyToLLA`` needs the adapter's geodetic frame; the others do not move).
    """
    x, y, z = base
    if isinstance(command, Takeoff):
        return (x, y, command.height_m)
    if isinstance(command, FlyBy):
        dx, dy, dz = command.offset_m()
        return (x + dx, y + dy, z + dz)
    if isinstance(command, FlyToXYZ):
        return (command.x_m, command.y_m, command.z_m)
    return None


# --- Descriptions for people: the language reference's tables and the editor's help ---------
#
# Added for the language server's hover and completion and for the generated tables of
# docs/mission-language.md (tests/test_docs_tables.py keeps them equal).  The compiler's checks
# (eamos/compiler/check.py, limits.py) enforce the ranges stated here.

#: The flight actions every drone type of the paper offers.
FLIGHT_ACTIONS = _FLIGHT

#: Allowed values of each action parameter, as the compiler checks them.
PARAM_RANGES: dict[str, str] = {
    "height_m": "0 < height_m ≤ 10 000",
    "distance_m": "-10 000 to 10 000",
    "x_m": "-10 000 to 10 000",
    "y_m": "-10 000 to 10 000",
    "z_m": "-10 000 to 10 000",
    "alt_m": "-10 000 to 10 000",
    "lat_deg": "-90 to 90",
    "lon_deg": "-180 to 180",
    "duration_s": "0 to 86 400",
    "heading_deg": "0 to 360",
    "speed_m_s": "0 < speed_m_s ≤ 30",
    "radius_m": "0 < radius_m ≤ 1 000",
    "turns": "0 < turns ≤ 100",
}

#: A parameter's unit, from the suffix of its name.
UNIT_NAMES: dict[str, str] = {
    "m": "metres",
    "deg": "degrees",
    "s": "seconds",
    "m/s": "metres per second",
    "%": "percent",
    "turns": "turns (a count; fractions allowed)",
}


def param_unit(param: str) -> str:
    """The unit of an action parameter (``height_m`` -> ``m``), from its name's suffix."""
    if param.endswith("_m_s"):
        return "m/s"
    if param == "turns":  # a count: the name is its own unit
        return "turns"
    return param.rsplit("_", 1)[-1] if "_" in param else ""


@dataclass(frozen=True)
class ControlSpec:
    """A control structure of the paper's Table 3: how it is written and what it does.

    ``params`` names the arguments in order (``cond`` a condition, ``n`` a whole number,
    ``Body``/``Then``/``Else``/``Exit`` block names, written without ``()``); ``optional``
    is how many trailing ones may be left out; ``on_drone`` is True when it may also be
    written on a drone (``D1.PauseWhile(...)``), which then evaluates the condition.
    """

    name: str
    params: tuple[str, ...]
    doc: str
    optional: int = 0
    on_drone: bool = False

    @property
    def signature(self) -> str:
        """``If(cond, Then[, Else])``: the argument shape as the reference writes it."""
        required = self.params[: len(self.params) - self.optional]
        text = ", ".join(required)
        for extra in self.params[len(required) :]:
            text += f"[, {extra}]"
        return f"{self.name}({text})"


CONTROL_STRUCTURES: dict[str, ControlSpec] = {
    c.name: c
    for c in (
        ControlSpec(
            "If",
            ("cond", "Then", "Else"),
            "Evaluate `cond` once; run `Then` if it holds, else `Else` (or nothing). "
            "Then continue.",
            optional=1,
        ),
        ControlSpec("WaitWhile", ("cond", "Body"), "Wait while `cond` holds; then run `Body`."),
        ControlSpec("WaitUntil", ("cond", "Body"), "Wait until `cond` holds; then run `Body`."),
        ControlSpec("PauseWhile", ("cond",), "Stop here while `cond` holds.", on_drone=True),
        ControlSpec("PauseUntil", ("cond",), "Stop here until `cond` holds.", on_drone=True),
        ControlSpec(
            "RepeatWhile",
            ("cond", "Body", "Exit"),
            "Run `Body` again and again while `cond` holds; then `Exit`.",
            optional=1,
        ),
        ControlSpec(
            "RepeatUntil",
            ("cond", "Body", "Exit"),
            "Run `Body` again and again until `cond` holds; then `Exit`.",
            optional=1,
        ),
        ControlSpec(
            "RepeatFor", ("n", "Body", "Exit"), "Run `Body` `n` times; then `Exit`.", optional=1
        ),
        ControlSpec(
            "DoWhile",
            ("cond", "Body", "Exit"),
            "Run `Body` as long as `cond` holds; interrupt it when it stops holding, "
            "then run `Exit`.",
            optional=1,
        ),
        ControlSpec(
            "DoUntil",
            ("cond", "Body", "Exit"),
            "Run `Body` until `cond` holds; interrupt it when it does, then run `Exit`.",
            optional=1,
        ),
        ControlSpec(
            "Try",
            ("Body", "OnFailure"),
            "Run `Body`; if one of its actions fails (on any of its drones), cancel the rest "
            "of `Body` on every one of them and run `OnFailure`; the mission goes on.",
        ),
        ControlSpec(
            "Whenever",
            ("cond", "Handler"),
            "While the rest of this block runs: each time `cond` becomes true, interrupt the "
            "running actions of the drones `Handler` uses, run `Handler`, then resume them.",
        ),
        ControlSpec(
            "Abandon",
            (),
            "In a Whenever's `Handler`: skip the rest of the guarded block on every drone of it "
            "instead of resuming.",
        ),
    )
}
