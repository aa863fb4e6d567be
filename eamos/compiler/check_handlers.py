"""Checks of the event-handler structures: where ``Whenever`` and ``Abandon()`` may stand.

* ``Whenever(cond, Handler)`` guards the statements after it in a ``SEQ_``
  block: in a ``PAR_`` block (no "after") or as the last statement (nothing
  to guard) it is an error.
* ``Abandon()`` only means something inside a Whenever's Handler (directly or
  in a block the Handler runs): a block that also runs outside any Handler
  may not contain it.

Pure, on the parsed mission; every finding is a located :class:`Diagnostic`.
"""

from __future__ import annotations

from collections.abc import Iterator

from .errors import Diagnostic
from .syntax import BlockCall, BlockRef, Control, Mission, flat_statements


def _refs(stmt: object, handlers: bool) -> Iterator[BlockRef | BlockCall]:
    """Blocks a statement runs: the Handler of a Whenever only when ``handlers``."""
    if isinstance(stmt, BlockCall):
        yield stmt
    elif isinstance(stmt, Control):
        if stmt.kind == "Whenever":
            if handlers and stmt.body is not None:
                yield stmt.body
            return
        for ref in (stmt.body, stmt.orelse, stmt.exit):
            if ref is not None:
                yield ref


def _outside_handlers(mission: Mission) -> set[str]:
    """Blocks the mission runs on a path that enters no Whenever Handler."""
    seen: set[str] = set()
    stack = [mission.entry]
    while stack:
        name = stack.pop()
        if name in seen or name not in mission.blocks:
            continue
        seen.add(name)
        for stmt in flat_statements(mission.blocks[name].statements):
            stack.extend(ref.name for ref in _refs(stmt, handlers=False))
    return seen


def handler_errors(mission: Mission) -> list[Diagnostic]:
    """Every misplaced ``Whenever`` or ``Abandon()`` of the mission."""
    out: list[Diagnostic] = []
    outside = _outside_handlers(mission) if mission.entry else set()
    for name, block in mission.blocks.items():
        top = set(map(id, block.statements))  # a Whenever in a loop is the loop checks' concern
        for stmt in flat_statements(block.statements):
            if not isinstance(stmt, Control):
                continue
            index = block.statements.index(stmt) if id(stmt) in top else -1
            if stmt.kind == "Whenever" and index < 0:
                continue
            if stmt.kind == "Whenever" and block.mode == "PAR":
                out.append(
                    Diagnostic(
                        "error",
                        stmt.loc,
                        "Whenever in a PAR_ block: it guards the statements after it in a "
                        "SEQ_ block",
                        f"call a SEQ_ block from {name} that starts with the Whenever",
                        stmt.loc.col + len("Whenever"),
                    )
                )
            elif stmt.kind == "Whenever" and index == len(block.statements) - 1:
                out.append(
                    Diagnostic(
                        "error",
                        stmt.loc,
                        f"Whenever is the last statement of {name}: it guards nothing",
                        "it guards the statements after it in its block: put it before them",
                        stmt.loc.col + len("Whenever"),
                    )
                )
            elif stmt.kind == "Abandon" and name in outside:
                out.append(
                    Diagnostic(
                        "error",
                        stmt.loc,
                        f"Abandon() outside a Whenever handler ({name} runs outside one)",
                        "Abandon() goes in the Handler block of Whenever(cond, Handler); "
                        "to stop a Body on a condition use DoWhile/DoUntil",
                        stmt.loc.col + len("Abandon"),
                    )
                )
    return out
