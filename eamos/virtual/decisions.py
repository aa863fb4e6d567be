"""A hook deciding conditions the simulation cannot know (for the pre-flight check).

A condition on a battery's charge, or on a drone flown by a person, has a value
in a virtual run (the model's battery, the scripted pilot's path), but a real
flight may give the other one.  :func:`install_decide` makes a condition node
ask ``decide(drone, logic, activation, purpose, value)`` each time it has a
value, and use the answer instead; the explorer in :mod:`eamos.check` answers
"as simulated" or "the other way" to enumerate the branches.
"""

from __future__ import annotations

from collections.abc import Callable

from ..actors.logic import ConditionLogic
from ..actors.state import Iteration

#: ``decide(drone, logic, activation, purpose, simulated value) -> value to use``.
Decide = Callable[[str, ConditionLogic, Iteration, str, bool], bool]


def install_decide(drone: str, logic: ConditionLogic, decide: Decide) -> None:
    """Make ``logic`` (one condition node of ``drone``) ask ``decide`` for every decision."""
    logic.override = lambda act, purpose, value: decide(drone, logic, act, purpose, value)


__all__ = ["Decide", "install_decide"]
