"""Help texts about the mission vocabulary, for hover, completion and the reference's tables.

Everything here is rendered from :mod:`eamos.program.uniform` (actions with their parameters and
units, properties, drone types, control structures): the editor's help, the compiler's checks
and the tables of ``docs/mission-language.md`` come from the same descriptions.
``python -m eamos.lsp.vocabulary`` prints the tables; ``tests/test_docs_tables.py`` checks
that the reference carries exactly them.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..program.uniform import (
    ACTIONS,
    CONTROL_STRUCTURES,
    DEFAULT_DRONE_TYPE,
    DRONE_TYPES,
    FLIGHT_ACTIONS,
    PARAM_RANGES,
    PROPERTIES,
    UNIT_NAMES,
    ActionSpec,
    ControlSpec,
    DroneType,
    PropertySpec,
    param_unit,
)


def _param_text(param: str) -> str:
    unit = param_unit(param)
    bounds = PARAM_RANGES.get(param, "")
    unit_name = UNIT_NAMES.get(unit, unit)
    return f"{param} ({bounds} {unit_name})" if bounds else param


def action_signature(spec: ActionSpec) -> str:
    """``Takeoff(height_m)``."""
    return f"{spec.name}({', '.join(spec.params)})"


def action_help(spec: ActionSpec) -> str:
    """Markdown help of an action: how to call it, its arguments with units, what it does."""
    lines = [f"```go\n{action_signature(spec)}\n```", spec.doc]
    if spec.params:
        lines.append("Arguments: " + "; ".join(_param_text(p) for p in spec.params) + ".")
    if spec.payload:
        lines.append("A payload action: the drone does not move.")
    return "\n\n".join(lines)


def property_help(spec: PropertySpec) -> str:
    """Markdown help of a property: its unit and meaning."""
    unit = "true/false" if spec.type == "bool" else UNIT_NAMES.get(spec.unit, spec.unit)
    return (
        f"```go\n{spec.name}() // {unit}\n```\n\n{spec.doc} Read in conditions: `D1.{spec.name}()`."
    )


def _arguments_help(spec: ControlSpec) -> str:
    """What each kind of argument of ``spec`` is, from its parameters' names."""
    parts = []
    if "cond" in spec.params:
        parts.append("`cond` is a condition")
    if "n" in spec.params:
        parts.append("`n` is a whole number")
    blocks = [f"`{p}`" for p in spec.params if p not in ("cond", "n")]
    if blocks:
        are = "is a block name" if len(blocks) == 1 else "are block names"
        parts.append(f"{', '.join(blocks)} {are} written without `()`")
    return "; ".join(parts) + "." if parts else "It takes no arguments."


def control_help(spec: ControlSpec) -> str:
    """Markdown help of a control structure: its argument shape and meaning."""
    forms = f"{spec.signature}" + (f"\nD.{spec.signature}" if spec.on_drone else "")
    return f"```go\n{forms}\n```\n\n{spec.doc}\n\n{_arguments_help(spec)}"


def _ordered(names: frozenset[str] | set[str], order: Mapping[str, object]) -> list[str]:
    return [n for n in order if n in names]


def type_help(dtype: DroneType) -> str:
    """Markdown help of a drone type: its actions and properties."""
    default = " (the default type)" if dtype.name == DEFAULT_DRONE_TYPE else ""
    return (
        f"**{dtype.name}**{default}: {dtype.doc}\n\n"
        f"Actions: {', '.join(_ordered(dtype.actions, ACTIONS)) or 'none'}.\n\n"
        f"Properties: {', '.join(_ordered(dtype.properties, PROPERTIES)) or 'none'}."
    )


def control_snippet(spec: ControlSpec) -> str:
    """A snippet for a control structure: placeholders for every required argument."""
    required = spec.params[: len(spec.params) - spec.optional]
    holes = ", ".join(f"${{{i}:{p}}}" for i, p in enumerate(required, start=1))
    return f"{spec.name}({holes})"


def action_snippet(spec: ActionSpec) -> str:
    """A snippet for an action call: one placeholder per parameter."""
    holes = ", ".join(f"${{{i}:{p}}}" for i, p in enumerate(spec.params, start=1))
    return f"{spec.name}({holes})"


# -- the tables of docs/mission-language.md --------------------------------------------------


def _row(*cells: str) -> str:
    return "| " + " | ".join(cells) + " |"


def actions_table() -> str:
    """The reference's table of actions."""
    rows = [_row("action", "arguments", "what it does"), "|---|---|---|"]
    for spec in ACTIONS.values():
        args = ", ".join(_param_text(p) for p in spec.params) or "—"
        rows.append(_row(f"`{action_signature(spec)}`", args, spec.doc))
    return "\n".join(rows)


def properties_table() -> str:
    """The reference's table of properties."""
    rows = [_row("property", "unit", "meaning"), "|---|---|---|"]
    for spec in PROPERTIES.values():
        unit = "true/false" if spec.type == "bool" else spec.unit
        rows.append(_row(f"`{spec.name}()`", unit, spec.doc))
    return "\n".join(rows)


def _actions_of(dtype: DroneType) -> str:
    if dtype.actions == frozenset(ACTIONS):
        return "all"
    names = _ordered(dtype.actions - FLIGHT_ACTIONS, ACTIONS)
    if dtype.actions >= FLIGHT_ACTIONS:
        flight = _ordered(FLIGHT_ACTIONS, ACTIONS)
        names = [f"flight actions ({flight[0]} ... {flight[-1]})", *names]
    return ", ".join(names)


def types_table() -> str:
    """The reference's table of drone types."""
    rows = [_row("type", "actions", "properties", "description"), "|---|---|---|---|"]
    for dtype in DRONE_TYPES.values():
        name = f"`{dtype.name}`" + (" (default)" if dtype.name == DEFAULT_DRONE_TYPE else "")
        props = (
            "all"
            if dtype.properties == frozenset(PROPERTIES)
            else ", ".join(_ordered(dtype.properties, PROPERTIES))
        )
        rows.append(_row(name, _actions_of(dtype), props, dtype.doc))
    return "\n".join(rows)


def controls_table() -> str:
    """The reference's table of control structures."""
    rows = [_row("structure", "meaning"), "|---|---|"]
    for spec in CONTROL_STRUCTURES.values():
        forms = f"`{spec.signature}`" + (f", `D.{spec.signature}`" if spec.on_drone else "")
        rows.append(_row(forms, spec.doc))
    return "\n".join(rows)


def reference_tables() -> dict[str, str]:
    """Every generated table of the language reference, by name."""
    return {
        "actions": actions_table(),
        "properties": properties_table(),
        "drone types": types_table(),
        "control structures": controls_table(),
    }


if __name__ == "__main__":  # pragma: no cover - a helper for editing the reference
    for title, table in reference_tables().items():
        print(f"<!-- {title}: generated from eamos/program/uniform.py -->\n{table}\n")
