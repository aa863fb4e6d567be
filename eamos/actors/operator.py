"""The operator's commands to one drone's runtime (pause, hold, resume, land, return-home, release).

The ground station broadcasts :class:`~eamos.net.wire.Operator`; each drone's In-Bridge
hands the ones for it (``target`` its name, or ``""``) to the runtime, which logs them
with their origin and tells its uniform-API actor (:class:`Operate`).  The uniform
space (:class:`~.uniform_api.UniformSpace`) carries them out:

* ``pause`` (every drone) and ``hold`` (one): each running action that moves the
  vehicle or counts time is *suspended*: cancelled on the adapter (the vehicle brakes
  and holds where it is, the adapter's ``cancel`` contract), but not answered: its node
  keeps waiting.  An action asked for while suspended waits too.  Conditions keep
  being evaluated (telemetry flows on).
* ``resume``: each suspended action goes on from where it stopped
  (:func:`remaining_command`): a move is re-issued to its original target, a
  ``PauseFor``/``Hold`` for the time it had left; actions asked for meanwhile start.
  After ``release`` it hands the vehicle back to EAMOS.
* ``land`` / ``return-home``: the drone is taken out of the mission: its running and
  later actions fail with :data:`TAKEN_OUT` (a ``Try`` catches them; the drones
  waiting for it are blocked and apply their policy), and the vehicle lands (the
  adapter's ``abort``) or flies home and lands (``ReturnHome``).
* ``release``: the vehicle is handed to a pilot: its running actions are cancelled
  (it holds) and fail, and from then on nothing here commands it, as after a pilot's
  takeover (:meth:`~.uniform_api.UniformSpace.pilot_has_it`): no action, no cancel,
  no landing, until an explicit ``resume``.

The pure part (which actions are suspended, what is left of them) is here, tested
without threads; the time an action ran is counted on the adapter's clock
(:func:`adapter_time_s`: simulated seconds for the simulator).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Final

from eamos.hal.api import TakenOver
from eamos.program.uniform import (
    Command,
    FlyBy,
    FlyToLLA,
    FlyToXYZ,
    Hold,
    Land,
    Orbit,
    PauseFor,
    ReturnHome,
    Takeoff,
    Yaw,
    target_xyz,
)

__all__ = [
    "COMMANDS",
    "RELEASED",
    "TAKEN_OUT",
    "Operate",
    "adapter_time_s",
    "remaining_command",
    "suspendable",
]

#: Every operator command; those for one drone are all but ``pause``.
COMMANDS: Final = ("pause", "resume", "hold", "land", "return-home", "release")

#: Why the actions of a drone taken out of the mission fail, by command.
TAKEN_OUT: Final = {
    "land": "landed by the operator",
    "return-home": "sent home by the operator",
    "release": "released to a pilot by the operator",
}

#: The takeover a release stands for: the uniform space treats it as a pilot's.
RELEASED: Final = TakenOver("RELEASED by the operator")

_MOVES = (Takeoff, FlyBy, FlyToXYZ, FlyToLLA, Land, ReturnHome, Orbit, Yaw)
_TIMED = (PauseFor, Hold)


@dataclass(frozen=True)
class Operate:
    """To the uniform-API actor: carry out the operator's ``command`` on this drone."""

    command: str


def suspendable(command: Command) -> bool:
    """Whether a pause suspends ``command``: moves and timed waits (instant actions --
    arm, a payload, a plugin's -- end on their own and are not)."""
    return isinstance(command, _MOVES + _TIMED)


def remaining_command(
    command: Command,
    ran_s: float,
    start: tuple[float, float, float] | None,
) -> Command:
    """What to issue on resume for ``command``, suspended after running ``ran_s`` seconds
    (adapter clock) from the position ``start`` (mission frame; None: unknown).

    A relative move goes on to its original target (``FlyBy``: ``FlyToXYZ`` of the start
    plus its offset); a timed wait for what it had left; anything else again as it was
    (an absolute move, a landing, a turn; an ``Orbit`` starts its circle again).
    """
    if isinstance(command, PauseFor):
        return PauseFor(max(0.0, command.duration_s - ran_s))
    if isinstance(command, Hold):
        return Hold(max(0.0, command.duration_s - ran_s))
    if isinstance(command, FlyBy) and start is not None:
        target = target_xyz(command, start)
        assert target is not None  # a FlyBy always has one
        return FlyToXYZ(*target)
    return command


def adapter_time_s(adapter: object) -> float:
    """The adapter's clock, in seconds: the simulator's simulated time (``sim_time_s``: a
    ``PauseFor`` lasts simulated seconds, whatever the speed-up), else the monotonic clock."""
    value = getattr(adapter, "sim_time_s", None)
    if isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    return time.monotonic()
