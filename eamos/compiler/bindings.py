"""What names stand for while a block copy or a loop iteration is expanded.

A :class:`Binding` maps a block's parameters and the variables of the loops
around a statement to values: a drone's name, a number (an ``int`` for loop
counters and ``int`` parameters, a ``float`` otherwise) or a group (its
members' names).  The functions here turn what a statement names into what the
expanded mission holds: ``Team[i + 1]`` into ``Team_4``, ``Team[0:10]`` into
ten members, a condition with loop variables and group conditions into a
condition over drones only.  Problems are :class:`~.constants.FoldError`\\ s,
located where the mission writes the offending part.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from .constants import FoldError, Value, fold_value
from .limits import MAX_EXPRESSION_DEPTH
from .syntax import (
    Binary,
    Bool,
    Expr,
    GroupDecl,
    Len,
    Member,
    Name,
    Num,
    Prop,
    Quantifier,
    Slice,
    Unary,
    expr_text,
    member_name,
    props_in,
    sub_expressions,
)


@dataclass(frozen=True)
class Group:
    """A group as a binding holds it: members ``start`` .. of the declared group ``name``."""

    members: tuple[str, ...]
    name: str
    start: int = 0
    size: int = 0  # the declared group's

    @staticmethod
    def declared(decl: GroupDecl) -> Group:
        members = tuple(member_name(decl.name, i) for i in range(decl.size))
        return Group(members, decl.name, 0, decl.size)

    @property
    def shown(self) -> str:
        """How copies' names and labels show it: ``Team``, or a part, ``Team[2:5]``."""
        if self.start == 0 and len(self.members) == self.size:
            return self.name
        return f"{self.name}[{self.start}:{self.start + len(self.members)}]"

    def part(self, low: int, high: int) -> Group:
        """Its members ``low`` .. ``high - 1`` (Go's slice)."""
        return Group(self.members[low:high], self.name, self.start + low, self.size)


@dataclass(frozen=True)
class Binding:
    """What the names in scope stand for, and where the expansion is (for messages)."""

    drones: dict[str, str] = field(default_factory=dict)
    numbers: dict[str, Value] = field(default_factory=dict)
    groups: dict[str, Group] = field(default_factory=dict)
    copy: str = ""  # the block copy being written, ``SEQ_Hop(D1, 5)``
    iterations: tuple[str, ...] = ()  # ``i=3`` per enclosing loop, outermost first

    def where(self) -> str:
        """``in SEQ_Hop(D1, 5), iteration i=3``: the hint of an error found here."""
        parts = [self.copy] if self.copy else []
        if self.iterations:
            parts.append("iteration " + ", ".join(self.iterations))
        return "in " + ", ".join(parts) if parts else ""

    def inside(self, label: str, numbers: dict[str, Value], drones: dict[str, str]) -> Binding:
        """This binding inside one iteration of a loop."""
        return dataclasses.replace(
            self,
            numbers={**self.numbers, **numbers},
            drones={**self.drones, **drones},
            iterations=(*self.iterations, label),
        )


