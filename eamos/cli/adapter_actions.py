"""Which drone's adapter lacks which action: ``eamos check``, ``compile --fleet`` and ``run``.

A drone's fleet file entry chooses its adapter (``hal.adapter``); an adapter runs the
uniform API's actions and the plugin actions with an implementation for its family
(docs/plugins.md).  A mission that calls, on some drone, an action that drone's adapter
cannot run is bad input for that fleet: every such call is a located error (exit 2),
before anything flies.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from eamos.compiler import Diagnostic, MissionError
from eamos.compiler.drone_types import installed_plugins
from eamos.compiler.errors import SourceLocation
from eamos.program.plugins import PluginRegistry
from eamos.program.uniform import ACTIONS, GROUND_STATION


def adapter_of(hal: Mapping[str, Any]) -> tuple[str, str]:
    """(label, family) of a drone's adapter from its ``hal`` table.

    The label is what people call it (``sim``, ``px4``, ``ardupilot``, ``mavlink`` when
    the autopilot is found out at connection, ``ground``); the family is what plugins
    name implementations for (``sim``, ``mavlink``; ``ground`` runs none).
    """
    kind = str(hal.get("adapter", "sim"))
    if kind == "mavlink":
        vehicle = hal.get("sim_vehicle")
        autopilot = hal.get("autopilot") or (
            vehicle.get("autopilot") if isinstance(vehicle, Mapping) else None
        )
        label = autopilot if autopilot in ("px4", "ardupilot") else "mavlink"
        return str(label), "mavlink"
    if kind in ("sim", "fake"):
        return kind, "sim"
    return kind, "ground"


def adapter_gaps(compiled: Any, fleet: Any, plugins: PluginRegistry) -> list[Diagnostic]:
    """One located error per call of an action the calling drone's adapter cannot run.

    ``fleet`` is a :class:`~eamos.config.FleetConfig` (its ``hal_for``); the ground
    station's part is left out (it only waits, and the compiler checks that).
    """
    diags: list[Diagnostic] = []
    for drone, program in compiled.programs.items():
        if drone == GROUND_STATION:
            continue
        label, family = adapter_of(fleet.hal_for(drone))
        runs = frozenset(ACTIONS) | plugins.implemented_by(family)
        seen: set[tuple[str, int, int]] = set()
        for node in program.nodes:
            action = node.action
            if not node.native or not action or action in runs:
                continue
            if (action, node.line, node.col) in seen:
                continue  # one call expanded into several nodes (a loop, a library block)
            seen.add((action, node.line, node.col))
            plugin = plugins.get(action)
            if plugin is None:
                hint = "no installed action plugin provides it (docs/plugins.md)"
            else:
                has = ", ".join(plugin.families) or "no adapter"
                hint = (
                    f"the plugin providing {action} implements it for: {has}; fly {drone} "
                    f"with such an adapter, or install a plugin with a {family} implementation"
                )
            diags.append(
                Diagnostic(
                    "error",
                    SourceLocation(max(1, node.line), max(1, node.col)),
                    f"{drone}'s adapter ({label}) does not implement action '{action}'",
                    hint,
                )
            )
    return diags


def refuse_adapter_gaps(compiled: Any, fleet: Any, plugins: PluginRegistry | None = None) -> None:
    """Raise :class:`~eamos.compiler.MissionError` (exit 2) listing :func:`adapter_gaps`."""
    registry = installed_plugins() if plugins is None else plugins
    diags = adapter_gaps(
        compiled, fleet.for_mission(compiled.programs, compiled.mission.types), registry
    )
    if diags:
        raise MissionError(diags)


__all__ = ["adapter_gaps", "adapter_of", "refuse_adapter_gaps"]
