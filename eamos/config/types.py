"""Drone types in a fleet file: ``[types.NAME.hal]`` tables and each drone's type lineage.

A fleet file may give settings per drone type (``[types.DroneType2.hal]``); they
apply to every drone of that type.  A drone's *lineage* is its type followed by
the types that type embeds (depth first, in declaration order): a custom type
``type Inspector interface { Quadcopter; TakePhoto() }`` has the lineage
``("Inspector", "Quadcopter")``, so it flies Quadcopter's settings unless the
fleet file names ``Inspector`` too (nearest type wins).

Precedence of a drone's merged ``[hal]`` table, strongest first (docs/safety.md):
``[drones.X.hal]`` > ``[types.T.hal]`` (nearest type of the lineage first) >
``[defaults.hal]`` > the built-in battery model of the nearest built-in type
(:data:`eamos.hal.sim.settings.BATTERY_MODELS`; simulated drones only).
All of it is pure: nothing here reads a clock or a file.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from types import MappingProxyType
from typing import Any

from ..hal.api import AdapterError
from ..hal.settings import did_you_mean
from ..hal.sim.settings import BATTERY_MODELS, BatteryModel, SimSettings
from ..program.uniform import DEFAULT_DRONE_TYPE, DRONE_TYPES
from .validation import ConfigError, check_hal, key_shown, participant_name

#: The pre-flight check's model of a MAVLink drone, per autopilot: what each SITL was
#: measured to do with the drone type's speeds set (experiment A on ArduCopter 4.7.0-dev
#: and PX4 main SIH in ../shared/sitl, vehicle seconds; tests/sitl/test_check_model_vs_sitl.py
#: compares the prediction with a real flight).  ``arm_delay_s``: from the connection until
#: it may arm (ArduCopter's EKF takes ~39 s of vehicle time at any speed-up, PX4 main 2-4 s);
#: ``liftoff_delay_s``: take-off command to leaving the ground; ``accel_mps2``: ArduCopter's
#: jerk-limited controller over 1 m moves, PX4's P position controller; ``descent_speed_mps``:
#: LAND_SPEED 0.5 m/s, PX4's MPC_LAND_SPEED then MPC_LAND_CRWL below 1 m; ``land_detect_s``
#: touchdown to "landed"; ``disarm_after_landing_s`` touchdown to disarm; ``tolerance_m`` and
#: ``settle_speed_mps`` the adapter's completion (eamos.hal.mavlink.autopilots).  PX4 SIH
#: varies much from flight to flight (its estimate wanders; experiment A took 22-34 s in
#: five flights, a 1 m leg 1.3-4.2 s, a landing from 1.5 m 4.8-9.3 s): its figures are
#: the middle of those flights.  The
#: horizontal and climb speeds are the drone type's, which the adapter sets on the vehicle.
MAVLINK_MODELS: Mapping[str, Mapping[str, float]] = MappingProxyType(
    {
        "ardupilot": MappingProxyType(
            {
                "arm_delay_s": 39.0,
                "liftoff_delay_s": 3.6,
                "accel_mps2": 0.72,
                "descent_speed_mps": 0.5,
                "land_detect_s": 1.5,
                "disarm_after_landing_s": 2.3,
                "tolerance_m": 0.3,
                "settle_speed_mps": 0.3,
            }
        ),
        "px4": MappingProxyType(
            {
                "arm_delay_s": 3.0,
                "liftoff_delay_s": 5.0,
                "accel_mps2": 0.6,
                "descent_speed_mps": 0.4,
                "land_detect_s": 4.0,
                "disarm_after_landing_s": 6.0,
                "tolerance_m": 0.6,
                "settle_speed_mps": 0.5,
            }
        ),
    }
)
#: The drone-type keys of a MAVLink drone's ``hal`` its model takes over (the adapter sets
#: them on the vehicle: eamos.hal.mavlink.params.speed_plan).
MAVLINK_MODEL_KEYS = ("horizontal_speed_mps", "climb_speed_mps", "speedup")


def mavlink_model(hal: Mapping[str, Any]) -> tuple[dict[str, Any] | None, str]:
    """The simulator settings that model a MAVLink drone (its ``hal`` table), and a note.

    The autopilot is the ``hal``'s ``autopilot`` (or its ``sim_vehicle``'s); ``None`` and
    why when it is not known (``autopilot = "auto"``): the check then cannot say more than
    the simulator's default model would.
    """
    autopilot = hal.get("autopilot", "auto")
    vehicle = hal.get("sim_vehicle")
    if autopilot == "auto" and isinstance(vehicle, Mapping):
        autopilot = vehicle.get("autopilot", "auto")
    model = MAVLINK_MODELS.get(str(autopilot))
    if model is None:
        return None, (
            'its autopilot is not known (hal.autopilot = "auto"): checked with the '
            'simulator\'s default model; say autopilot = "px4" or "ardupilot" for its timing'
        )
    settings: dict[str, Any] = dict(model)
    settings.update({k: hal[k] for k in MAVLINK_MODEL_KEYS if k in hal})
    return settings, f"modelled as {autopilot} (measured on its SITL)"


#: A lineage of no more types than this is followed (declared types are few; cycles are
#: the compiler's error, but a fleet must not loop on a hand-made table either).
MAX_LINEAGE = 64


def embedded_names(declared: Any) -> tuple[str, ...]:
    """The names a declared type embeds: from a compiler ``TypeDecl`` (``embeds`` holds
    ``(name, location)`` pairs) or a plain sequence of names."""
    embeds = getattr(declared, "embeds", declared)
    names = []
    for item in embeds:
        names.append(item if isinstance(item, str) else str(item[0]))
    return tuple(names)


def type_lineage(drone_type: str, declared: Mapping[str, Sequence[str]]) -> tuple[str, ...]:
    """``drone_type`` and every type it embeds, depth first, each once.

    ``declared``: the mission's declared types and what each embeds (built-in
    types embed nothing).  An empty ``drone_type`` (the ground station) has none.
    """
    out: list[str] = []
    stack = [drone_type] if drone_type else []
    while stack and len(out) < MAX_LINEAGE:
        name = stack.pop()
        if name in out:
            continue
        out.append(name)
        stack.extend(reversed(declared.get(name, ())))
    return tuple(out)


def builtin_model(lineage: Iterable[str]) -> BatteryModel:
    """The battery model of the nearest built-in type of ``lineage`` (else Quadcopter's)."""
    for name in lineage:
        if name in BATTERY_MODELS:
            return BATTERY_MODELS[name]
    return BATTERY_MODELS[DEFAULT_DRONE_TYPE]


def merge_hal(
    defaults: Mapping[str, Any],
    types: Mapping[str, Mapping[str, Any]],
    lineage: Sequence[str],
    drone: Mapping[str, Any],
) -> dict[str, Any]:
    """One drone's ``[hal]`` table: drone > types (nearest first) > defaults > built-in model."""
    merged = dict(defaults)
    for name in reversed(lineage):
        merged.update(types.get(name, {}))
    merged.update(drone)
    merged.setdefault("adapter", "sim")
    if merged["adapter"] == "sim":
        for key, value in builtin_model(lineage).settings().items():
            merged.setdefault(key, value)
    return merged


def load_types(w: str, raw: Any, defaults: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Validate a fleet file's ``[types]``: ``{NAME: {"hal": {...}}}`` -> ``{NAME: hal}``.

    ``w`` is the error prefix (``"<file>: "``).  A table for a simulated drone
    (its ``adapter``, else the defaults', is ``"sim"``) is checked against the
    simulator's settings here, so a misspelt battery field names this table.
    Whether NAME is a type of the mission is checked by :func:`check_type_names`.
    """
    if not isinstance(raw, dict):
        raise ConfigError(f"{w}types: must be a table of drone types, such as [types.Quadcopter]")
    out: dict[str, dict[str, Any]] = {}
    for name, table in raw.items():
        participant_name(f"{w}types.{key_shown(name)}", name, "drone type's name")
        where = f"{w}types.{name}"
        if not isinstance(table, dict):
            raise ConfigError(f"{where}: must be a table, such as [types.{name}.hal]")
        if set(table) - {"hal"}:
            key = sorted(set(table) - {"hal"})[0]
            raise ConfigError(
                f"{where}.{key}: unknown field (a type's table holds only [types.{name}.hal], "
                "the simulator's or adapter's settings, battery model included)"
            )
        hal = table.get("hal", {})
        if not isinstance(hal, dict):
            raise ConfigError(f"{where}.hal: must be a table")
        check_hal(f"{where}.hal.", hal, drone=True)
        if hal.get("adapter", defaults.get("adapter", "sim")) == "sim":
            settings = {k: v for k, v in hal.items() if k != "adapter"}
            try:
                SimSettings.from_mapping(settings, prefix=f"types.{name}.hal")
            except AdapterError as exc:
                raise ConfigError(f"{w}{exc}") from exc
        out[str(name)] = dict(hal)
    return out


def check_type_names(
    path: Path | None, types: Iterable[str], known: Iterable[str], used: Iterable[str]
) -> None:
    """Refuse a ``[types.NAME]`` table naming neither a built-in type nor one the mission declares.

    A misspelt type would silently leave its drones on the defaults' battery,
    so it is an error (as a misspelt ``[drones.X]`` is), naming the nearest type.
    ``known``: the mission's declared types; ``used``: the types its drones fly.
    """
    names = set(DRONE_TYPES) | set(known) | set(used)
    for name in sorted(set(types) - names):
        listed = ", ".join(sorted(names))
        raise ConfigError(
            f"{path}: types.{name}: not a drone type of the mission or a built-in one"
            f"{did_you_mean(name, names)}; known types: {listed}"
        )
