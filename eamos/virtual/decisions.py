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
    """Make ``logic`` (one condition node of ``drone``) ask ``decide`` for every decision.

    The node's own check is replaced on this instance only: same order of
    events (pending activation, value known, not aborted), the answer in place
    of the simulated value.
    """

    def check(act: Iteration) -> None:
        purpose = logic.pending.get(act)
        if purpose is None or logic.aborted:
            return
        value = logic._value()
        if value is None:
            return  # no telemetry yet: as the node itself, wait for the next push
        logic._decide(act, purpose, decide(drone, logic, act, purpose, value))

    setattr(logic, "_check", check)  # noqa: B010 (an instance attribute on purpose)


__all__ = ["Decide", "install_decide"]
