"""What the editor asks at a position: definition, references, rename, hover, outline.

Pure functions over a :class:`~.document.MissionIndex`, in the compiler's coordinates
(1-based lines, character columns).  Completion is in :mod:`.completion`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from ..compiler.syntax import (
    ActionCall,
    BlockCall,
    Control,
    ForLoop,
    Mission,
    expr_text,
    member_name,
)
from ..program.uniform import ACTIONS, CONTROL_STRUCTURES, DRONE_TYPES, GROUND_STATION, PROPERTIES
from .document import MissionIndex, Occurrence, Span, _props
from .libraries import LibraryBlock
from .names import Variable
from .vocabulary import action_help, control_help, property_help, type_help


@dataclass(frozen=True)
class Symbol:
    """One entry of the document outline: a block (with its kind) or a drone."""

    name: str
    kind: str  # "SEQ block", "PAR block", "drone"
    detail: str
    span: Span


@dataclass(frozen=True)
class Hover:
    """Markdown help about the name under the cursor, and the text it covers."""

    markdown: str
    span: Span


_QUALIFIED = re.compile(r"([^\W\d]\w*)\s*\.\s*([^\W\d]\w*)")


def library_block_at(index: MissionIndex, line: int, col: int) -> tuple[LibraryBlock, Span] | None:
    """The imported library's block named at (line, col) (``shapes.SEQ_Square``), and its span."""
    text = index.lines.line(line)
    for match in _QUALIFIED.finditer(text):
        if match.group(1) in index.packages and match.start() + 1 <= col <= match.end() + 1:
            block = index.library_block(f"{match.group(1)}.{match.group(2)}")
            if block is not None:
                return block, Span(line, match.start() + 1, match.end() + 1)
    return None


def definition(index: MissionIndex, line: int, col: int) -> list[Span]:
    """Where the block, drone, group or variable under the cursor is defined (declared)."""
    occ = index.at(line, col)
    if occ is None:
        return []
    return [o.span for o in index.same(occ) if o.definition]


def references(
    index: MissionIndex, line: int, col: int, include_declaration: bool = True
) -> list[Span]:
    """Every place the block, drone, group or variable under the cursor is named."""
    occ = index.at(line, col)
    if occ is None:
        return []
    return [o.span for o in index.same(occ) if include_declaration or not o.definition]


_IDENTIFIER = re.compile(r"[^\W\d]\w*\Z")


_KEYWORDS = frozenset({"func", "var", "for", "range", "len", "All", "Any", "Count", "int"})


def rename(index: MissionIndex, line: int, col: int, new_name: str) -> list[Span] | None:
    """The spans to replace by ``new_name`` to rename the block, drone, group or loop
    variable (or block parameter) under the cursor.

    None when there is nothing to rename there or ``new_name`` cannot be such a name (not an
    identifier, a name of the vocabulary, the ground station's, or already taken: by a
    block, drone or group, or by a variable in scope where the renamed one is).
    """
    occ = index.at(line, col)
    if occ is None or not _IDENTIFIER.match(new_name) or new_name == occ.name:
        return None
    if "." in occ.name:
        return None  # a library's block is renamed in its library, not here
    reserved = set(ACTIONS) | set(PROPERTIES) | set(CONTROL_STRUCTURES) | set(DRONE_TYPES)
    if new_name in reserved or new_name == GROUND_STATION or new_name in _KEYWORDS:
        return None
    if new_name in index.blocks or new_name in index.drones or new_name in index.groups:
        return None
    spans = index.same(occ)
    if any(index.variable(new_name, o.span.line) is not None for o in spans):
        return None  # it would stand for another variable there
    return [o.span for o in spans]


def symbols(index: MissionIndex) -> list[Symbol]:
    """The document outline: drones as declared, then every block with its kind and drones."""
    out: list[Symbol] = []
    for occ in index.occurrences:
        if not occ.definition or occ.kind == "variable":
            continue
        if occ.kind == "drone":
            out.append(Symbol(occ.name, "drone", index.declared_type(occ.name) or "", occ.span))
        elif occ.kind == "group":
            group = index.groups.get(occ.name)
            detail = f"[{group.size}]{group.type}" if group is not None else ""
            out.append(Symbol(occ.name, "group", detail, occ.span))
        else:
            mode = "PAR" if occ.name.startswith("PAR_") else "SEQ"
            drones = ", ".join(block_drones(index.mission, occ.name))
            out.append(Symbol(occ.name, f"{mode} block", drones, occ.span))
    return out


def block_drones(mission: Mission | None, name: str) -> list[str]:
    """The drones a block involves, itself and through the blocks it runs, in first-use order."""
    if mission is None or name not in mission.blocks:
        return []
    seen: set[str] = set()
    drones: dict[str, None] = {}
    stack = [name]
    while stack:
        current = stack.pop()
        if current in seen or current not in mission.blocks:
            continue
        seen.add(current)
        callees: list[str] = []
        block = mission.blocks[current]
        statements = _flat(block.statements)
        hidden = {p.name for p in block.params} | {
            n for s in statements if isinstance(s, ForLoop) for n in (s.index, s.member) if n
        }
        for stmt in statements:
            if isinstance(stmt, ActionCall):
                if stmt.pick is not None:
                    drones.setdefault(f"{stmt.drone}[{expr_text(stmt.pick.index)}]", None)
                elif stmt.drone not in hidden or stmt.drone is None:
                    drones.setdefault(stmt.drone or GROUND_STATION, None)
            elif isinstance(stmt, BlockCall):
                callees.append(stmt.name)
            elif isinstance(stmt, Control):
                if stmt.drone is not None:
                    drones.setdefault(stmt.drone, None)
                for prop in _props(stmt.cond):
                    drones.setdefault(prop.drone, None)
                callees.extend(r.name for r in (stmt.body, stmt.orelse, stmt.exit) if r)
        stack.extend(reversed(callees))
    return list(drones)


