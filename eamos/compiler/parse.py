"""Phase 1: mission text -> :class:`~.syntax.Mission`, with a real Go parser.

tree-sitter-go gives a concrete syntax tree even for broken input, so this
phase reports every syntax error and every Go construct missions do not
support (``for``, ``if``, ``go``, assignments ...) in one pass, each with the
control structure to use instead.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Literal

from ..program.uniform import ACTIONS
from .errors import Diagnostic, MissionError, SourceLocation
from .limits import MAX_REPEAT, MAX_SOURCE_BYTES
from .parse_expressions import Node, text
from .parse_loops import LoopReader
from .source import SourceText
from .syntax import (
    CONTROL_KINDS,
    Block,
    Control,
    DroneDecl,
    Expr,
    GroupDecl,
    Member,
    Mission,
    Statement,
    TypeDecl,
)

__all__ = ["MAX_SOURCE_BYTES", "parse_mission", "parse_partial", "parse_with_warnings"]

# Go statements a mission cannot contain, and what to write instead.
_UNSUPPORTED_STATEMENTS = {
    "if_statement": (
        "a Go 'if' statement",
        "use If(cond, Then, Else) with blocks named Then and Else",
    ),
    "go_statement": ("a 'go' statement", "put the calls in a PAR_ block to run them in parallel"),
    "assignment_statement": ("an assignment", "missions have no variables; use literal values"),
    "short_var_declaration": (
        "a variable declaration",
        "missions have no variables; use literal values",
    ),
    "var_declaration": (
        "a variable declaration inside a block",
        "declare drones at the top: var Drone1 DroneType1",
    ),
    "const_declaration": ("a constant", "missions have no constants; use literal values"),
    "inc_statement": ("an increment", "missions have no variables"),
    "dec_statement": ("a decrement", "missions have no variables"),
    "return_statement": ("a 'return'", "a block ends at its closing brace"),
    "defer_statement": ("a 'defer'", "put the call last in a SEQ_ block"),
    "expression_switch_statement": ("a 'switch'", "use If(cond, Then, Else)"),
    "type_switch_statement": ("a 'switch'", "use If(cond, Then, Else)"),
    "select_statement": ("a 'select'", "use WaitUntil(cond, Body)"),
    "goto_statement": ("a 'goto'", "call blocks instead"),
    "labeled_statement": ("a label", "call blocks instead"),
    "break_statement": ("a 'break'", "use DoWhile/DoUntil to interrupt a body"),
    "continue_statement": ("a 'continue'", "use RepeatWhile/RepeatUntil"),
    "send_statement": ("a channel send", "missions synchronise through SEQ_ and PAR_ blocks"),
    "block": ("a nested block", "put the statements in a named SEQ_ or PAR_ block and call it"),
}

_CONTROL_SIGNATURES = {
    "If": "If(cond, Then[, Else])",
    "WaitWhile": "WaitWhile(cond, Body)",
    "WaitUntil": "WaitUntil(cond, Body)",
    "RepeatWhile": "RepeatWhile(cond, Body[, Exit])",
    "RepeatUntil": "RepeatUntil(cond, Body[, Exit])",
    "RepeatFor": "RepeatFor(n, Body[, Exit])",
    "PauseWhile": "PauseWhile(cond)",
    "PauseUntil": "PauseUntil(cond)",
    "DoWhile": "DoWhile(cond, Body[, Exit])",
    "DoUntil": "DoUntil(cond, Body[, Exit])",
    "Try": "Try(Body, OnFailure)",
    "Whenever": "Whenever(cond, Handler)",
    "Abandon": "Abandon()",
}


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


class _Reader(LoopReader):
    """Walks one tree-sitter tree, collecting diagnostics instead of stopping."""

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

    def statements_of(self, body: Node) -> tuple[list[Statement], bool]:
        """The statements of a ``{ ... }`` body, and whether none was lost to an error."""
        statements: list[Statement] = []
        complete = True
        for stmt_node in self._statement_nodes(body):
            stmt = self._statement(stmt_node)
            if stmt is not None:
                statements.append(stmt)
            else:
                complete = False
        return statements, complete

    def _statement_nodes(self, body: Node) -> list[Node]:
        out: list[Node] = []
        for child in body.named_children:
            if child.type == "statement_list":
                out.extend(c for c in child.named_children)
            else:
                out.append(child)
        return [c for c in out if c.type not in ("comment", "empty_statement")]

    # -- statements ---------------------------------------------------------

    def _statement(self, node: Node) -> Statement | None:
        if node.type == "ERROR":
            return None
        if node.type == "for_statement":
            return self.for_loop(node)
        if node.type in _UNSUPPORTED_STATEMENTS:
            what, hint = _UNSUPPORTED_STATEMENTS[node.type]
            self.error(node, f"{what} is not supported in missions", hint)
            return None
        if node.type != "expression_statement" or node.named_child_count != 1:
            self.error(
                node,
                "a statement is a block call, a drone action or a control structure",
                "e.g. SEQ_Fly(), Drone1.Takeoff(1.5) or WaitUntil(D1.Z() > 1, SEQ_Go)",
            )
            return None
        call = node.named_children[0]
        if call.type != "call_expression":
            self.error(
                call,
                "a statement is a block call, a drone action or a control structure",
                "e.g. SEQ_Fly(), Drone1.Takeoff(1.5) or WaitUntil(D1.Z() > 1, SEQ_Go)",
            )
            return None
        function = call.child_by_field_name("function")
        args_node = call.child_by_field_name("arguments")
        args = [a for a in args_node.named_children if a.type != "comment"] if args_node else []
        if function is None:
            return None
        if function.type == "identifier":
            name = text(function)
            if name in CONTROL_KINDS:
                return self._control(name, None, call, args)
            if name == "PauseFor":
                # A bare PauseFor(s) is an action without a drone: it runs on the
                # drone of the preceding statement (the ground station at the start).
                return self._action_call(None, name, call, args, function)
            if name in ACTIONS:
                self.error(
                    function,
                    f"'{name}' is an action and needs a drone",
                    f"write Drone1.{name}(...)",
                )
                return None
            return self._block_call(self.qualify(name), call, args, function)
        if function.type == "selector_expression":
            operand = function.child_by_field_name("operand")
            field = function.child_by_field_name("field")
            member: Member | None = None
            if operand is not None and operand.type == "index_expression" and field is not None:
                if self.too_deep(operand, "this index"):
                    return None
                picked = self.pick(operand)  # Team[i].Arm(): a member of a group
                if not isinstance(picked, Member):
                    return None
                member = picked
            elif operand is None or field is None or operand.type != "identifier":
                self.error(
                    function,
                    "an action is called on a drone by name",
                    "e.g. Drone1.Takeoff(1.5), or Team[i].Takeoff(1.5) on a group's member",
                )
                return None
            drone = member.group if member is not None else text(operand)
            action = text(field)
            if drone in self.packages and member is None:
                return self._block_call(f"{drone}.{action}", call, args, function)
            if action in ("PauseWhile", "PauseUntil"):
                return self._control(action, drone, call, args, member)
            if action in CONTROL_KINDS:
                self.error(
                    field,
                    f"{action} is a control structure, not an action of {drone}",
                    f"write {_CONTROL_SIGNATURES[action]}",
                )
                return None
            return self._action_call(drone, action, call, args, field, member)
        self.error(
            function,
            "a statement is a block call, a drone action or a control structure",
            "e.g. SEQ_Fly(), Drone1.Takeoff(1.5)",
        )
        return None

    def _control(
        self,
        kind: str,
        drone: str | None,
        call: Node,
        args: list[Node],
        member: Member | None = None,
    ) -> Control | None:
        sig = _CONTROL_SIGNATURES[kind]
        loc = self.loc(call)
        needs_cond = kind != "RepeatFor"
        min_args, max_args = {
            "If": (2, 3),
            "WaitWhile": (2, 2),
            "WaitUntil": (2, 2),
            "RepeatWhile": (2, 3),
            "RepeatUntil": (2, 3),
            "RepeatFor": (2, 3),
            "PauseWhile": (1, 1),
            "PauseUntil": (1, 1),
            "DoWhile": (2, 3),
            "DoUntil": (2, 3),
            "Try": (2, 2),
            "Whenever": (2, 2),
            "Abandon": (0, 0),
        }[kind]
        if not (min_args <= len(args) <= max_args):
            self.diags.append(
                Diagnostic(
                    "error",
                    loc,
                    f"{kind} takes {_count(min_args, max_args)}, got {len(args)}",
                    f"write {sig}",
                    self.end_col(call),
                )
            )
            return None
        if kind == "Try":
            # No condition: both arguments are blocks (Body, then OnFailure).
            refs = self.control_refs(kind, sig, args)
            if refs is None:
                return None
            return Control("Try", loc, body=refs[0], exit=refs[1])
        if kind == "Abandon":
            return Control("Abandon", loc)
        cond: Expr | None = None
        count: int | None = None
        count_expr: Expr | None = None
        if self.too_deep(args[0], "this condition" if needs_cond else "this count"):
            return None
        if needs_cond:
            cond = self.expr(args[0])
            if cond is None:
                return None
        elif _reads_names(args[0]):
            count_expr = self.const_expr(args[0])
            if count_expr is None:
                return None
        else:
            value = self.number(args[0])
            if value is None:
                return None
            if value != int(value) or not 0 <= value <= MAX_REPEAT:
                self.error(
                    args[0],
                    f"RepeatFor repeats a whole number of times, 0 to {MAX_REPEAT}",
                    "e.g. RepeatFor(3, SEQ_Body)",
                )
                return None
            count = int(value)
        refs = self.control_refs(kind, sig, args[1:])
        if refs is None:
            return None
        body = refs[0] if refs else None
        rest = refs[1] if len(refs) > 1 else None
        if kind == "If":
            return Control("If", loc, cond=cond, body=body, orelse=rest)  # type: ignore[arg-type]
        return Control(
            kind,  # type: ignore[arg-type]
            loc,
            cond=cond,
            count=count,
            body=body,
            exit=rest,
            drone=drone,
            count_expr=count_expr,
            pick=member,
        )


def _reads_names(node: Node) -> bool:
    """True if an argument's text names something (a parameter), not only numbers."""
    stack = [node]
    while stack:
        current = stack.pop()
        if current.type == "identifier":
            return True
        stack.extend(current.named_children)
    return False


def _count(lo: int, hi: int) -> str:
    plural = "s" if hi != 1 else ""
    return f"{lo} argument{plural}" if lo == hi else f"{lo} or {hi} arguments"


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
    tree = _go_parser().parse(encoded)
    reader = _Reader(source, source_text, file, package)
    reader.syntax_errors(tree.root_node)
    reader.long_names(tree.root_node)
    syntax_broken = any(d.severity == "error" for d in reader.diags)
    mission = reader.mission(tree.root_node)
    errors = [d for d in reader.diags if d.severity == "error"]
    if errors:
        exc = MissionError(reader.diags)
        exc.partial = mission
        exc.fatal = syntax_broken or not mission.entry
        raise exc
    return mission, [d for d in reader.diags if d.severity == "warning"]


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
