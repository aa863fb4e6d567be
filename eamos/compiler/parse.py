"""Phase 1: mission text -> :class:`~.syntax.Mission`, with a real Go parser.

tree-sitter-go gives a concrete syntax tree even for broken input, so this
phase reports every syntax error and every Go construct missions do not
support (``if``, ``go``, assignments ...) in one pass, each with the
control structure to use instead.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Literal

from .errors import Diagnostic, MissionError, SourceLocation
from .limits import MAX_ERRORS, MAX_SOURCE_BYTES, PROBE_BYTES
from .parse_expressions import Node, text
from .parse_statements import StatementReader
from .source import SourceText
from .syntax import (
    Block,
    DroneDecl,
    GroupDecl,
    Mission,
    Statement,
    TypeDecl,
)

__all__ = ["MAX_SOURCE_BYTES", "parse_mission", "parse_partial", "parse_with_warnings"]


def _go_parser() -> Any:
    try:
        import tree_sitter
        import tree_sitter_go
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise MissionError(
            [
                Diagnostic(
                    "error",
                    SourceLocation(1, 1),
                    "the mission compiler needs tree-sitter and tree-sitter-go",
                    "install them with: pip install 'eamos[compiler]'",
                )
            ]
        ) from exc
    return tree_sitter.Parser(tree_sitter.Language(tree_sitter_go.language()))


class _Reader(StatementReader):
    """Walks one tree-sitter tree, collecting diagnostics instead of stopping: the file's
    top level (package, drones, groups, drone types, blocks) here, each block's statements in
    :class:`~.parse_statements.StatementReader`."""

    def __init__(
        self, source: str, source_text: SourceText, file: str = "", package: str = ""
    ) -> None:
        super().__init__(source_text, file, package)
        self.original = source
        self.incomplete: set[str] = set()

    # -- top level ----------------------------------------------------------

    def mission(self, root: Node) -> Mission:
        name = "mission"
        blocks: dict[str, Block] = {}
        drones: dict[str, DroneDecl] = {}
        groups: dict[str, GroupDecl] = {}
        order: list[str] = []
        imports = self._imports(root)
        types: dict[str, TypeDecl] = {}
        for node in root.named_children:
            kind = node.type
            if kind in ("comment", "ERROR", "import_declaration"):
                continue
            if kind == "package_clause":
                ident = next(
                    (c for c in node.named_children if c.type == "package_identifier"), None
                )
                if ident is not None:
                    name = text(ident)
            elif kind == "var_declaration":
                for decl in self.var_specs(node):
                    first = drones.get(decl.name) or groups.get(decl.name)
                    if first is not None:
                        what = "group" if decl.name in groups else "drone"
                        self.diags.append(
                            Diagnostic(
                                "error",
                                decl.loc,
                                f"{what} '{decl.name}' is declared twice",
                                f"first declared at line {first.loc.line}",
                            )
                        )
                        continue
                    if isinstance(decl, GroupDecl):
                        groups[decl.name] = decl
                    else:
                        drones[decl.name] = decl
            elif kind == "function_declaration":
                block = self._function(node)
                if block is None:
                    continue
                if block.name in blocks:
                    self.error(
                        node.child_by_field_name("name") or node,
                        f"block '{block.name}' is defined twice",
                        f"first defined at line {blocks[block.name].loc.line}; rename one",
                    )
                    continue
                blocks[block.name] = block
                order.append(block.name)
            elif kind == "type_declaration":
                for tdecl in self._types(node):
                    if tdecl.name in types:
                        self.diags.append(
                            Diagnostic(
                                "error",
                                tdecl.loc,
                                f"drone type '{tdecl.name}' is declared twice",
                                f"first declared at line {types[tdecl.name].loc.line}",
                            )
                        )
                    types[tdecl.name] = tdecl
            elif kind in ("method_declaration", "const_declaration"):
                self.error(
                    node,
                    f"a Go {kind.split('_')[0]} declaration is not supported here",
                    "a mission has only drone declarations (var) and func blocks",
                )
            else:
                self.error(
                    node,
                    "unexpected top-level statement",
                    "a mission has only drone declarations (var) and func blocks",
                )
        # A block with parameters cannot start the mission: the first one without does.
        plain = [name for name in order if not blocks[name].params]
        entry = "INIT" if "INIT" in blocks else (plain or order or [""])[0]
        if self.prefix:
            entry = ""  # a library is not run by itself
        elif not blocks and not any(d.severity == "error" for d in self.diags):
            self.diags.append(
                Diagnostic(
                    "error",
                    SourceLocation(1, 1),
                    "the mission has no blocks",
                    "write at least one block, e.g. func SEQ_Main() { Drone1.Arm() }",
                )
            )
        return Mission(
            name=name,
            blocks=blocks,
            drones=drones,
            entry=entry,
            source=self.original,
            incomplete_blocks=frozenset(self.incomplete),
            imports=tuple(imports),
            types=types,
            groups=groups,
        )

    def _function(self, node: Node) -> Block | None:
        name_node = node.child_by_field_name("name")
        if name_node is None:
            return None
        name = text(name_node)
        params = self._params(node.child_by_field_name("parameters"), name) or ()
        self.param_names = frozenset(p.name for p in params)
        if node.child_by_field_name("result") is not None:
            self.error(
                node.child_by_field_name("result"),
                f"block '{name}' returns nothing",
                "remove the result type",
            )
        mode: Literal["SEQ", "PAR"]
        if name.startswith("PAR_"):
            mode = "PAR"
        else:
            mode = "SEQ"
            if not name.startswith("SEQ_") and name != "INIT":
                self.warn(
                    name_node,
                    f"block '{name}' has no SEQ_ or PAR_ prefix; its statements run in order",
                    f"rename it SEQ_{name} (in order) or PAR_{name} (in parallel)",
                )
        body = node.child_by_field_name("body")
        statements: list[Statement] = []
        if body is not None:
            statements, complete = self.statements_of(body)
            if not complete:
                self.incomplete.add(self.qualify(name))
        self.param_names = frozenset()
        return Block(
            name=self.qualify(name),
            mode=mode,
            statements=tuple(statements),
            loc=self.loc(name_node),
            params=params,
            end_line=node.end_point.row + 1,
        )


def parse_mission(source: str) -> Mission:
    """Parse mission text into a :class:`Mission`, or raise :class:`MissionError`.

    Raises with every syntax error and unsupported construct found at once.
    Warnings found on a successful parse are returned by :func:`parse_with_warnings`.
    """
    mission, _ = parse_with_warnings(source)
    return mission


def parse_with_warnings(
    source: str, file: str = "", package: str = ""
) -> tuple[Mission, list[Diagnostic]]:
    """Parse mission text; return the mission and the warnings, or raise MissionError.

    For a library file, ``file`` is its path (every location carries it) and
    ``package`` its package name (its blocks and types are named ``package.Name``).
    """
    try:
        return _parse(source, file, package)
    except MissionError as exc:
        if file:
            exc.diagnostics = [
                d if d.loc.file else replace(d, loc=replace(d.loc, file=file))
                for d in exc.diagnostics
            ]
        raise


def _parse(source: str, file: str, package: str) -> tuple[Mission, list[Diagnostic]]:
    what = "library file" if file else "mission file"
    if not source.strip():
        raise MissionError(
            [
                Diagnostic(
                    "error",
                    SourceLocation(1, 1),
                    f"the {what} is empty",
                    "write at least one block, e.g. func SEQ_Main() { Drone1.Arm() }",
                )
            ]
        )
    if "\x00" in source:
        raise MissionError(
            [
                Diagnostic(
                    "error",
                    SourceLocation(1, 1),
                    f"the {what} is not text (it contains NUL bytes)",
                    "give the path of a .go mission file",
                )
            ]
        )
    source_text = SourceText(source)
    encoded = source_text.data
    if len(encoded) > MAX_SOURCE_BYTES:
        raise MissionError(
            [
                Diagnostic(
                    "error",
                    SourceLocation(1, 1),
                    f"the {what} is too large ({len(encoded)} bytes)",
                    f"missions are limited to {MAX_SOURCE_BYTES} bytes",
                )
            ]
        )
    parser = _go_parser()
    junk = _junk(parser, encoded, file, package, what)
    if junk is not None:
        raise MissionError([junk])
    tree = parser.parse(encoded)
    reader = _Reader(source, source_text, file, package)
    reader.syntax_errors(tree.root_node)
    reader.long_names(tree.root_node)
    syntax_broken = any(d.severity == "error" for d in reader.diags)
    mission = reader.mission(tree.root_node)
    dropped = reader.dropped()
    if dropped is not None:
        reader.diags.append(dropped)
    errors = [d for d in reader.diags if d.severity == "error"]
    if errors:
        exc = MissionError(reader.diags)
        exc.partial = mission
        exc.fatal = syntax_broken or not mission.entry
        raise exc
    return mission, [d for d in reader.diags if d.severity == "warning"]


def _junk(parser: Any, encoded: bytes, file: str, package: str, what: str) -> Diagnostic | None:
    """The error for a long file whose first :data:`PROBE_BYTES` are not mission text.

    Junk costs tree-sitter ten times what a mission does and yields an error every few
    bytes; so a file longer than :data:`PROBE_BYTES` is first read that far (to a
    line's end), and more than :data:`MAX_ERRORS` errors there refuse it, at the first
    one, without reading the rest.  None: go on with the whole file.
    """
    if len(encoded) <= PROBE_BYTES:
        return None
    cut = encoded.rfind(b"\n", 0, PROBE_BYTES) + 1 or PROBE_BYTES
    head = encoded[:cut].decode("utf-8", errors="replace")
    root = parser.parse(encoded[:cut]).root_node
    reader = _Reader(head, SourceText(head), file, package)
    reader.syntax_errors(root)
    reader.mission(root)
    if reader.errors_kept + reader.dropped_errors <= MAX_ERRORS:
        return None
    first = min(
        (d.loc for d in reader.diags if d.severity == "error"), key=lambda at: (at.line, at.col)
    )
    return Diagnostic(
        "error",
        first,
        f"the {what} is not mission text: more than {MAX_ERRORS} errors in its first "
        f"{head.count(chr(10))} lines",
        "is this the mission file? a mission is Go text, e.g. func SEQ_Main() { Drone1.Arm() }",
    )


def parse_partial(
    source: str, file: str = "", package: str = ""
) -> tuple[Mission, list[Diagnostic], bool]:
    """Parse as far as possible: the mission, every diagnostic, and whether it is unusable.

    Unsupported Go statements are dropped with an error, but the rest of the
    mission is still returned so that later checks can report their errors too
    (all errors of a file at once).  Real syntax errors make the mission
    unusable: checking a broken tree would only add misleading errors.
    """
    try:
        mission, warnings = parse_with_warnings(source, file, package)
        return mission, warnings, False
    except MissionError as exc:
        if exc.partial is None:
            raise
        assert isinstance(exc.partial, Mission)
        return exc.partial, exc.diagnostics, exc.fatal
