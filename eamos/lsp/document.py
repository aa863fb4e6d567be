"""One mission document, analysed: the compiler's findings and an index of names.

Pure functions of the text; no server, no threads.  The findings come from
:func:`eamos.compiler.compile_mission`, exactly as ``eamos compile`` prints them (same
messages, hints, all at once).  The index of blocks and drones comes from the syntax
layer (:func:`eamos.compiler.parse.parse_partial`); where the text is too broken to parse
(half-typed), a lexical scan of ``func NAME`` / ``var NAME TYPE`` / ``NAME.`` answers instead.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cached_property
from typing import Literal

from ..compiler import CompilerBug, Diagnostic, MissionError, check_source, compile_mission
from ..compiler.errors import SourceLocation
from ..compiler.parse import parse_partial
from ..compiler.syntax import (
    GROUP_PREFIX,
    ActionCall,
    BlockCall,
    Control,
    Expr,
    GroupDecl,
    Import,
    Mission,
    Prop,
    flat_statements,
    props_in,
)
from ..program.uniform import DEFAULT_DRONE_TYPE, DRONE_TYPES, GROUND_STATION, DroneType
from ..program.uniform import GROUND_TYPE as _GROUND_TYPE
from .libraries import LibraryBlock, imported_blocks
from .names import Variable, in_scope, names_in_scope
from .positions import LineIndex

SymbolKind = Literal["block", "drone", "group", "variable"]


@dataclass(frozen=True, order=True)
class Span:
    """Text on one line: 1-based line, first column and the column after the last."""

    line: int
    col: int
    end_col: int


@dataclass(frozen=True)
class Occurrence:
    """A block, drone, group or variable name where it stands in the text, defined or used.

    ``key`` tells variables of one name apart (two loops' ``i``): see
    :attr:`~.names.Variable.key`.
    """

    name: str
    kind: SymbolKind
    span: Span
    definition: bool
    key: str = ""


@dataclass(frozen=True)
class Finding:
    """A compiler diagnostic placed on the text: what the editor underlines."""

    severity: Literal["error", "warning"]
    span: Span
    message: str
    hint: str


_WORD = re.compile(r"[^\W\d]\w*|[-+]?\.?\d[\w.]*")


def _extent(index: LineIndex, d: Diagnostic) -> Span:
    """Where a diagnostic underlines: its columns, else the word at its column, else one."""
    line, col = d.loc.line, d.loc.col
    if d.end_col is not None and d.end_col > col:
        return Span(line, col, d.end_col)
    word = _WORD.match(index.line(line), max(col - 1, 0))
    end = col + len(word.group()) if word else col + 1
    return Span(line, col, end)


def _placed(text: str, diagnostics: list[Diagnostic]) -> list[Finding]:
    index = LineIndex(text)
    return [
        Finding(d.severity, _extent(index, d), d.message, d.hint)
        if not d.loc.file
        # A problem in an imported library file: shown at the top, saying where it is.
        else Finding(d.severity, Span(1, 1, 2), f"{d.loc.file}:{d.loc}: {d.message}", d.hint)
        for d in diagnostics
    ]


def _internal(exc: BaseException) -> list[Finding]:
    # Our mistake, not the author's: say so where the editor shows it.
    return [Finding("error", Span(1, 1, 2), f"internal compiler error: {exc!r}", "")]


def findings(text: str, path: str = "<mission>") -> list[Finding]:
    """Every error and warning ``eamos compile`` reports for ``text``, in its order.

    The whole compiler runs (:func:`eamos.compiler.compile_mission`): the reference answer.
    ``path`` is the mission file's (its folder is searched first for imported libraries).
    """
    try:
        compiled = compile_mission(text, path)
        diagnostics = list(compiled.warnings)
    except MissionError as exc:
        diagnostics = list(exc.diagnostics)
    except (CompilerBug, RecursionError, MemoryError) as exc:
        return _internal(exc)
    return _placed(text, diagnostics)


def checked_findings(text: str, path: str = "<mission>") -> list[Finding]:
    """The findings of the compiler's checking phases: :func:`findings` without building graphs.

    :func:`eamos.compiler.check_source` is the first phase of
    :func:`eamos.compiler.compile_mission`; the graph phases after it are skipped (they
    cost most of the time of a large mission and find only one rare thing more: too many
    synchronisation arcs).  The
    server publishes these at once and the whole compile's :func:`findings` after it;
    tests/lsp/test_analysis.py checks both agree on every mission and on broken prefixes.
    """
    try:
        diagnostics = check_source(text, path)[1]
    except MissionError as exc:
        diagnostics = list(exc.diagnostics)
    except (CompilerBug, RecursionError, MemoryError) as exc:
        return _internal(exc)
    return _placed(text, diagnostics)


# -- the index of names ------------------------------------------------------------------


def _props(expr: Expr | None) -> Iterator[Prop]:
    return props_in(expr)


class MissionIndex:
    """Blocks and drones of one document: where each is defined and used.

    ``path`` is the mission file's (``"<mission>"`` for an unsaved text): its folder
    is where imported libraries are looked up first, as the compiler does.
    """

    def __init__(self, text: str, path: str = "<mission>") -> None:
        self.text = text
        self.path = path
        self.lines = LineIndex(text)
        self.mission = _parse(text)
        self.imports = self.mission.imports if self.mission is not None else _imports(text)
        #: Package names the mission imports: ``shapes`` in ``shapes.SEQ_Square(D1, 5)``.
        self.packages = {imp.path.rsplit("/", 1)[-1] for imp in self.imports}
        #: Groups by name, and the loop variables and block parameters of the file.
        self.groups: dict[str, GroupDecl] = (
            dict(self.mission.groups) if self.mission is not None else _lexical_groups(self.lines)
        )
        self.variables: list[Variable] = []
        found: list[Occurrence] = []
        if self.mission is not None:
            found = list(self._scoped_names(self.mission))
            named = {f.span for f in found}
            found += [o for o in self._from_syntax(self.mission) if o.span not in named]
        taken = {f.span for f in found}
        found.extend(o for o in _lexical(self.lines) if o.span not in taken)
        # ``shapes.`` reads like a drone's member to the lexical scan: a package is not one,
        # nor is a group or a loop variable.
        found = [
            o
            for o in found
            if not (o.kind == "drone" and (o.name in self.packages or self._not_drone(o)))
        ]
        self.occurrences = sorted(found, key=lambda o: o.span)
        self.blocks = {o.name for o in self.occurrences if o.kind == "block" and o.definition}
        self.drones = {o.name for o in self.occurrences if o.kind == "drone"}

    def _occurrence(
        self, name: str, kind: SymbolKind, line: int, col: int, definition: bool, key: str = ""
    ) -> Iterator[Occurrence]:
        # Only where the text really holds the name: a location from a broken tree is skipped.
        if self.lines.line(line)[col - 1 : col - 1 + len(name)] == name and name:
            yield Occurrence(name, kind, Span(line, col, col + len(name)), definition, key)

    def _not_drone(self, occ: Occurrence) -> bool:
        """A lexical ``NAME.`` that is a group or a variable in scope there."""
        if occ.name in self.groups:
            return True
        return any(v.name == occ.name for v in in_scope(self.variables, occ.span.line))

    def _scoped_names(self, mission: Mission) -> Iterator[Occurrence]:
        """Groups and loop variables (and parameters), defined and used (:mod:`.names`)."""
        for group in mission.groups.values():
            yield from self._occurrence(group.name, "group", group.loc.line, group.loc.col, True)
        variables, uses = names_in_scope(mission)
        self.variables = variables
        defined = {(v.loc.line, v.loc.col) for v in variables}
        for var in variables:
            if var.role == "parameter":
                yield from self._occurrence(
                    var.name, "variable", var.loc.line, var.loc.col, True, var.key
                )
        for use in uses:
            kind: SymbolKind = use.kind  # type: ignore[assignment]
            definition = use.kind == "variable" and (use.loc.line, use.loc.col) in defined
            yield from self._occurrence(
                use.name, kind, use.loc.line, use.loc.col, definition, use.key
            )

    def _from_syntax(self, mission: Mission) -> Iterator[Occurrence]:
        for decl in mission.drones.values():
            yield from self._occurrence(decl.name, "drone", decl.loc.line, decl.loc.col, True)
        for block in mission.blocks.values():
            yield from self._occurrence(block.name, "block", block.loc.line, block.loc.col, True)
            for stmt in flat_statements(block.statements):
                if isinstance(stmt, BlockCall):
                    yield from self._occurrence(
                        stmt.name, "block", stmt.loc.line, stmt.loc.col, False
                    )
                elif isinstance(stmt, ActionCall) and stmt.drone is not None:
                    yield from self._occurrence(
                        stmt.drone, "drone", stmt.loc.line, stmt.loc.col, False
                    )
                elif isinstance(stmt, Control):
                    if stmt.drone is not None:
                        loc = stmt.loc
                        yield from self._occurrence(stmt.drone, "drone", loc.line, loc.col, False)
                    for ref in (stmt.body, stmt.orelse, stmt.exit):
                        if ref is not None:
                            yield from self._occurrence(
                                ref.name, "block", ref.loc.line, ref.loc.col, False
                            )
                    for prop in _props(stmt.cond):
                        loc = prop.loc
                        yield from self._occurrence(prop.drone, "drone", loc.line, loc.col, False)

    @cached_property
    def library_blocks(self) -> dict[str, tuple[LibraryBlock, ...]]:
        """The blocks of each library the document imports, by package (read on first use)."""
        if not self.imports:
            return {}
        mission = self.mission or Mission("mission", {}, {}, "", self.text, imports=self.imports)
        return imported_blocks(mission, self.path)

    def library_block(self, qualified: str) -> LibraryBlock | None:
        """``shapes.SEQ_Square`` as a block of an imported library, or None."""
        package, _, name = qualified.partition(".")
        for block in self.library_blocks.get(package, ()) if name else ():
            if block.name == name:
                return block
        return None

    # -- queries -------------------------------------------------------------------------

    def at(self, line: int, col: int) -> Occurrence | None:
        """The block or drone name under a 1-based (line, column), or None."""
        for occ in self.occurrences:
            if occ.span.line == line and occ.span.col <= col <= occ.span.end_col:
                return occ
        return None

    def of(self, name: str, kind: SymbolKind) -> list[Occurrence]:
        """Every occurrence of one block, drone or group, in source order."""
        return [o for o in self.occurrences if o.name == name and o.kind == kind]

    def same(self, occ: Occurrence) -> list[Occurrence]:
        """Every occurrence of what ``occ`` names (one variable: the same declaration)."""
        return [o for o in self.of(occ.name, occ.kind) if o.key == occ.key]

    def variable(self, name: str, line: int) -> Variable | None:
        """The loop variable or parameter ``name`` in scope on ``line`` (the innermost)."""
        found = [v for v in in_scope(self.variables, line) if v.name == name]
        return max(found, key=lambda v: v.first) if found else None

    def group_type(self, name: str, line: int = 0) -> DroneType | None:
        """The members' type of the group ``name`` (a group parameter in scope too)."""
        var = self.variable(name, line) if line else None
        if var is not None:
            if not var.type.startswith(GROUP_PREFIX):
                return None
            return self._type(var.type.removeprefix(GROUP_PREFIX))
        group = self.groups.get(name)
        return self._type(group.type) if group is not None else None

    def _type(self, name: str) -> DroneType:
        return DRONE_TYPES.get(name, DRONE_TYPES[DEFAULT_DRONE_TYPE])

    def drone_type(self, drone: str, line: int = 0) -> DroneType:
        """A drone's type as the compiler sees it (undeclared or unknown: the default).

        With ``line``, a loop's member variable or a drone parameter in scope there has
        its own type (a member: its group's).
        """
        if drone == GROUND_STATION:
            return _GROUND_TYPE
        var = self.variable(drone, line) if line else None
        if var is not None and var.type and not var.type.startswith(GROUP_PREFIX):
            return self._type(var.type)
        declared = self.declared_type(drone)
        return DRONE_TYPES.get(declared or "", DRONE_TYPES[DEFAULT_DRONE_TYPE])

    def declared_type(self, drone: str) -> str | None:
        """The type name a drone is declared with, or None."""
        if self.mission is not None and drone in self.mission.drones:
            return self.mission.drones[drone].type
        for line in self.lines.lines:
            match = _VAR.match(line)
            if match and match.group(1) == drone:
                return match.group(2)
        return None


def _parse(text: str) -> Mission | None:
    try:
        mission, _, _ = parse_partial(text)
    except MissionError:
        return None  # empty, binary or too large: nothing to index
    return mission


_GROUP_DECL = re.compile(r"^\s*(?:var\s+)?([^\W\d]\w*)\s*\[\s*(\d+)\s*\]\s*([\w.]+)")


def _lexical_groups(lines: LineIndex) -> dict[str, GroupDecl]:
    """``var Team [20]Quadcopter`` lines of a text the parser cannot read."""
    out: dict[str, GroupDecl] = {}
    for number, line in enumerate(lines.lines, start=1):
        match = _GROUP_DECL.match(line)
        if match:
            loc = SourceLocation(number, match.start(1) + 1)
            out[match.group(1)] = GroupDecl(
                match.group(1), match.group(3), int(match.group(2)), loc
            )
    return out


_IMPORT = re.compile(r'\bimport\s*(?:"([^"\n]*)"|\(([^)]*)\)?)')
_QUOTED = re.compile(r'"([^"\n]*)"')


def _imports(text: str) -> tuple[Import, ...]:
    """The imports of a text the parser cannot read, found lexically (comments skipped)."""
    blanked = blank_comments(text)
    out: list[Import] = []
    for match in _IMPORT.finditer(blanked):
        if match.group(1) is not None:
            spots = [(match.group(1), match.start(1))]
        else:
            group = match.group(2) or ""
            spots = [(q.group(1), match.start(2) + q.start(1)) for q in _QUOTED.finditer(group)]
        for name, at in spots:
            if name:
                line = blanked.count("\n", 0, at) + 1
                col = at - (blanked.rfind("\n", 0, at) + 1)
                out.append(Import(name, SourceLocation(line, col + 1)))
    return tuple(out)


# A lexical reading for text the parser cannot follow.  Comments are blanked first so
# that a commented-out block is not a definition.
_COMMENT = re.compile(r"//[^\n\r]*|/\*.*?(?:\*/|\Z)", re.S)
_FUNC = re.compile(r"^\s*func\s+([^\W\d]\w*)")
_VAR = re.compile(r"^\s*(?:var\s+)?([^\W\d]\w*)\s+([^\W\d]\w*)\s*$")
_VAR_KEYWORD = re.compile(r"^\s*var\s+([^\W\d]\w*)")
_MEMBER = re.compile(r"(?<![\w.])([^\W\d]\w*)\s*\.")
_BLOCK_NAME = re.compile(r"(?<![\w.])((?:SEQ|PAR)_\w+|INIT)\b")


def blank_comments(text: str) -> str:
    return _COMMENT.sub(lambda m: re.sub(r"[^\n\r]", " ", m.group()), text)


def _lexical(index: LineIndex) -> Iterator[Occurrence]:
    lines = LineIndex(blank_comments("\n".join(index.lines))).lines
    for number, line in enumerate(lines, start=1):
        func = _FUNC.match(line)
        if func:
            yield Occurrence(
                func.group(1), "block", Span(number, func.start(1) + 1, func.end(1) + 1), True
            )
        var = _VAR_KEYWORD.match(line)
        if var:
            yield Occurrence(
                var.group(1), "drone", Span(number, var.start(1) + 1, var.end(1) + 1), True
            )
        for member in _MEMBER.finditer(line):
            yield Occurrence(
                member.group(1),
                "drone",
                Span(number, member.start(1) + 1, member.end(1) + 1),
                False,
            )
        for block in _BLOCK_NAME.finditer(line):
            if func and block.start(1) == func.start(1):
                continue
            yield Occurrence(
                block.group(1), "block", Span(number, block.start(1) + 1, block.end(1) + 1), False
            )
