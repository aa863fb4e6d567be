"""The ground station's role (paper VI-G): start trigger, progress, completion, abort.

The ground station is a participant like any drone: it runs its own program
(the initial node, and any pause or condition hosted there) in a
:class:`~.runtime.DroneRuntime`.  On top, :class:`GroundStation` collects the
drones' Ready, Progress, Resolved and Report messages, sends the start
trigger only once every drone is ready (so no trigger is lost at start), and
declares the mission complete once every participant resolved its top-level
nodes.  There is no central master during the mission: drones trigger each
other directly; the ground station only starts, watches and ends.

Links: the network layer reports a drone that went silent (``lost``), came
``back`` or ``left`` (:class:`~eamos.net.link.PeerStatus`).  A silent drone is
still waited for -- it may be flying on behind a broken link and come back --
unless it stays silent longer than ``give_up_s``: then it counts as failed
(like a drone whose process died) and the others may complete without it.

A lost drone (its process died, or it was given up) is not waited for, neither
for resolution nor for its final report: it is already counted as failed, and
waiting for it would only delay the summary by the report timeout.  If its
report arrives anyway, it is kept.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from eamos.actors.report import DroneReport, DroneReportError
from eamos.actors.runtime import DroneRuntime
from eamos.net import wire
from eamos.net.effects import PeerStatus
from eamos.net.progress import progress_events
from eamos.program.uniform import GROUND_STATION

from .flown import Flown
from .last_seen import LastSeen

Clock = Callable[[], float]


@dataclass(frozen=True)
class ParticipantFailed:
    """Local event for the display: a participant is gone (its process died, ...), and why."""

    sender: str
    reason: str


@dataclass
class DroneView:
    """What the ground station knows of one drone, for display and the summary."""

    name: str
    ready: bool = False
    resolved: bool = False
    state: str = "starting"
    action: str = ""
    node: str = ""
    position: tuple[float, float, float] | None = None
    armed: bool | None = None
    landed: bool | None = None
    seen_at: float | None = None  # wall-clock time its latest telemetry arrived
    done_actions: int = 0
    failed_actions: int = 0
    report: DroneReport | None = None  # its final report, once received
    events: list[dict[str, Any]] = field(default_factory=list)
    link: str = "up"  # "up", "lost" (silent), "back" or "left" (said goodbye)
    link_serial: int = 0
    silent_since: float | None = None  # monotonic time the link was reported lost
    given_up: bool = False  # silent for longer than give_up_s: not waited for
    exited: str = ""  # how its node's process ended, once it did ("" while it runs)
    mode: str = ""  # its autopilot's own flight mode (MAVLink drones)
    samples: list[wire.TelemetrySample] = field(default_factory=list)  # the latest three
    # The fastest horizontal speed it held over two sample intervals in a row (m/s): what the
    # live look-ahead flies it at (a drone slower than its type says is seen slower).
    cruise_mps: float = 0.0
    # Its airborne flight so far (seconds, metres, climb, battery used): the look-ahead's
    # measure of its battery's drain.
    flown: Flown = field(default_factory=Flown)

    def take_sample(self, msg: wire.TelemetrySample) -> None:
        """Its latest telemetry: where it is, the speed it holds, what it has flown."""
        if self.samples:
            self.flown = self.flown.after(self.samples[-1], msg)
        self.samples = [*self.samples[-2:], msg]
        self.position = (msg.x_m, msg.y_m, msg.z_m)
        self.armed = msg.armed
        self.landed = msg.landed
        self.seen_at = time.time()
        if len(self.samples) == 3:
            a, b, c = self.samples
            held = min(horizontal_speed(a, b), horizontal_speed(b, c))
            self.cruise_mps = max(self.cruise_mps, held)

    def last_seen(self) -> LastSeen | None:
        """Where its latest telemetry placed it (None: no telemetry arrived)."""
        if self.position is None or self.seen_at is None:
            return None
        x, y, z = self.position
        return LastSeen(x, y, z, bool(self.armed), self.landed, self.seen_at)


def horizontal_speed(a: wire.TelemetrySample, b: wire.TelemetrySample) -> float:
    """Horizontal speed between two samples (m/s; 0 when no time passed between them)."""
    dt = b.time_s - a.time_s
    return math.hypot(b.x_m - a.x_m, b.y_m - a.y_m) / dt if dt > 0 else 0.0


#: The operator's commands for the whole mission; every other one is for one drone.
MISSION_COMMANDS = ("pause", "resume")
DRONE_COMMANDS = ("hold", "resume", "land", "return-home", "release")


def command_refusal(command: str, drone: str, drones: list[str]) -> str:
    """Why the operator's ``command`` for ``drone`` ("": the mission) cannot be sent ("": sent)."""
    if not drone:
        if command not in MISSION_COMMANDS:
            return f"{command!r} is not a mission command (one of: {', '.join(MISSION_COMMANDS)})"
        return ""
    if drone not in drones:
        return f"no drone {drone!r} in this mission (its drones: {', '.join(drones)})"
    if command not in DRONE_COMMANDS:
        return f"{command!r} is not a drone command (one of: {', '.join(DRONE_COMMANDS)})"
    return ""


