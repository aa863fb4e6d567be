"""Completion: what may be written at the cursor, read from the text before it.

Half-typed text rarely parses, so the context comes from the characters before the cursor
(its line, and whether it stands inside a ``func`` body); the names come from the document's
index and the vocabulary (:mod:`eamos.program.uniform`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal

from ..program.uniform import ACTIONS, CONTROL_STRUCTURES, DRONE_TYPES, PROPERTIES
from .document import MissionIndex
from .vocabulary import (
    action_help,
    action_snippet,
    control_help,
    control_snippet,
    property_help,
    type_help,
)

ItemKind = Literal["action", "property", "control", "block", "drone", "type", "keyword"]


@dataclass(frozen=True)
class Item:
    """One completion: its label, what it is, a short detail, help, and a snippet to insert."""

    label: str
    kind: ItemKind
    detail: str
    documentation: str = ""
    snippet: str | None = None  # LSP snippet syntax (${1:name}); None: insert the label


_MEMBER = re.compile(r"([^\W\d]\w*)\s*\.\s*(\w*)$")
_VAR_TYPE = re.compile(r"^\s*var\s+[^\W\d]\w*\s+(\w*)$")
_GROUP_TYPE = re.compile(r"^\s*[^\W\d]\w*\s+(\w*)$")  # a line of ``var ( ... )``
_VAR_GROUP = re.compile(r"\bvar\s*\(([^()]*)$")
_CONTROL_ARG = re.compile(r"(\w+)\s*\(([^()]*(?:\([^()]*\)[^()]*)*)$")
_WORD = re.compile(r"(\w*)$")
_COMMENT_OR_STRING = re.compile(r"//|/\*.*?\*/|\"(?:[^\"\\\n]|\\.)*\"?|`[^`]*`?", re.S)


def _depth(text: str) -> int:
    """Brace depth at the end of ``text`` (comments and strings skipped)."""
    depth = 0
    at = 0
    for match in _COMMENT_OR_STRING.finditer(text):
        chunk = text[at : match.start()]
        depth += chunk.count("{") - chunk.count("}")
        if match.group() == "//":
            newline = text.find("\n", match.end())
            at = len(text) if newline == -1 else newline
        else:
            at = match.end()
    chunk = text[at:]
    return depth + chunk.count("{") - chunk.count("}")


def _open_parens(prefix: str) -> int:
    return prefix.count("(") - prefix.count(")")


def _actions(index: MissionIndex, drone: str) -> list[Item]:
    dtype = index.drone_type(drone)
    items = [
        Item(name, "action", f"{dtype.name} action", action_help(spec), action_snippet(spec))
        for name, spec in ACTIONS.items()
        if name in dtype.actions
    ]
    for name in ("PauseWhile", "PauseUntil"):
        spec = CONTROL_STRUCTURES[name]
        items.append(
            Item(name, "control", spec.signature, control_help(spec), control_snippet(spec))
        )
    return items


def _properties(index: MissionIndex, drone: str) -> list[Item]:
    dtype = index.drone_type(drone)
    return [
        Item(
            name,
            "property",
            f"{spec.unit or spec.type} ({dtype.name})",
            property_help(spec),
            f"{name}()",
        )
        for name, spec in PROPERTIES.items()
        if name in dtype.properties
    ]


def _blocks(index: MissionIndex, call: bool) -> list[Item]:
    return [
        Item(
            name,
            "block",
            "PAR block" if name.startswith("PAR_") else "SEQ block",
            snippet=f"{name}()" if call else None,
        )
        for name in sorted(index.blocks)
    ]


def _drones(index: MissionIndex) -> list[Item]:
    return [
        Item(name, "drone", index.declared_type(name) or index.drone_type(name).name)
        for name in sorted(index.drones)
    ]


def _controls() -> list[Item]:
    items = [
        Item(name, "control", spec.signature, control_help(spec), control_snippet(spec))
        for name, spec in CONTROL_STRUCTURES.items()
    ]
    pause = ACTIONS["PauseFor"]
    items.append(
        Item(
            "PauseFor", "action", "PauseFor(duration_s)", action_help(pause), action_snippet(pause)
        )
    )
    return items


def _types() -> list[Item]:
    return [Item(name, "type", "drone type", type_help(t)) for name, t in DRONE_TYPES.items()]


def completions(index: MissionIndex, line: int, col: int) -> list[Item]:
    """What may be written at 1-based (line, col) of the indexed text."""
    text = index.lines.line(line)
    prefix = text[: max(col - 1, 0)]
    member = _MEMBER.search(prefix)
    if member:
        drone = member.group(1)
        if _open_parens(prefix[: member.start()]) > 0:
            return _properties(index, drone)  # inside a condition
        return _actions(index, drone)
    if _VAR_TYPE.match(prefix):
        return _types()
    before = "\n".join([*index.lines.lines[: max(line - 1, 0)], prefix])
    if _GROUP_TYPE.match(prefix) and _VAR_GROUP.search(before):
        return _types()
    if _depth(before) <= 0:
        # Top level: declarations and blocks.
        return [
            Item("func", "keyword", "a block", snippet="func ${1:SEQ_Name}() {\n\t$0\n}"),
            Item("var", "keyword", "a drone", snippet="var ${1:Drone1} ${2:Quadcopter}"),
        ]
    args = _CONTROL_ARG.search(prefix)
    if args and _open_parens(prefix) > 0:
        name = args.group(1)
        if name in CONTROL_STRUCTURES and "," in args.group(2):
            return _blocks(index, call=False)  # Body, Then, Else, Exit
        return _drones(index)  # a condition reads drone properties
    # The start of a statement inside a block.
    return _drones(index) + _blocks(index, call=True) + _controls()