class Resolver:
    """Groups, members and conditions of one binding, against the mission's groups."""

    def __init__(self, groups: dict[str, GroupDecl], binding: Binding) -> None:
        self.declared = groups
        self.b = binding

    # -- numbers and groups ----------------------------------------------------------

    def size(self, ref: Name | Slice) -> int:
        return len(self.group(ref).members)

    def number(self, expr: Expr) -> Value:
        """A number: every name, ``len`` and arithmetic folded (raises FoldError)."""
        return fold_value(expr, self.b.numbers, self.size)

    def whole(self, expr: Expr, what: str) -> int:
        """A whole number (an index, a bound); a decimal like 1.5 is an error."""
        value = self.number(expr)
        if isinstance(value, float):
            if not value.is_integer():
                raise FoldError(f"{what} is a whole number, got {value:g}", expr.loc)
            value = int(value)
        return value

    def group(self, ref: Name | Slice) -> Group:
        """The group ``Team``, ``g`` or ``Team[a:b]`` names here."""
        name = ref.group if isinstance(ref, Slice) else ref.name
        whole = self.b.groups.get(name)
        if whole is None:
            decl = self.declared.get(name)
            if decl is None:  # pragma: no cover - the checks refuse an unknown group
                raise FoldError(f"'{name}' is not a group here", ref.loc)
            whole = Group.declared(decl)
        if not isinstance(ref, Slice):
            return whole
        size = len(whole.members)
        low = 0 if ref.low is None else self.whole(ref.low, "a bound")
        high = size if ref.high is None else self.whole(ref.high, "a bound")
        if not 0 <= low <= high <= size:
            raise FoldError(
                f"{name}[{low}:{high}] is not a part of {name}, whose members are "
                f"{name}[0] .. {name}[{size - 1}]",
                ref.loc,
            )
        return whole.part(low, high)

    def member(self, pick: Member) -> str:
        """The drone name of ``Team[i]`` (raises FoldError out of range)."""
        group = self.group(Name(pick.group, pick.loc))
        index = self.whole(pick.index, "an index")
        if not 0 <= index < len(group.members):
            raise FoldError(
                f"index {index} is outside {pick.group}, whose members are {pick.group}[0] .. "
                f"{pick.group}[{len(group.members) - 1}]",
                pick.loc,
            )
        return group.members[index]

    def drone(self, name: str, pick: Member | None) -> str:
        """The drone a statement names: a member, a bound parameter, or itself."""
        if pick is not None:
            return self.member(pick)
        return self.b.drones.get(name, name)

    # -- conditions --------------------------------------------------------------------

    def condition(self, expr: Expr) -> tuple[Expr, str]:
        """The runtime condition (drones and numbers only), and its text for labels if it
        has group conditions (else ""), or raises FoldError."""
        bound = self._bind(expr, None, compact=False)
        if _depth(bound) > MAX_EXPRESSION_DEPTH:
            raise FoldError(
                f"this condition nests operators more than {MAX_EXPRESSION_DEPTH} deep once "
                "its group conditions are written out",
                expr.loc,
            )
        if not _has_quantifier(expr):
            return bound, ""
        return bound, expr_text(self._bind(expr, None, compact=True))

    def _typed(self, expr: Expr) -> bool:
        """True if a property-free part must be folded here: it computes with whole numbers
        (a loop counter, an int parameter, len, %), whose rules the runtime does not have."""
        if _reads_props(expr):
            return False
        return any(
            isinstance(node, Len)
            or (isinstance(node, Binary) and node.op == "%")
            or (isinstance(node, Name) and isinstance(self.b.numbers.get(node.name), int))
            for node in sub_expressions(expr)
        )

    def _bind(self, expr: Expr, each: tuple[str, str] | None, *, compact: bool) -> Expr:
        """``expr`` with its names replaced; ``each`` = (group, member) inside ``All(...)``."""
        if self._typed(expr):
            return Num(float(self.number(expr)), expr.loc)
        if isinstance(expr, Name):
            return Num(float(self.b.numbers.get(expr.name, 0.0)), expr.loc)
        if isinstance(expr, Len):
            return Num(float(self.size(expr.group)), expr.loc)
        if isinstance(expr, Prop):
            return self._prop(expr, each)
        if isinstance(expr, Unary):
            return dataclasses.replace(
                expr, operand=self._bind(expr.operand, each, compact=compact)
            )
        if isinstance(expr, Binary):
            return dataclasses.replace(
                expr,
                left=self._bind(expr.left, each, compact=compact),
                right=self._bind(expr.right, each, compact=compact),
            )
        if isinstance(expr, Quantifier):
            return self._quantifier(expr, compact=compact)
        return expr

    def _group_read(self, prop: Prop) -> Name | Slice | None:
        """The group a property read inside a group condition reads, if it reads one."""
        if isinstance(prop.pick, Slice):
            return prop.pick
        named = prop.drone in self.b.groups or prop.drone in self.declared
        if prop.pick is None and prop.drone not in self.b.drones and named:
            return Name(prop.drone, prop.loc)
        return None

    def _prop(self, prop: Prop, each: tuple[str, str] | None) -> Prop:
        if each is not None and self._group_read(prop) is not None:
            return Prop(each[1], prop.name, prop.loc)
        if isinstance(prop.pick, Member):
            return Prop(self.member(prop.pick), prop.name, prop.loc)
        return Prop(self.b.drones.get(prop.drone, prop.drone), prop.name, prop.loc)

    def _quantifier(self, expr: Quantifier, *, compact: bool) -> Expr:
        ref = next(r for p in props_in(expr.cond) if (r := self._group_read(p)) is not None)
        group = self.group(ref)
        name = ref.group if isinstance(ref, Slice) else ref.name
        if compact:
            inner = self._bind(expr.cond, (name, group.shown), compact=True)
            return Quantifier(expr.kind, inner, expr.loc)
        if not group.members:
            # All of nobody holds, Any of nobody does not, and nobody counts zero.
            if expr.kind == "Count":
                return Num(0.0, expr.loc, True)
            return Bool(expr.kind == "All", expr.loc)
        terms = [self._bind(expr.cond, (name, m), compact=False) for m in group.members]
        op = {"All": "&&", "Any": "||", "Count": "+"}[expr.kind]
        return _balanced(op, terms, expr)


def _balanced(op: str, terms: list[Expr], at: Quantifier) -> Expr:
    """``a op b op c ...`` as a balanced tree: n terms nest about log2(n) deep, not n."""
    level = terms
    while len(level) > 1:
        paired: list[Expr] = [
            Binary(op, level[i], level[i + 1], at.loc) for i in range(0, len(level) - 1, 2)
        ]
        if len(level) % 2:
            paired.append(level[-1])
        level = paired
    return level[0]


def _reads_props(expr: Expr) -> bool:
    return any(True for _ in props_in(expr))


def _has_quantifier(expr: Expr) -> bool:
    return any(isinstance(node, Quantifier) for node in sub_expressions(expr))


def _depth(expr: Expr) -> int:
    """Operators nested in a bound condition (as the runtime counts them)."""
    best = 0
    stack: list[tuple[Expr, int]] = [(expr, 0)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, Unary):
            stack.append((node.operand, depth + 1))
        elif isinstance(node, Binary):
            stack.extend(((node.left, depth + 1), (node.right, depth + 1)))
        best = max(best, depth)
    return best
