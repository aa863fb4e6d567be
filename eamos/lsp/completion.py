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
from .document import MissionIndex, blank_comments
from .libraries import available_libraries
from .names import in_scope
from .vocabulary import (
    action_help,
    action_snippet,
    control_help,
    control_snippet,
    property_help,
    type_help,
)

ItemKind = Literal[
    "action",
    "property",
    "control",
    "block",
    "drone",
    "type",
    "keyword",
    "library",
    "group",
    "variable",
]


@dataclass(frozen=True)
class Item:
    """One completion: its label, what it is, a short detail, help, and a snippet to insert."""

    label: str
    kind: ItemKind
    detail: str
    documentation: str = ""
    snippet: str | None = None  # LSP snippet syntax (${1:name}); None: insert the label


_MEMBER = re.compile(r"([^\W\d]\w*)\s*\.\s*(\w*)$")
# ``Team[i + 1].`` or ``Team[0:10].``: a member (or a part of a group, in All(...)).
_PICKED = re.compile(r"([^\W\d]\w*)\s*\[[^\[\]]*\]\s*\.\s*(\w*)$")
_LEN = re.compile(r"\blen\s*\(\s*(\w*)$")
_VAR_TYPE = re.compile(r"^\s*var\s+[^\W\d]\w*\s+(\w*)$")
_GROUP_TYPE = re.compile(r"^\s*[^\W\d]\w*\s+(\w*)$")  # a line of ``var ( ... )``
_VAR_GROUP = re.compile(r"\bvar\s*\(([^()]*)$")
_CONTROL_ARG = re.compile(r"(\w+)\s*\(([^()]*(?:\([^()]*\)[^()]*)*)$")
_WORD = re.compile(r"(\w*)$")
_IMPORT_QUOTE = re.compile(r'^\s*import\s*"[\w/]*$')  # import "sha|
_IMPORT_BARE = re.compile(r"^\s*import\s+$")  # import |
_IN_IMPORT_GROUP = re.compile(r"\bimport\s*\(([^()]*)$")  # import ( ... |
_GROUP_QUOTE = re.compile(r'^\s*"[\w/]*$')
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


def _actions(index: MissionIndex, drone: str, line: int = 0) -> list[Item]:
    dtype = index.group_type(drone, line) or index.drone_type(drone, line)
    items = [
        Item(name, "action", f"{dtype.name} action", action_help(spec), action_snippet(spec))
        for name, spec in ACTIONS.items()
        if name in dtype.actions
    ]
    # The control structures that may also be written on a drone (``D1.PauseWhile(...)``).
    items += [
        Item(name, "control", spec.signature, control_help(spec), control_snippet(spec))
        for name, spec in CONTROL_STRUCTURES.items()
        if spec.on_drone
    ]
    return items


def _properties(index: MissionIndex, drone: str, line: int = 0) -> list[Item]:
    dtype = index.group_type(drone, line) or index.drone_type(drone, line)
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


def _groups(index: MissionIndex) -> list[Item]:
    return [
        Item(name, "group", f"[{g.size}]{g.type}", f"a group of {g.size} {g.type} drones")
        for name, g in sorted(index.groups.items())
    ]


def _variables(index: MissionIndex, line: int) -> list[Item]:
    """The loop variables and parameters in scope on ``line`` (the innermost of a name)."""
    seen: dict[str, Item] = {}
    for var in in_scope(index.variables, line):
        what = {"member": f"each member of {var.over}", "index": f"index in {var.over}"}.get(
            var.role, var.type
        )
        seen[var.name] = Item(var.name, "variable", f"{var.role}: {what}")
    return list(seen.values())


