"""Reading a file's declarations (imports, drone types, parameters) and call arguments.

The part of the parser's reader (:mod:`.parse`) for what the language added
to the paper's: ``import "name"``, ``type Name interface { ... }`` drone types
and parameters ``(d Quadcopter, dist_m float64)``.  A library's blocks and
types are named ``package.Name`` from the start, so names from different
files never mix.
"""

from __future__ import annotations

from ..program.uniform import DRONE_TYPES
from .constants import FoldError, fold, is_constant
from .errors import Diagnostic, SourceLocation
from .parse_conditions import ConditionReader
from .parse_expressions import Node, text
from .source import SourceText
from .syntax import (
    GROUP_PREFIX,
    NUMBER_TYPES,
    ActionCall,
    BlockCall,
    BlockRef,
    Expr,
    Import,
    Member,
    MethodDecl,
    Param,
    TypeDecl,
)


class DeclarationReader(ConditionReader):
    """Imports, drone types, parameters and the arguments of calls, in one file."""

    def __init__(self, source_text: SourceText, file: str = "", package: str = "") -> None:
        super().__init__(source_text, file)
        # A library's blocks and types are named ``package.Name``; a mission's keep their names.
        self.prefix = f"{package}." if package else ""
        self.packages: set[str] = set()  # the package names this file imports

    def qualify(self, name: str) -> str:
        """The full name of a block this file names without a package."""
        return self.prefix + name

    def type_name(self, node: Node) -> str | None:
        """A drone or parameter type: ``Quadcopter``, ``float64``, ``int``, ``Inspector``,
        ``lib.T``, or a group of one, ``[]Flyer``."""
        if node.type == "type_identifier":
            name = text(node)
            if name in NUMBER_TYPES or name in DRONE_TYPES:
                return name
            return self.qualify(name)
        if node.type == "slice_type":
            element = node.child_by_field_name("element")
            inner = self.type_name(element) if element is not None else None
            if inner is None:
                return None
            if inner in NUMBER_TYPES or inner.startswith(GROUP_PREFIX):
                self.error(node, "a group parameter is a group of drones", "e.g. g []Quadcopter")
                return None
            return GROUP_PREFIX + inner
        if node.type == "qualified_type":
            package = node.child_by_field_name("package")
            name = node.child_by_field_name("name")
            if package is not None and name is not None:
                if text(package) not in self.packages:
                    self.error(
                        package,
                        f"'{text(package)}' is not an imported library",
                        f'import it: import "{text(package)}"',
                    )
                    return None
                return f"{text(package)}.{text(name)}"
        self.error(
            node,
            "a type is a plain name, or a group's: []Name",
            "e.g. Quadcopter, float64, int, lib.Inspector, or []Quadcopter for a group",
        )
        return None

    def _imports(self, root: Node) -> list[Import]:
        """Every ``import "path"`` of the file (read first: calls name the packages)."""
        out: list[Import] = []
        for node in root.named_children:
            if node.type != "import_declaration":
                continue
            specs = [c for c in node.named_children if c.type == "import_spec"]
            for group in (c for c in node.named_children if c.type == "import_spec_list"):
                specs.extend(c for c in group.named_children if c.type == "import_spec")
            for spec in specs:
                path_node = spec.child_by_field_name("path")
                if spec.child_by_field_name("name") is not None:
                    self.error(
                        spec,
                        "an import cannot rename its library",
                        'write import "name" and call its blocks as name.SEQ_Block(...)',
                    )
                    continue
                if path_node is None or path_node.type != "interpreted_string_literal":
                    self.error(spec, "an import names a library folder", 'write import "name"')
                    continue
                path = text(path_node)[1:-1]
                out.append(Import(path, self.loc(path_node)))
                self.packages.add(path.rsplit("/", 1)[-1])
        return out

    def _types(self, node: Node) -> list[TypeDecl]:
        """``type Name interface { Embedded; Action(param float64) }`` declarations."""
        specs = [c for c in node.named_children if c.type in ("type_spec", "type_alias")]
        out: list[TypeDecl] = []
        for spec in specs:
            name_node = spec.child_by_field_name("name")
            body = spec.child_by_field_name("type")
            hint = "declare a drone type: type Inspector interface { Quadcopter; TakePhoto() }"
            if spec.type != "type_spec" or name_node is None or body is None:
                self.error(spec, "a type declaration declares a drone type", hint)
                continue
            if body.type != "interface_type" or spec.child_by_field_name("type_parameters"):
                self.error(body, "a drone type is an interface of actions", hint)
                continue
            embeds: list[tuple[str, SourceLocation]] = []
            methods: list[MethodDecl] = []
            for elem in body.named_children:
                if elem.type == "comment":
                    continue
                if elem.type == "method_elem":
                    method = self._method(elem)
                    if method is not None:
                        methods.append(method)
                    continue
                inner = elem.named_children[0] if elem.type == "type_elem" else elem
                if elem.type == "type_elem" and elem.named_child_count == 1:
                    named = self.type_name(inner)
                    if named is not None:
                        embeds.append((named, self.loc(inner)))
                    continue
                self.error(elem, "a drone type lists drone types and actions", hint)
            out.append(
                TypeDecl(
                    self.qualify(text(name_node)),
                    tuple(embeds),
                    tuple(methods),
                    self.loc(name_node),
                )
            )
        return out

    def _method(self, elem: Node) -> MethodDecl | None:
        name_node = elem.child_by_field_name("name")
        if name_node is None:
            return None
        if elem.child_by_field_name("result") is not None:
            self.error(
                elem.child_by_field_name("result"),
                f"action '{text(name_node)}' returns nothing",
                "remove the result type",
            )
            return None
        params = self._params(elem.child_by_field_name("parameters"), text(name_node))
        if params is None:
            return None
        for param in params:
            if param.type != "float64":
                self.diags.append(
                    Diagnostic(
                        "error",
                        param.type_loc or param.loc,
                        f"an action's parameters are numbers: {param.name} float64",
                        "name the unit in the parameter, e.g. pitch_deg float64",
                    )
                )
                return None
        return MethodDecl(text(name_node), params, self.loc(name_node))

    def _params(self, node: Node | None, owner: str) -> tuple[Param, ...] | None:
        """The parameters of a block or an action, or None (reported)."""
        out: list[Param] = []
        if node is None:
            return ()
        for decl in node.named_children:
            if decl.type == "comment":
                continue
            type_node = decl.child_by_field_name("type")
            names = list(decl.children_by_field_name("name"))
            if decl.type != "parameter_declaration" or type_node is None:
                self.error(decl, f"'{owner}' has a parameter this language does not have")
                return None
            if not names:
                self.error(
                    decl,
                    "a parameter needs a name",
                    "e.g. dist_m float64 or d Quadcopter",
                )
                return None
            kind = self.type_name(type_node)
            if kind is None:
                return None
            for name in names:
                if any(p.name == text(name) for p in out):
                    self.error(name, f"parameter '{text(name)}' is declared twice")
                    return None
                out.append(Param(text(name), kind, self.loc(name), self.loc(type_node)))
        return tuple(out)

    # -- arguments ------------------------------------------------------------

    def _arguments(self, args: list[Node]) -> tuple[list[Expr], list[SourceLocation]] | None:
        """Constant-expression arguments and their locations (every bad one is reported)."""
        exprs: list[Expr] = []
        locs: list[SourceLocation] = []
        ok = True
        for arg in args:
            if self.too_deep(arg, "this argument"):
                ok = False
                continue
            expr = self.const_expr(arg)
            if expr is None:
                ok = False
                continue
            exprs.append(expr)
            locs.append(self.loc(arg))
        return (exprs, locs) if ok else None

    def _block_call(
        self, name: str, call: Node, args: list[Node], function: Node
    ) -> BlockCall | None:
        read = self._arguments(args)
        if read is None:
            return None
        return BlockCall(name, self.loc(function), tuple(read[0]))

    def _action_call(
        self,
        drone: str | None,
        action: str,
        call: Node,
        args: list[Node],
        name_node: Node,
        member: Member | None = None,
    ) -> ActionCall | None:
        """An action whose arguments are constant expressions, folded here if they can be."""
        read = self._arguments(args)
        if read is None:
            return None
        exprs, locs = read
        values: list[float] = []
        for expr, arg in zip(exprs, args, strict=True):
            if not is_constant(expr):
                # Reads a block parameter or a loop variable: folded when it is expanded.
                return ActionCall(
                    drone,
                    action,
                    (),
                    self.loc(call),
                    tuple(locs),
                    self.loc(name_node),
                    tuple(exprs),
                    member,
                )
            try:
                values.append(fold(expr, {}))
            except FoldError as exc:
                hint = (
                    "% gives the remainder of whole numbers: loop counters, int parameters, "
                    "len(...) and numbers written without a point"
                    if "%" in str(exc)
                    else "numbers must be finite; see the limits in docs"
                )
                self.error(arg, str(exc), hint)
                return None
        return ActionCall(
            drone,
            action,
            tuple(values),
            self.loc(call),
            tuple(locs),
            self.loc(name_node),
            pick=member,
        )

    def control_refs(self, kind: str, sig: str, args: list[Node]) -> list[BlockRef] | None:
        """The blocks a control structure names (Body, Then, Else, Exit), or None (reported).

        A block with parameters is named with its arguments: ``SEQ_Leg(d, 5)``.
        """
        refs: list[BlockRef] = []
        for arg in args:
            if arg.type == "identifier":
                refs.append(BlockRef(self.qualify(text(arg)), self.loc(arg)))
            elif (
                arg.type == "selector_expression"
                and text(arg.child_by_field_name("operand")) in self.packages
            ):
                refs.append(BlockRef(text(arg), self.loc(arg)))
            elif arg.type == "call_expression":
                fn = arg.child_by_field_name("function")
                name = text(fn) if fn is not None else "?"
                call_args = arg.child_by_field_name("arguments")
                given = (
                    [a for a in call_args.named_children if a.type != "comment"]
                    if call_args
                    else []
                )
                package = name.split(".")[0] if "." in name else None
                if package is not None and package not in self.packages:
                    self.error(arg, f"{kind} expects a block here", f"write {sig}")
                    return None
                if not given or fn is None:
                    self.error(
                        arg,
                        f"name the block without calling it: {name}, not {name}()",
                        f"write {sig}",
                    )
                    return None
                # A block with parameters, named with its arguments: SEQ_Leg(d, 5).
                ref = self._block_call(name if "." in name else self.qualify(name), arg, given, fn)
                if ref is None:
                    return None
                refs.append(BlockRef(ref.name, ref.loc, ref.args))
            else:
                self.error(arg, f"{kind} expects a block name here", f"write {sig}")
                return None
        return refs