def _flat(statements: tuple[object, ...]) -> list[object]:
    """The statements of a block, those in its loops (and nested loops') included."""
    out: list[object] = []
    stack = list(reversed(statements))
    while stack:
        stmt = stack.pop()
        out.append(stmt)
        if isinstance(stmt, ForLoop):
            stack.extend(reversed(stmt.body))
    return out


_AROUND = re.compile(r"[^\W\d]\w*")


def _word_at(line_text: str, col: int) -> tuple[str, int, int] | None:
    """The identifier covering 1-based column ``col`` (or ending just before it)."""
    for match in _AROUND.finditer(line_text):
        if match.start() + 1 <= col <= match.end() + 1:
            return match.group(), match.start() + 1, match.end() + 1
    return None


def _block_help(index: MissionIndex, occ: Occurrence) -> str:
    mode = "PAR" if occ.name.startswith("PAR_") else "SEQ"
    how = "its statements run in parallel" if mode == "PAR" else "its statements run in order"
    drones = block_drones(index.mission, occ.name)
    where = [o.span.line for o in index.of(occ.name, "block") if o.definition]
    text = f"**{occ.name}**: a {mode} block; {how}."
    if not where:
        return text + "\n\nNot defined in this file."
    text += f"\n\nDrones: {', '.join(drones) or 'none'}.  Defined at line {where[0]}."
    return text


def _drone_help(index: MissionIndex, name: str) -> str:
    if name == GROUND_STATION:
        return f"**{GROUND_STATION}**: the ground station; it only waits and never flies."
    declared = index.declared_type(name)
    dtype = index.drone_type(name)
    if declared is None:
        head = f"**{name}**: a drone used without a declaration, so a {dtype.name}."
    elif declared not in DRONE_TYPES:
        head = f"**{name}**: declared with the unknown type '{declared}'."
        return head
    else:
        head = f"**{name}**: a {dtype.name}."
    return f"{head}\n\n{type_help(dtype)}"


_INDEX = re.compile(r"\s*\[\s*(\d+)\s*\]")


def _group_help(index: MissionIndex, name: str, after: str) -> str:
    """A group, or one member of it when the text after the name is a number in brackets."""
    group = index.groups.get(name)
    if group is None:
        return f"**{name}**: a group of drones."
    dtype = index.group_type(name)
    help_text = type_help(dtype) if dtype is not None and group.type in DRONE_TYPES else ""
    member = _INDEX.match(after)
    if member is not None and int(member.group(1)) < group.size:
        k = int(member.group(1))
        head = (
            f"**{name}[{k}]**: member {k} of the group {name}, a {group.type}; "
            f"the drone `{member_name(name, k)}` in fleet files, programs, logs and graphs."
        )
    else:
        head = (
            f"**{name}**: a group of {group.size} {group.type} drones, "
            f"`{name}[0]` .. `{name}[{group.size - 1}]` (named "
            f"`{member_name(name, 0)}` .. `{member_name(name, group.size - 1)}` outside the "
            f"mission).  Loop over it with `for i, d := range {name}`; test all of them with "
            f"`All({name}.Z() > 2)`, `Any(...)`, `Count(...)`."
        )
    return f"{head}\n\n{help_text}" if help_text else head


def _variable_help(index: MissionIndex, var: Variable) -> str:
    """What a loop variable or a block parameter stands for."""
    where = f"the loop at line {var.loc.line}"
    if var.role == "member":
        dtype = index.drone_type(var.name, var.loc.line)
        return (
            f"**{var.name}**: each member of {var.over} in turn, in {where} (a {var.type}).\n\n"
            + type_help(dtype)
        )
    if var.role == "index":
        return f"**{var.name}**: the index of each member of {var.over} (0, 1, ...), in {where}."
    if var.role == "counter":
        return f"**{var.name}**: the counter of {where}, a whole number."
    return f"**{var.name}**: a parameter of {var.block}, of type `{var.type}`."


def hover(index: MissionIndex, line: int, col: int) -> Hover | None:
    """Help about the name at (line, col): an action, property, control structure, block,
    drone or drone type; None over anything else."""
    text = index.lines.line(line)
    found = _word_at(text, col)
    if found is None:
        return None
    word, start, end = found
    library = library_block_at(index, line, col)
    if library is not None:
        return Hover(library[0].help(), library[1])
    span = Span(line, start, end)
    before = text[: start - 1].rstrip()
    member = before.endswith(".")
    occ = index.at(line, start)
    if occ is not None and occ.span.col == start:
        if occ.kind == "block":
            return Hover(_block_help(index, occ), span)
        if occ.kind == "group":
            return Hover(_group_help(index, word, text[end - 1 :]), span)
        if occ.kind == "variable":
            var = next((v for v in index.variables if v.key == occ.key), None)
            if var is not None:
                return Hover(_variable_help(index, var), span)
        return Hover(_drone_help(index, word), span)
    if word in CONTROL_STRUCTURES:
        return Hover(control_help(CONTROL_STRUCTURES[word]), span)
    if word in ACTIONS and (member or word == "PauseFor"):
        return Hover(action_help(ACTIONS[word]), span)
    if word in PROPERTIES and member:
        return Hover(property_help(PROPERTIES[word]), span)
    if word in DRONE_TYPES:
        return Hover(type_help(DRONE_TYPES[word]), span)
    if word in ACTIONS:
        return Hover(action_help(ACTIONS[word]), span)
    return None