_LOOPS = [
    Item(
        "for",
        "keyword",
        "a loop over a group",
        "Each iteration runs its statements in order; the iterations run as the block's "
        "statements (at once in a PAR_ block, one after the other in a SEQ_ block).",
        "for ${1:i}, ${2:d} := range ${3:Team} {\n\t$0\n}",
    ),
    Item(
        "for",
        "keyword",
        "a counting loop",
        "for i := 0; i < 10; i++ { ... }: i takes 0 .. 9.",
        "for ${1:i} := ${2:0}; ${1:i} < ${3:10}; ${1:i}++ {\n\t$0\n}",
    ),
]
_GROUP_CONDITIONS = [
    Item(name, "control", f"{name}(Team.Z() > 2)", doc, f"{name}(${{1:Team}}.$0)")
    for name, doc in (
        ("All", "True when the condition holds for every member of the group."),
        ("Any", "True when the condition holds for at least one member."),
        ("Count", "The number of members for which the condition holds (compare it)."),
    )
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


def _libraries(index: MissionIndex, quoted: bool) -> list[Item]:
    """Every library ``import`` would find (the compiler's search path), quoted if asked."""
    return [
        Item(
            lib.name,
            "library",
            f"library ({lib.origin})",
            f"`{lib.folder}`",
            f'"{lib.name}"' if quoted else None,
        )
        for lib in available_libraries(index.path)
    ]


def _library_blocks(index: MissionIndex, package: str) -> list[Item]:
    return [
        Item(b.name, "block", b.signature, b.help(), b.snippet)
        for b in index.library_blocks.get(package, ())
    ]


def _packages(index: MissionIndex) -> list[Item]:
    return [Item(p, "library", "imported library") for p in sorted(index.packages)]


def _import_context(index: MissionIndex, line: int, prefix: str) -> list[Item] | None:
    """Library names after ``import "`` (or in an ``import ( ... )`` group); None elsewhere."""
    if _IMPORT_QUOTE.match(prefix):
        return _libraries(index, quoted=False)
    if _IMPORT_BARE.match(prefix):
        return _libraries(index, quoted=True)
    if _GROUP_QUOTE.match(prefix) or not prefix.strip():
        before = blank_comments("\n".join([*index.lines.lines[: max(line - 1, 0)], prefix]))
        if _IN_IMPORT_GROUP.search(before):
            return _libraries(index, quoted=not prefix.strip())
    return None


def _argument(spec_params: tuple[str, ...], args: str) -> str | None:
    """The parameter of a control structure the cursor is at (``args``: the text after ``(``)."""
    depth = commas = 0
    for ch in args:
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
        elif ch == "," and depth == 0:
            commas += 1
    return spec_params[commas] if commas < len(spec_params) else None


def _types() -> list[Item]:
    return [Item(name, "type", "drone type", type_help(t)) for name, t in DRONE_TYPES.items()]


def completions(index: MissionIndex, line: int, col: int) -> list[Item]:
    """What may be written at 1-based (line, col) of the indexed text."""
    text = index.lines.line(line)
    prefix = text[: max(col - 1, 0)]
    imports = _import_context(index, line, prefix)
    if imports is not None:
        return imports
    if _LEN.search(prefix):
        params = _variables(index, line)
        return _groups(index) + [v for v in params if v.detail.startswith("parameter: []")]
    picked = _PICKED.search(prefix)
    if picked and (picked.group(1) in index.groups or index.variable(picked.group(1), line)):
        if _open_parens(prefix[: picked.start()]) > 0:
            return _properties(index, picked.group(1), line)
        return _actions(index, picked.group(1), line)
    member = _MEMBER.search(prefix)
    if member:
        drone = member.group(1)
        if drone in index.packages:
            return _library_blocks(index, drone)
        if _open_parens(prefix[: member.start()]) > 0:
            return _properties(index, drone, line)  # inside a condition
        if index.group_type(drone, line) is not None:
            return []  # a group takes no action: Team[i].Arm(), or a loop
        return _actions(index, drone, line)
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
            Item(
                "var",
                "keyword",
                "a group of drones",
                snippet="var ${1:Team} [${2:10}]${3:Quadcopter}",
            ),
            Item("import", "keyword", "a library", snippet='import "${1:shapes}"'),
        ]
    args = _CONTROL_ARG.search(prefix)
    if args and _open_parens(prefix) > 0:
        spec = CONTROL_STRUCTURES.get(args.group(1))
        param = _argument(spec.params, args.group(2)) if spec else "cond"
        if param == "n":
            return []  # a whole number
        if param is not None and param != "cond":
            return _blocks(index, call=False)  # Body, Then, Else, Exit, OnFailure, ...
        # A condition reads drone properties: of drones, members, or a group in All(...).
        return _drones(index) + _groups(index) + _variables(index, line) + _GROUP_CONDITIONS
    # The start of a statement inside a block.
    return (
        _drones(index)
        + _groups(index)
        + _variables(index, line)
        + _packages(index)
        + _blocks(index, call=True)
        + _controls()
        + _LOOPS
    )
