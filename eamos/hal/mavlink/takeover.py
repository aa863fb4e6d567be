"""Who changed the vehicle's mode: the adapter, a documented failsafe, or a pilot.

A vehicle the adapter flies changes mode for three reasons.  The adapter asked
for it (MAV_CMD_DO_SET_MODE, or a command that switches the mode itself:
MAV_CMD_NAV_LAND, MAV_CMD_NAV_RETURN_TO_LAUNCH, PX4's MAV_CMD_NAV_TAKEOFF and
MAV_CMD_DO_ORBIT).  The autopilot's own failsafe did it, and said so: ArduCopter
announces every failsafe it acts on with a STATUSTEXT (``events.cpp``
``announce_failsafe``: "Radio Failsafe", "Battery Failsafe", "GCS Failsafe",
"... Failsafe - Continuing Landing"; "Failsafe: Terrain data missing"; the EKF
check's "EKF variance" and "EKF Failsafe"; a fence breach) before it switches to
RTL, SMART_RTL, LAND, BRAKE or ALT_HOLD; PX4's failsafe framework says "Failsafe
activated" (``failsafe/framework.cpp`` ``notifyUser``) as it switches to HOLD,
AUTO.RTL, AUTO.LAND or, after an offboard loss, POSCTL.  Or someone else chose the
mode: a pilot, through a second ground station (QGroundControl, MAVProxy's ``mode
loiter``) or an RC mode switch.  Nothing in the HEARTBEAT tells these apart, so
:class:`TakeoverWatch` does, from what the adapter asked for and what the vehicle
said: a mode change the adapter did not cause, with no failsafe announced within
:data:`FAILSAFE_WINDOW_S` before it or ``grace_s`` after it, while the adapter
flies the vehicle (it armed it, or has commanded it since, and it is armed), is a
pilot's.  From then on the adapter never commands that vehicle again.

A mode change right after the link was silent is neither: PX4 leaves OFFBOARD by
itself when a second passes without setpoints and comes back when they resume.

Pure: times are passed in (``time.monotonic()`` seconds of the caller), nothing
here waits, locks or sends.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal

#: A failsafe's STATUSTEXT may come this long (vehicle seconds) before its mode change.
FAILSAFE_WINDOW_S = 5.0
#: ... or this long after it: a mode change nobody asked for waits this long for one.
FAILSAFE_GRACE_S = 1.5
#: A mode the adapter asked for still counts as its own this long after the request
#: (a second request may overtake the first one's HEARTBEAT).
REQUEST_MEMORY_S = 10.0

#: MAV_CMD ids that switch the mode by themselves, and to what, per autopilot.
MAV_CMD_NAV_RETURN_TO_LAUNCH = 20
MAV_CMD_NAV_LAND = 21
MAV_CMD_NAV_TAKEOFF = 22
MAV_CMD_DO_ORBIT = 34
COMMAND_MODES: dict[str, dict[int, frozenset[str]]] = {
    "ardupilot": {
        MAV_CMD_NAV_LAND: frozenset({"LAND"}),
        MAV_CMD_NAV_RETURN_TO_LAUNCH: frozenset({"RTL", "LAND"}),
    },
    "px4": {
        MAV_CMD_NAV_LAND: frozenset({"AUTO.LAND"}),
        MAV_CMD_NAV_RETURN_TO_LAUNCH: frozenset({"AUTO.RTL", "AUTO.LAND", "HOLD"}),
        MAV_CMD_NAV_TAKEOFF: frozenset({"AUTO.TAKEOFF", "HOLD"}),
        MAV_CMD_DO_ORBIT: frozenset({"ORBIT"}),
    },
}
#: Modes an autopilot moves on to by itself from a mode the adapter chose.
FOLLOW_ON: dict[str, frozenset[tuple[str, str]]] = {
    "ardupilot": frozenset(),
    "px4": frozenset(
        {
            ("AUTO.TAKEOFF", "HOLD"),  # AUTO.TAKEOFF switches to HOLD at the altitude
            ("AUTO.RTL", "AUTO.LAND"),
            ("AUTO.RTL", "HOLD"),
        }
    ),
}
#: The mode each autopilot follows a companion computer in: a change into it hands the
#: vehicle to the adapter (PX4 returns to OFFBOARD by itself once setpoints flow again),
#: never takes it away.
COMPANION_MODES: dict[str, str] = {"ardupilot": "GUIDED", "px4": "OFFBOARD"}
#: STATUSTEXTs that announce a failsafe (lower case; see the module docstring).
_FAILSAFE_TEXT = re.compile(r"failsafe|ekf variance|fence|breach|dead reckoning")

Verdict = Literal["ours", "failsafe", "pilot", "pending", "link"]


def announces_failsafe(text: str) -> bool:
    """Whether a STATUSTEXT is an autopilot announcing a failsafe (or a fence breach)."""
    return _FAILSAFE_TEXT.search(text.lower()) is not None


@dataclass(frozen=True)
class ModeChange:
    """One mode change the watch classified: what it was, to which mode, and why."""

    verdict: Verdict
    mode: str
    previous: str
    why: str = ""  # the failsafe's STATUSTEXT, for a failsafe


class TakeoverWatch:
    """Classifies every mode change of one vehicle (see the module docstring).

    Feed it what the adapter asks (:meth:`expect`, :meth:`expect_command`), what
    the vehicle says (:meth:`statustext`, :meth:`link_gap`) and the mode changes
    seen in HEARTBEATs (:meth:`mode_seen`); :meth:`tick` settles a pending change
    once its grace is over.  :attr:`taken` is the pilot's mode once one is seen;
    it never clears.
    """

    def __init__(
        self,
        autopilot: str,
        grace_s: float = FAILSAFE_GRACE_S,
        window_s: float = FAILSAFE_WINDOW_S,
        link_grace_s: float = 3.0,
    ) -> None:
        self.autopilot = autopilot
        self.grace_s = grace_s
        self.window_s = window_s
        self.link_grace_s = link_grace_s
        self._requested: dict[str, float] = {}  # mode -> when the adapter last caused it
        self._latest: frozenset[str] = frozenset()  # what the latest request may lead to
        self._failsafe_text = ""
        self._failsafe_at = -float("inf")
        self._gap_at = -float("inf")
        self._pending: ModeChange | None = None
        self._pending_since = 0.0
        #: The mode the latest HEARTBEAT showed (as classified so far).
        self.mode = ""
        #: The latest failsafe verdict (the adapter's actions fail with it).
        self.failsafe: ModeChange | None = None
        #: The pilot's mode once a takeover is seen (never cleared).
        self.taken: ModeChange | None = None
        #: The adapter flies the vehicle (it armed it, or commanded it since it was armed).
        self.commanding = False

    # -- what the adapter does -------------------------------------------------------

    def set_autopilot(self, autopilot: str) -> None:
        """The autopilot, once the HEARTBEAT named it."""
        self.autopilot = autopilot

    def expect(self, modes: Iterable[str], now: float) -> None:
        """The adapter asks for one of ``modes`` (MAV_CMD_DO_SET_MODE) and commands the vehicle."""
        latest = frozenset(modes)
        for mode in latest:
            self._requested[mode] = now
        self._latest = latest
        self.commanding = True
        if self._pending is not None and self._pending.mode in latest:
            self._pending = None  # it was on its way: ours after all

    def expect_command(self, command: int, now: float) -> None:
        """The adapter sends MAV_CMD ``command`` (it may switch the mode by itself)."""
        modes = COMMAND_MODES.get(self.autopilot, {}).get(command)
        if modes is not None:
            self.expect(modes, now)
        else:
            self.commanding = True

    def disarmed(self) -> None:
        """The vehicle disarmed: the adapter flies it again only once it commands it."""
        self.commanding = False

    # -- what the vehicle says -----------------------------------------------------------

    def statustext(self, text: str, now: float) -> ModeChange | None:
        """A STATUSTEXT arrived; a pending change it explains is a failsafe (returned)."""
        if not announces_failsafe(text):
            return None
        # PX4 ends its texts with a tab (the rest belongs to its events protocol).
        self._failsafe_text, self._failsafe_at = text.strip(), now
        pending, self._pending = self._pending, None
        if pending is None:
            return None
        change = ModeChange("failsafe", pending.mode, pending.previous, text.strip())
        self.failsafe = change
        return change

    def link_gap(self, now: float) -> None:
        """The link was silent for a while (a mode change soon after may be PX4's own)."""
        self._gap_at = now

    def mode_seen(self, previous: str, mode: str, armed: bool, now: float) -> ModeChange:
        """A HEARTBEAT shows ``mode`` after ``previous``: whose change is it?

        ``pending`` when it may still be a failsafe whose STATUSTEXT has not come
        (settled by :meth:`statustext` or :meth:`tick`); ``pilot`` at once only when
        the grace is zero.
        """
        self.mode = mode
        if self.taken is not None:
            return self.taken
        # A pilot flicking through modes: the grace runs from the first unexplained one.
        earlier, self._pending = self._pending, None
        if mode != previous and self.failsafe is not None and self.failsafe.mode == previous:
            self.failsafe = None  # the failsafe's mode is over
        if not armed or not self.commanding:
            return ModeChange("ours", mode, previous, "not flown by the adapter")
        if self._caused(previous, mode, now):
            return ModeChange("ours", mode, previous)
        if now - self._failsafe_at <= self.window_s:
            change = ModeChange("failsafe", mode, previous, self._failsafe_text)
            self.failsafe = change
            return change
        if now - self._gap_at <= self.link_grace_s:
            return ModeChange("link", mode, previous, "after a silent link")
        pending = ModeChange("pending", mode, previous)
        if self.grace_s <= 0:
            return self._take(pending)
        self._pending = pending
        if earlier is None:
            self._pending_since = now
        return pending

    def tick(self, now: float) -> ModeChange | None:
        """A pending change whose grace is over without a failsafe: the pilot's (returned)."""
        if self._pending is None or now - self._pending_since < self.grace_s:
            return None
        pending, self._pending = self._pending, None
        return self._take(pending)

    # -- reading ---------------------------------------------------------------------

    @property
    def pending(self) -> ModeChange | None:
        """A mode change waiting for its grace to end (None: none)."""
        return self._pending

    def _caused(self, previous: str, mode: str, now: float) -> bool:
        if mode in self._latest or mode == COMPANION_MODES.get(self.autopilot):
            return True
        asked = self._requested.get(mode)
        if asked is not None and now - asked <= REQUEST_MEMORY_S:
            return True
        return (previous, mode) in FOLLOW_ON.get(self.autopilot, frozenset())

    def _take(self, pending: ModeChange) -> ModeChange:
        taken = ModeChange("pilot", pending.mode, pending.previous)
        self.taken = taken
        return taken


__all__ = [
    "COMMAND_MODES",
    "COMPANION_MODES",
    "FAILSAFE_GRACE_S",
    "FAILSAFE_WINDOW_S",
    "FOLLOW_ON",
    "ModeChange",
    "TakeoverWatch",
    "Verdict",
    "announces_failsafe",
]
