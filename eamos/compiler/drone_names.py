"""A drone name one typing mistake away from another: a warning with a hint.

A drone needs no declaration: a name used as ``Dron1.FlyByX(1)`` is a drone of the
default type (the paper's listings declare none, :func:`~.check.drone_types`).  So
a misspelt name silently becomes a new drone, standing at its own home, and only
the pre-flight check notices (a separation or termination finding, far from the
cause).  The compiler warns instead, at the misspelt name's first use: ``drone
'Dron1' is not declared and is one letter away from 'Drone1'`` with the hint
``did you mean Drone1?``.

"One letter away" is one insertion, deletion, substitution or swap of two
neighbouring characters, of anything but digits: ``D1``, ``D2``, ``D3`` and
``Drone1`` ... ``Drone12`` are a fleet, not typing mistakes.  Of two such names the
one taken for the mistake is undeclared and the less used (a declared name is
never one; of two declared names, neither).  Pure: a function of the parsed mission.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator

from .errors import Diagnostic, SourceLocation
from .syntax import ActionCall, Binary, BlockCall, Control, Expr, Mission, Name, Prop, Unary


def one_edit_apart(a: str, b: str) -> bool:
    """True when ``a`` and ``b`` differ by one edit of a character that is not a digit.

    An edit is an insertion, a deletion, a substitution or a swap of two neighbours
    (``Dron1``/``Drone1``, ``Drome1``/``Drone1``, ``Dorne1``/``Drone1``, ``drone1``/``Drone1``);
    a substitution of a digit by a digit, or a digit inserted, is not (``D1``/``D2``,
    ``Drone1``/``Drone12``).
    """
    if a == b or abs(len(a) - len(b)) > 1:
        return False
    if len(a) > len(b):
        a, b = b, a
    start = 0
    while start < len(a) and a[start] == b[start]:
        start += 1
    if len(a) < len(b):  # one character of b inserted at ``start``
        return a[start:] == b[start + 1 :] and not b[start].isdigit()
    x, y = a[start], b[start]
    if a[start + 1 :] == b[start + 1 :]:  # one substitution
        return not (x.isdigit() and y.isdigit())
    # A swap of two neighbours: ab -> ba, the rest the same.
    return (
        start + 1 < len(a)
        and a[start + 1] == y
        and b[start + 1] == x
        and a[start + 2 :] == b[start + 2 :]
        and not (x.isdigit() and y.isdigit())
    )


def _neighbours(names: list[str]) -> dict[str, set[str]]:
    """For each name, the others that may be one edit from it (a superset, in linear time).

    Two names one insertion, deletion, substitution or swap apart have a common string
    among each one and its copies with one character deleted; grouping by those
    strings finds the candidates without comparing every pair (a mission may have
    thousands of drones).
    """
    groups: dict[str, list[str]] = {}
    for name in names:
        keys = {name} | {name[:i] + name[i + 1 :] for i in range(len(name))}
        for key in keys:
            groups.setdefault(key, []).append(name)
    near: dict[str, set[str]] = {}
    for members in groups.values():
        if len(members) > 1:
            for name in members:
                near.setdefault(name, set()).update(m for m in members if m != name)
    return near


def _props(expr: Expr | None) -> Iterator[Prop]:
    if isinstance(expr, Prop):
        yield expr
    elif isinstance(expr, Unary):
        yield from _props(expr.operand)
    elif isinstance(expr, Binary):
        yield from _props(expr.left)
        yield from _props(expr.right)


def drone_uses(mission: Mission) -> list[tuple[str, SourceLocation]]:
    """Every use of a drone by name (not a block's drone parameter), in source order per block.

    Actions (``Drone1.Land()``), conditions (``Drone1.X() > 2``), a drone's own
    wait (``Drone1.PauseWhile(...)``) and drones passed to a block's parameters.
    """
    uses: list[tuple[str, SourceLocation]] = []
    for block in mission.blocks.values():
        found: list[tuple[str, SourceLocation]] = []
        for stmt in block.statements:
            if isinstance(stmt, ActionCall) and stmt.drone is not None:
                found.append((stmt.drone, stmt.loc))
            elif isinstance(stmt, Control):
                if stmt.drone is not None:
                    found.append((stmt.drone, stmt.loc))
                found.extend((p.drone, p.loc) for p in _props(stmt.cond))
                refs = (stmt.body, stmt.orelse, stmt.exit)
                args = [a for ref in refs if ref is not None for a in ref.args]
                found.extend((a.name, a.loc) for a in args if isinstance(a, Name))
            elif isinstance(stmt, BlockCall):
                found.extend((a.name, a.loc) for a in stmt.args if isinstance(a, Name))
        # The block's own parameters (drones or numbers passed on by name) are not drones.
        params = {p.name for p in block.params}
        uses.extend((name, loc) for name, loc in found if name not in params)
    return uses


def misspelt_drones(mission: Mission) -> list[Diagnostic]:
    """A warning at the first use of each drone name one edit away from another (module doc)."""
    uses = drone_uses(mission)
    count = Counter(name for name, _ in uses)
    first: dict[str, SourceLocation] = {}
    for name, loc in uses:
        first.setdefault(name, loc)
    declared = set(mission.drones)
    names = sorted(declared | set(count))
    near = _neighbours(names)
    out: list[Diagnostic] = []
    for name in names:
        if name in declared or name not in first:
            continue
        # The names it may be a mistake for: declared ones, or used more often.
        likelier = [
            other
            for other in near.get(name, ())
            if one_edit_apart(name, other) and (other in declared or count[other] > count[name])
        ]
        if not likelier:
            continue
        best = min(likelier, key=lambda o: (o not in declared, -count[o], o))
        how = "declared" if best in declared else f"used {count[best]} times"
        out.append(
            Diagnostic(
                "warning",
                first[name],
                f"drone '{name}' is not declared and is one letter away from '{best}' ({how}): "
                f"it is a drone of its own",
                f"did you mean {best}?",
            )
        )
    return out


__all__ = ["drone_uses", "misspelt_drones", "one_edit_apart"]