def progress_entry(
    msg: wire.Progress, position: tuple[float, float, float] | None
) -> dict[str, Any]:
    """A node's progress as a drone view keeps it (pure but for a missing time stamp).

    A ``running`` action also keeps where the ground station last saw the vehicle
    (``position``): a snapshot's continuation flies a relative move to its own end.
    """
    entry = {
        "t": msg.detail.get("at", time.time()),
        "state": msg.state,
        "node": msg.node,
        "action": msg.action,
        **msg.detail,
    }
    if msg.state == "running" and position is not None:
        entry["position"] = list(position)
    return entry


class GroundStation:
    """Coordinates one mission run from the ground; thread-safe, waits on a Condition."""

    def __init__(
        self,
        drones: Iterable[str],
        mission_id: str,
        on_change: Callable[[str, DroneView, Any], None] | None = None,
        give_up_s: float | None = None,
        clock: Clock = time.monotonic,
        deployment: str = "",
        checksums: Mapping[str, str] | None = None,
    ) -> None:
        self.mission_id = mission_id
        self.deployment = deployment  # named in the Start: the drones of this roll-out start
        # The checksum of each participant's compiled program: a Ready naming another
        # program (a file edited, its checksum recomputed) is refused, not counted ready.
        self.checksums = dict(checksums or {})
        self.give_up_s = give_up_s
        self.clock = clock  # monotonic seconds: when a silent drone is given up
        self.views = {name: DroneView(name) for name in drones}
        self.views.setdefault(GROUND_STATION, DroneView(GROUND_STATION))
        self.runtime: DroneRuntime | None = None
        self.on_change = on_change
        self._cond = threading.Condition()
        self.failures: list[str] = []  # participants that died or never became ready
        # Of those, the ones known dead (a process exit, a failed start): unlike a
        # silent drone, which may fly on behind a broken link, they fail the run.
        self.dead: list[str] = []
        # Complete or Abort sent: from now on a drone's report and exit are its normal end.
        self.over = False
        self.started = False  # the Start was sent: the operator's commands may come
        self.paused = False  # the operator paused the mission (until a resume)
        self.amendment_answers: Callable[[wire.Amend], None] | None = None  # (.amend)

    # -- wiring -------------------------------------------------------------------------

    def attach(self, runtime: DroneRuntime) -> None:
        """Use ``runtime`` (running the ground station's program) to talk to the fleet."""
        self.runtime = runtime

    def handle(self, msg: Any) -> None:
        """Everything addressed to the ground station arrives here (any thread).

        A progress batch is taken apart: each state change it carries is
        handled (and shown) on its own, in order.
        """
        if isinstance(msg, wire.Progress):
            for event in progress_events(msg):
                self._handle_one(event)
        elif isinstance(msg, wire.Amend):  # a drone's answer to an amendment's phase
            if self.amendment_answers is not None:
                self.amendment_answers(msg)
        else:
            self._handle_one(msg)

    def _handle_one(self, msg: Any) -> None:
        stopped_early = ""
        with self._cond:
            view = self.views.get(getattr(msg, "sender", ""))
            if view is None:
                return
            if isinstance(msg, wire.Ready):
                expected = self.checksums.get(view.name, msg.program_checksum)
                if msg.program_checksum == expected:
                    if view.exited and not self.over:
                        self._rejoined(view)
                    view.ready = True
                    view.state = "ready"
                else:
                    why = (
                        f"{view.name}: runs a program other than the one compiled for this "
                        f"run (checksum {msg.program_checksum[:23]}..., "
                        f"expected {expected[:23]}...): not started"
                    )
                    if why not in self.failures:  # Ready is resent until acknowledged
                        self.failures.append(why)
                    view.state = "wrong program"
            elif isinstance(msg, wire.Resolved):
                view.resolved = True
                view.state = "resolved"
            elif isinstance(msg, wire.Report):
                try:
                    view.report = DroneReport.from_json(msg.report)
                except DroneReportError as exc:
                    # Not waited for any longer: what it would send again is the same.
                    view.state = "lost"
                    self.failures.append(f"{view.name}: unreadable report ({exc})")
                else:
                    stopped_early = self._stopped_early(view)
            elif isinstance(msg, wire.Progress) and msg.state == "autopilot":
                view.mode = str(msg.detail.get("mode", ""))  # not a node's: no state change
            elif isinstance(msg, wire.Progress):
                view.node = msg.node
                view.action, view.state = msg.action, msg.state
                finished = msg.detail.get("finished")
                if isinstance(finished, int):
                    view.done_actions = finished
                if msg.state == "failed":
                    view.failed_actions += 1
                view.events.append(progress_entry(msg, view.position))
            elif isinstance(msg, wire.TelemetrySample):
                view.take_sample(msg)
            elif isinstance(msg, PeerStatus):
                if msg.serial <= view.link_serial:
                    return  # an older event overtaken by a newer one (two threads report)
                view.link_serial = msg.serial
                view.link = msg.state
                view.events.append({"t": time.time(), "link": msg.state, "silent_s": msg.silent_s})
                if msg.state == "lost":
                    view.silent_since = self.clock() - msg.silent_s
                else:
                    view.silent_since = None
                    if view.given_up and msg.state in ("back", "restarted"):
                        # It came back (or its node restarted) before the end: wait for it again.
                        view.given_up = False
                        view.state = "back"
                        gone = f"{view.name}: silent"
                        self.failures = [f for f in self.failures if not f.startswith(gone)]
            if not isinstance(msg, (wire.TelemetrySample, wire.Progress)):
                # What the waiters wait for (ready, resolved, lost, reports, failures):
                # not the stream of samples and progress, each of which would wake
                # them to look at every drone again.
                self._cond.notify_all()
        if self.on_change is not None:
            self.on_change(view.name, view, msg)
        if stopped_early:
            self.fail(view.name, stopped_early)

    def _rejoined(self, view: DroneView) -> None:
        """A new node of ``view``'s drone, whose node had exited, says it is ready: it
        rejoined (it proved nothing had run: :mod:`eamos.actors.rejoin`), so it is waited
        for again and its earlier exit no longer fails the run; lock held."""
        gone = f"{view.name}: "
        self.failures = [f for f in self.failures if not f.startswith(gone)]
        self.dead = [f for f in self.dead if not f.startswith(gone)]
        view.events.append({"t": time.time(), "rejoined": view.exited})
        view.exited = ""
        view.resolved = False
        view.report = None

    def _stopped_early(self, view: DroneView) -> str:
        """Why ``view``'s report, just received, ends its part before the mission's end
        ("" when it is the normal end); lock held.

        A drone reports last, when its node is about to exit: before Complete or Abort,
        from a drone that has not resolved, that is its node stopping (a signal, ...),
        a resolution counted at once, as a failure of the run.
        """
        if self.over or view.resolved or view.state == "lost" or view.report is None:
            return ""
        why = view.report.abort_reason or "its report says it did not finish"
        return f"its node stopped before the mission ended ({why})"

    def exited(self, name: str, why: str) -> None:
        """``name``'s node ended (``why``: how, e.g. "process exited with code 1").

        Every exit is counted at once: after the mission's end with a report, it is
        the normal end; otherwise (no report can come any more, or it stopped before
        the end) the participant failed and is no longer waited for.
        """
        with self._cond:
            view = self.views.get(name)
            if view is None:
                return
            view.exited = why
            view.events.append({"t": time.time(), "exited": why})
            counted = view.state == "lost"  # already failed (its early report, ...)
            normal = view.report is not None and (self.over or view.resolved)
            self._cond.notify_all()
        if counted or normal:
            return
        self.fail(name, why if view.report is None else f"{why} before the mission ended")

    def fail(self, name: str, reason: str) -> None:
        """A participant is gone (its process died, or it could not start).

        With no report from it, the reason says where its last telemetry placed it.
        """
        with self._cond:
            view = self.views.get(name)
            if view is not None and view.report is None:
                seen = view.last_seen()
                if seen is not None:
                    reason = f"{reason}; {seen.describe()}"
            self.failures.append(f"{name}: {reason}")
            self.dead.append(f"{name}: {reason}")
            if view is not None:
                view.state = "lost"
                view.events.append({"t": time.time(), "failed": reason})
            self._cond.notify_all()
        if self.on_change is not None and view is not None:
            # The operator hears it at once, not at the end of the run.
            self.on_change(name, view, ParticipantFailed(name, reason))

    # -- phases ---------------------------------------------------------------------------

    def _wait(
        self,
        predicate: Callable[[], bool],
        timeout_s: float | None,
        stop: threading.Event | None = None,
        fail_fast: bool = False,
    ) -> bool:
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        with self._cond:
            while not predicate():
                if stop is not None and stop.is_set():
                    return False
                if fail_fast and self.failures:
                    return False
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    return False
                # A bounded wait only so that `stop` (set by a signal handler, which
                # cannot notify a Condition safely) is noticed.
                self._cond.wait(0.5 if remaining is None else min(remaining, 0.5))
            return True

    def drones(self) -> list[str]:
        """The drones of the mission (not the ground station)."""
        return [n for n in self.views if n != GROUND_STATION]

    def wait_ready(self, timeout_s: float, stop: threading.Event | None = None) -> bool:
        """Every drone reported ready, and every drone listens to the ground station."""
        ok = self._wait(
            lambda: all(self.views[d].ready for d in self.drones()), timeout_s, stop, fail_fast=True
        )
        if not ok or self.runtime is None or self.runtime.out is None:
            return ok
        topics = [wire.topic_to(d) for d in self.drones()]
        return self.runtime.out.wait_subscribed(topics, timeout_s)

    def not_ready(self) -> list[str]:
        """The drones that have not reported ready."""
        with self._cond:
            return [d for d in self.drones() if not self.views[d].ready]

    def start(self) -> None:
        """Send the start trigger (naming the deployment); the initial node fires."""
        assert self.runtime is not None
        with self._cond:
            self.started = True
        self.runtime.send(
            wire.Start(mission=self.mission_id, sender=GROUND_STATION, deployment=self.deployment)
        )
        self.runtime.fire()

    def wait_resolved(self, timeout_s: float | None, stop: threading.Event | None = None) -> bool:
        """Every participant still alive (ground station included) resolved its top-level nodes.

        A lost drone (its process died, or it was silent for longer than
        ``give_up_s``) does not stop the others: drones that do not depend on it
        finish, and those that do stay unresolved until the timeout.
        """

        def done() -> bool:
            self._give_up_silent()
            return all(v.resolved or v.state == "lost" for v in self.views.values())

        return self._wait(done, timeout_s, stop)

    def _give_up_silent(self) -> None:
        """Count drones silent for longer than ``give_up_s`` as failed (lock held)."""
        if self.give_up_s is None:
            return
        now = self.clock()
        for view in self.views.values():
            if (
                view.link == "lost"
                and not view.resolved
                and not view.given_up
                and view.silent_since is not None
                and now - view.silent_since > self.give_up_s
            ):
                view.given_up = True
                view.state = "lost"
                reason = f"silent for more than {self.give_up_s:g} s"
                self.failures.append(f"{view.name}: {reason}")

    def lost_links(self) -> list[str]:
        """Participants whose link is currently reported lost."""
        with self._cond:
            return [n for n, v in self.views.items() if v.link == "lost"]

    def unresolved(self) -> list[str]:
        """The participants that have not resolved their top-level nodes."""
        with self._cond:
            return [n for n, v in self.views.items() if not v.resolved]

    def complete(self) -> None:
        """Tell every drone the mission is over (they report and exit)."""
        assert self.runtime is not None
        with self._cond:
            self.over = True
        self.runtime.send(wire.Complete(mission=self.mission_id, sender=GROUND_STATION))

    def abort(self, reason: str) -> None:
        """Every drone stops its mission and lands now."""
        with self._cond:
            self.over = True
        if self.runtime is not None:
            self.runtime.send(
                wire.Abort(mission=self.mission_id, sender=GROUND_STATION, reason=reason)
            )
            self.runtime.abort(reason)

    def take_command(self, command: str, drone: str, origin: str) -> str:
        """Record the operator's command for the summary (:func:`.operator.command`)."""
        with self._cond:
            why = "the mission is over" if self.over else "" if self.started else "not started"
            if not why:
                entry = {"t": time.time(), "operator": command, "drone": drone, "origin": origin}
                self.views[GROUND_STATION].events.append(entry)
                self.paused = {"pause": True, "resume": False}.get(command, self.paused)
        return why

    def wait_reports(
        self, names: Iterable[str], timeout_s: float, stop: threading.Event | None = None
    ) -> bool:
        """Wait for the final report of each of ``names`` that is not lost.

        A drone that is lost (its process died, or it was silent for longer
        than ``give_up_s``, even while this waits) is not waited for.  True when
        nothing is missing any more; False on timeout (or when ``stop`` is set).
        """
        wanted = list(names)
        return self._wait(lambda: not self._missing_reports(wanted), timeout_s, stop)

    def _missing_reports(self, names: list[str]) -> list[str]:
        """Of ``names``, those still expected to report (lock held)."""
        self._give_up_silent()
        return [n for n in names if self.views[n].report is None and self.views[n].state != "lost"]

    def missing_reports(self, names: Iterable[str]) -> list[str]:
        """Of ``names``, the drones still expected to report that have not (lost ones aside)."""
        with self._cond:
            return self._missing_reports(list(names))

    def snapshot(self) -> dict[str, DroneView]:
        """A copy of every participant's view (safe to read while messages arrive)."""
        with self._cond:
            return {
                n: DroneView(**{**v.__dict__, "events": list(v.events)})
                for n, v in self.views.items()
            }
