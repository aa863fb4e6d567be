"""Which way the conditions the simulation cannot know go: choice points and branch labels.

A condition is *unknowable* when it reads a battery's charge (the real charge
at take-off is not the model's) or a property of a drone flown by a person
(the scripted pilot is one possible flight, not the flight).  Every decision
of such a condition, the first time a node decides for an activation (and for
a loop, for an iteration), is a choice point with two options:

* 0, as simulated: the value the virtual run computed;
* 1, the other way: an ``If`` takes the other branch; a ``Wait``/``Pause`` ends
  at once ("early"; "late" is the simulated end); a ``Repeat`` stops before
  this iteration; a ``Do`` skips its Body; a ``Whenever`` whose condition is
  false at its first decision fires its Handler at once.  A decision that
  already ends the wait, loop or Do has no other way.

Each ``Try`` (per activation) has a choice point too, whatever its Body reads:
0 as simulated, 1 the first action of Body to start fails
(:meth:`Oracle.fail`), so OnFailure is checked as well.

:class:`Oracle` answers the virtual driver's ``decide`` hook from a list of
choices (the *prefix*; beyond it, as simulated) and records every choice point
it met, so the explorer can queue each alternative as a new run.
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from dataclasses import dataclass
from pathlib import PurePath

from ..actors.logic import ActionLogic, ConditionLogic, LoopLogic
from ..actors.state import Iteration, holds
from ..program.conditions import properties

#: Properties whose real value a simulation cannot know.
UNKNOWABLE_PROPERTIES = frozenset({"Battery"})
#: Node kinds as written in a mission.
_NAMES = {
    "if": "If",
    "wait_while": "WaitWhile",
    "wait_until": "WaitUntil",
    "pause_while": "PauseWhile",
    "pause_until": "PauseUntil",
    "repeat_while": "RepeatWhile",
    "repeat_until": "RepeatUntil",
    "do_while": "DoWhile",
    "do_until": "DoUntil",
    "try": "Try",
    "whenever": "Whenever",
}
#: The purposes a choice point is made of (watching a running Body is left as simulated).
_PURPOSES = frozenset({"if", "wait", "loop", "do", "whenever"})


@dataclass(frozen=True)
class ChoicePoint:
    """One decision of an unknowable condition, and which way this run took it."""

    drone: str
    node: str
    kind: str
    line: int
    col: int
    purpose: str
    count: int  # a loop's iteration (0 otherwise)
    choice: int  # 0 as simulated, 1 the other way
    value: bool  # the condition's value used
    file: str = ""  # the library file the decision is written in ("": the mission file)

    def label(self) -> str:
        """Short words for the branch: ``If line 12: else``, ``WaitUntil line 30: early``;
        ``If line 4 of insp.go: then`` for a decision written in a library file."""
        of = f" of {PurePath(self.file).name}" if self.file else ""
        where = f"{_NAMES.get(self.kind, self.kind)} line {self.line}{of}"
        if self.purpose == "if":
            return f"{where}: {'then' if self.value else 'else'}"
        if self.choice == 0:
            return f"{where}: as simulated"
        if self.purpose == "wait":
            return f"{where}: wait ends at once"
        if self.purpose == "loop":
            return f"{where}: loop stops before iteration {self.count + 1}"
        if self.purpose == "whenever":
            return f"{where}: Handler fires at once"
        if self.purpose == "try":
            return f"{where}: Body fails at its first action ({self.drone})"
        return f"{where}: Do body skipped"


def unknowable(
    logic: ConditionLogic, piloted: Collection[str], props: Collection[str] = UNKNOWABLE_PROPERTIES
) -> bool:
    """True when the node's condition reads a property the simulation cannot know."""
    return any(d in piloted or p in props for d, p in properties(logic.spec.cond))


def other_way(kind: str, purpose: str, value: bool) -> bool | None:
    """The value taking a decision the other way, or None if there is none (see module doc)."""
    if purpose == "if":
        return not value
    if purpose in ("wait", "loop", "do") and holds(kind, value):
        return not value  # it would wait / iterate / run Body: end it now instead
    if purpose == "whenever" and not value:
        return True  # its Handler fires at once (a real battery may already be low)
    return None


class Oracle:
    """The driver's ``decide`` hook for one explored run (see module doc)."""

    def __init__(
        self,
        prefix: tuple[int, ...],
        piloted: Collection[str],
        file_of: Callable[[str, str], str] = lambda drone, key: "",
    ) -> None:
        """``file_of(drone, node key)``: the library file a node is written in ("": none)."""
        self.prefix = prefix
        self.piloted = frozenset(piloted)
        self.file_of = file_of
        self.points: list[ChoicePoint] = []
        self._seen: set[tuple[str, str, Iteration, str, int]] = set()
        self._unknowable: dict[tuple[str, str], bool] = {}
        self._tries: set[tuple[int, Iteration]] = set()

    def __call__(
        self, drone: str, logic: ConditionLogic, act: Iteration, purpose: str, value: bool
    ) -> bool:
        """The value the node uses for this decision."""
        spec = logic.spec
        if purpose not in _PURPOSES:
            return value
        known = self._unknowable.get((drone, spec.key))
        if known is None:
            known = self._unknowable[(drone, spec.key)] = unknowable(logic, self.piloted)
        if not known:
            return value
        count = 0
        if isinstance(logic, LoopLogic) and act in logic.loops:
            count = logic.loops[act].counter
        seen = (drone, spec.key, act, purpose, count)
        if seen in self._seen:
            return value
        self._seen.add(seen)
        alt = other_way(spec.kind, purpose, value)
        if alt is None:
            return value
        i = len(self.points)
        choice = self.prefix[i] if i < len(self.prefix) else 0
        used = alt if choice else value
        self.points.append(
            ChoicePoint(
                drone,
                spec.key,
                spec.kind,
                spec.line,
                spec.col,
                purpose,
                count,
                choice,
                used,
                self.file_of(drone, spec.key),
            )
        )
        return used

    def fail(self, drone: str, logic: ActionLogic, act: Iteration) -> bool:
        """Whether this action of a Try's Body fails: a choice point at each Try's first action.

        0: as simulated; 1: it fails (so the check also runs OnFailure).  Any
        action can fail in flight (a vehicle rejects it, a link drops), so every
        Try has this branch.
        """
        spec = logic.spec
        assert spec.catch is not None
        key = (spec.catch, act[: spec.catch_loops])
        if key in self._tries:
            return False
        self._tries.add(key)
        i = len(self.points)
        choice = self.prefix[i] if i < len(self.prefix) else 0
        self.points.append(
            ChoicePoint(
                drone,
                spec.key,
                "try",
                spec.catch_line,
                0,
                "try",
                0,
                choice,
                bool(choice),
                # The Try's own node is not at hand (only its line): its file is not
                # guessed from the Body's first action, which may be written elsewhere.
            )
        )
        return bool(choice)

    def choices(self) -> tuple[int, ...]:
        """The choices this run made, in order."""
        return tuple(p.choice for p in self.points)

    def branch(self) -> str:
        """The run's label: every If's way, and every decision taken the other way."""
        words = [p.label() for p in self.points if p.purpose == "if" or p.choice]
        return "; ".join(words) or "as simulated"


__all__ = ["UNKNOWABLE_PROPERTIES", "ChoicePoint", "Oracle", "other_way", "unknowable"]
