"""A hook deciding conditions the simulation cannot know (for the pre-flight check).

A condition on a battery's charge, or on a drone flown by a person, has a value
in a virtual run (the model's battery, the scripted pilot's path), but a real
flight may give the other one.  :func:`install_decide` makes a condition node
ask ``decide(drone, logic, activation, purpose, value)`` each time it has a
value, and use the answer instead; the explorer in :mod:`eamos.check` answers
"as simulated" or "the other way" to enumerate the branches.  A ``fail`` hook
(:data:`FailHook`) is asked before each action inside a Try's Body starts: the
explorer makes the first one of each Try fail, to check OnFailure too.
"""

from __future__ import annotations

from collections.abc import Callable

from ..actors.logic import ActionLogic, ConditionLogic
from ..actors.state import Iteration

#: ``decide(drone, logic, activation, purpose, simulated value) -> value to use``.
Decide = Callable[[str, ConditionLogic, Iteration, str, bool], bool]
#: ``fail(drone, logic, activation) -> True to make this action fail`` (actions in a Try's Body).
FailHook = Callable[[str, ActionLogic, Iteration], bool]
#: The reason an action failed on purpose has (the check's "Body fails" branch).
FAILED_ON_PURPOSE = "failed on purpose: the check's branch where the Try's Body fails here"


def install_decide(drone: str, logic: ConditionLogic, decide: Decide) -> None:
    """Make ``logic`` (one condition node of ``drone``) ask ``decide`` for every decision."""
    logic.override = lambda act, purpose, value: decide(drone, logic, act, purpose, value)


__all__ = ["FAILED_ON_PURPOSE", "Decide", "FailHook", "install_decide"]
