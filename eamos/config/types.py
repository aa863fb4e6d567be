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
from typing import Any

from ..hal.api import AdapterError
from ..hal.settings import did_you_mean
from ..hal.sim.settings import BATTERY_MODELS, BatteryModel, SimSettings
from ..program.uniform import DEFAULT_DRONE_TYPE, DRONE_TYPES
from .validation import ConfigError, check_hal, key_shown, participant_name

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
