"""A link's timer: a thread of its own, or one thread for every link of a process.

A link's session asks to be ticked at its next deadline (a heartbeat, a
retransmission, a liveness check).  Alone, a participant's link has a thread
of its own for that (:class:`LinkTimer`).  Fifty drones in one
process would have fifty such threads, each waking for its own deadlines and
each queuing for the GIL; :class:`TimerHost` runs every link's ticks on one
thread instead, earliest deadline first.

A tick runs with its link's lock held, as on a link's own thread; the host's
lock is never held while a link's lock is taken (a link calls
:meth:`HostedTimer.kick` with its lock held, so the order is always link, then
host).  A tick that raises is logged (``net.link.timer_error``) and counted,
and that link's next tick comes ``retry_s`` later: one link's bug does not
stop the others' timers.
"""

from __future__ import annotations

import heapq
import itertools
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

from eamos.net.sockets import should_log

if TYPE_CHECKING:
    from eamos.logs import EventLog
    from eamos.net.effects import SessionEffect

__all__ = ["HostedTimer", "LinkTimer", "TimerHost", "TimerOwner", "link_timer"]

Clock = Callable[[], float]


def log_timer_error(log: EventLog, exc: BaseException, errors: int) -> None:
    """Log a timer's failed turn (``net.link.timer_error``): the first ones, then every
    so many (:func:`~eamos.net.sockets.should_log`)."""
    if should_log(errors):
        log.error(
            "net.link.timer_error",
            error=f"{type(exc).__name__}: {exc}"[:300],
            errors=errors,
            exc_info=exc,
        )


class TimerOwner(Protocol):
    """What a link's timer calls back: the driver of the session it ticks."""

    name: str  # the participant's (the timer thread's name when it has its own)
    clock: Clock

    @property
    def closed(self) -> bool:
        """Whether the session was closed (the timer's end); read with the lock held."""
        ...

    def tick(self) -> tuple[list[SessionEffect], float]:
        """The session's tick carried out (lock held): what to deliver, the next deadline."""
        ...

    def deliver(self, later: list[SessionEffect]) -> None:
        """Hand ``later`` to the application (lock not held)."""
        ...


class LinkTimer:
    """A link's timer thread: the session's tick at each of its deadlines, and nothing between.

    Kept apart from :class:`~eamos.net.link.LinkDriver` because its job is one of time alone:
    when to run the next tick.  Between two ticks it waits on ``wake``, a
    Condition on the driver's lock, until the deadline the last tick returned,
    or until the driver reports an earlier one (:meth:`kick`, for a
    :class:`~eamos.net.effects.Wake` action); it never polls.  It is kicked
    only for an earlier deadline, so a busy link does not wake it for every
    message.  A turn that raises is logged (``net.link.timer_error``) and
    counted (:attr:`errors`), and the next comes ``retry_s`` later.
    """

    def __init__(
        self, owner: TimerOwner, wake: threading.Condition, log: EventLog, name: str, retry_s: float
    ) -> None:
        self._owner = owner
        self._wake = wake
        self._log = log
        self._retry_s = retry_s
        self._next_wake = float("inf")
        self.errors = 0
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        """Start the thread."""
        self._thread.start()

    def kick(self, at: float) -> None:
        """A deadline at ``at`` appeared (lock held): wake the thread if it sleeps past it."""
        if at < self._next_wake:
            self._next_wake = at
            self._wake.notify()

    def wake_all(self) -> None:
        """Wake the thread to see that the session closed (lock held)."""
        self._wake.notify_all()

    def join(self, timeout_s: float) -> None:
        """Wait for the thread to end, unless called on it or it never started."""
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout_s)

    def _run(self) -> None:
        while True:
            try:
                if not self._turn():
                    return
            # A bug in one turn (the session's tick, a delivery) must not stop the
            # timer: no retransmission, heartbeat or liveness check would follow.
            except BaseException as exc:
                self.errors += 1
                log_timer_error(self._log, exc, self.errors)
                # Not at once again: a turn that keeps failing must not spin a core.
                with self._wake:
                    if self._owner.closed:
                        return
                    self._wake.wait(self._retry_s)

    def _turn(self) -> bool:
        """One turn of the timer: the session's tick, then a wait; False once closed."""
        owner = self._owner
        with self._wake:
            if owner.closed:
                return False
            later, deadline = owner.tick()
            if not later:
                self._next_wake = deadline
                self._wake.wait(max(0.0, deadline - owner.clock()))
                self._next_wake = float("-inf")  # awake: nobody needs to kick
        owner.deliver(later)
        return True


def link_timer(
    owner: TimerOwner,
    wake: threading.Condition,
    log: EventLog,
    retry_s: float,
    host: TimerHost | None = None,
) -> LinkTimer | HostedTimer:
    """``owner``'s timer: on ``host``'s thread if given, else on a thread of its own
    (named after the link).  ``wake`` is a Condition on the owner's lock."""
    if host is not None:
        return host.timer(owner, wake, log, retry_s)
    return LinkTimer(owner, wake, log, f"eamos-link-{owner.name}", retry_s)


class HostedTimer:
    """A link's timer on a :class:`TimerHost`: the interface of a link's own timer."""

    def __init__(
        self,
        host: TimerHost,
        owner: TimerOwner,
        lock: threading.Condition,
        log: EventLog,
        retry_s: float,
    ) -> None:
        self._host = host
        self._owner = owner
        self._lock = lock
        self._log = log
        self._retry_s = retry_s
        self.due = float("inf")  # guarded by the host's lock
        self.ended = threading.Event()
        self.started = False
        self.errors = 0

    def start(self) -> None:
        """Tick now (the first tick schedules the rest)."""
        self.started = True
        self._host.schedule(self, self._host.clock())

    def kick(self, at: float) -> None:
        """A deadline at ``at`` appeared (the link's lock held)."""
        self._host.schedule(self, at)

    def wake_all(self) -> None:
        """The session closed (the link's lock held): the next turn ends this timer."""
        self._host.schedule(self, float("-inf"))

    def join(self, timeout_s: float) -> None:
        """Wait until the host saw the session closed, unless called on the host's thread
        or never started."""
        if self.started and not self._host.on_its_thread():
            self.ended.wait(timeout_s)

    def turn(self) -> None:
        """One tick of the link (on the host's thread); schedules the next."""
        owner = self._owner
        try:
            with self._lock:
                if owner.closed:
                    self.ended.set()
                    return
                later, deadline = owner.tick()
                self._host.schedule(self, deadline, replace=True)
            owner.deliver(later)
        # A bug in one link's tick must stop neither its timer nor the other links'.
        except BaseException as exc:
            self.errors += 1
            log_timer_error(self._log, exc, self.errors)
            self._host.schedule(self, self._host.clock() + self._retry_s, replace=True)


class TimerHost:
    """One thread ticking the links of a process, each at its own deadlines."""

    def __init__(self, name: str = "eamos-link-timers", clock: Clock = time.monotonic) -> None:
        self.clock = clock
        self._cond = threading.Condition()
        self._heap: list[tuple[float, int, HostedTimer]] = []
        self._order = itertools.count()
        self._stopped = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def timer(
        self, owner: TimerOwner, lock: threading.Condition, log: EventLog, retry_s: float
    ) -> HostedTimer:
        """A timer for ``owner`` (a link), whose ticks run with ``lock`` held.

        Raises ValueError if ``owner`` reads another clock than the host: its deadlines
        would be compared with the wrong time."""
        if owner.clock is not self.clock:
            raise ValueError(f"link {owner.name} reads another clock than its shared timer")
        return HostedTimer(self, owner, lock, log, retry_s)

    def on_its_thread(self) -> bool:
        """Whether the caller is the host's thread."""
        return threading.current_thread() is self._thread

    def schedule(self, timer: HostedTimer, at: float, *, replace: bool = False) -> None:
        """Tick ``timer`` at ``at``: earlier than it is due (or in place of it, ``replace``)."""
        with self._cond:
            if not replace and at >= timer.due:
                return
            timer.due = at
            if at == float("inf"):
                return  # nothing to wait for (an entry still queued is stale now)
            wake = not self._heap or at < self._heap[0][0]
            heapq.heappush(self._heap, (at, next(self._order), timer))
            if wake:
                self._cond.notify()

    def stop(self, timeout_s: float = 5.0) -> None:
        """End the thread (every link closed first); idempotent."""
        with self._cond:
            self._stopped = True
            self._cond.notify()
        if not self.on_its_thread():
            self._thread.join(timeout_s)

    def _due(self) -> list[HostedTimer] | None:
        """Wait for the earliest deadline; the timers due then (None: stopped)."""
        with self._cond:
            while not self._stopped:
                now = self.clock()
                due: list[HostedTimer] = []
                while self._heap and self._heap[0][0] <= now:
                    at, _, timer = heapq.heappop(self._heap)
                    if at == timer.due:  # else a later schedule replaced this entry
                        timer.due = float("inf")
                        due.append(timer)
                if due:
                    return due
                self._cond.wait(self._heap[0][0] - now if self._heap else None)
            return None

    def _run(self) -> None:
        while (due := self._due()) is not None:
            for timer in due:
                timer.turn()
