"""One stepping clock for every simulated vehicle of a process.

A simulated vehicle advances in fixed simulated steps (:data:`SIM_DT_S`) paced
against the wall clock (its ``speedup``).  A thread per vehicle, waking every few
milliseconds, made a process of many drones mostly thread switches; now one
:class:`SimClock` per process wakes once per wall tick and steps every vehicle
that is due, each by as many steps as its own schedule (:class:`Pacer`) says wall
time has covered; several per tick at high speed-ups, so simulated time per step
stays what the physics needs while the wall tick stays at least
:data:`MIN_WALL_TICK_S`.  A vehicle at rest (nothing but its clock and battery
changes) leaves the ticking set and costs nothing until its rest ends or a request
pokes it (:meth:`SimClock.poke`).

The clock only schedules: what a vehicle does when called is its own
(:class:`Paced`, :meth:`eamos.hal.sim.adapter.SimAdapter.pace`).  Time is read
through the injected ``time`` function; :meth:`SimClock.tick` runs one round, so
tests drive the clock by hand (``threaded=False``) with a fake time and no
thread.  With ``threaded=True`` a daemon thread calls it: its wait between ticks
*is* the simulator's clock (a poke or :meth:`close` ends it early), not
synchronisation.
"""

from __future__ import annotations

import heapq
import itertools
import math
import threading
import time
from collections.abc import Callable
from typing import Protocol

from eamos.hal.sim.actions import SIM_DT_S

#: Shortest wall-clock tick: at high speed-ups several steps run per tick, so
#: the clock wakes at most ~200 times a second however many vehicles it steps.
MIN_WALL_TICK_S = 0.005
#: If a vehicle falls this far behind its wall schedule (a loaded machine),
#: its simulation slows down instead of bursting to catch up.
MAX_LAG_S = 0.1

__all__ = ["MAX_LAG_S", "MIN_WALL_TICK_S", "Paced", "Pacer", "SimClock"]


class Paced(Protocol):
    """A vehicle the clock steps."""

    @property
    def wall_tick_s(self) -> float:
        """The wall time between two of its ticks while it moves."""
        ...

    def pace(self, now: float) -> float | None:
        """Do what is due at wall time ``now``: None to be called again next tick, else
        the wall time its rest ends (``math.inf``: not before a :meth:`SimClock.poke`)."""
        ...


class Pacer:
    """How many simulated steps of one vehicle wall time has covered (pure: time passed in).

    ``steps_per_tick`` steps of :data:`SIM_DT_S` make one tick of ``wall_tick_s`` at
    ``speedup``.  :meth:`due` counts against a fixed schedule from :meth:`restart`
    (no drift): however late a round comes, the steps it runs are those wall time
    has covered; a vehicle more than :data:`MAX_LAG_S` behind runs one tick's steps
    and takes the rest as lost time (it slows down instead of bursting).

    The schedule's steps fall on one grid of wall time, the multiples of
    ``step_wall_s``, shared by every pacer of the same speed-up: vehicles that rest
    until the same moment then end their rests on the same step, and the clock wakes
    once for all of them, not once for each.
    """

    def __init__(self, speedup: float) -> None:
        if not (speedup > 0 and math.isfinite(speedup)):
            raise ValueError(f"speedup must be > 0, got {speedup!r}")
        self.speedup = speedup
        self.steps_per_tick = max(1, round(MIN_WALL_TICK_S * speedup / SIM_DT_S))
        self.step_wall_s = SIM_DT_S / speedup
        self.wall_tick_s = self.steps_per_tick * self.step_wall_s
        self._max_lag_steps = max(self.steps_per_tick, int(MAX_LAG_S * speedup / SIM_DT_S))
        self._origin = 0.0
        self._done = 0

    def restart(self, now: float) -> None:
        """Count from the step of the grid at ``now`` (at most one step before it)."""
        # The tolerance keeps a time computed as a grid step (a rest's end) on its step.
        self._origin = math.floor(now / self.step_wall_s + 1e-6) * self.step_wall_s
        self._done = 0

    def stepped_to(self) -> float:
        """The wall time the steps run so far have reached (a step of the grid)."""
        return self._origin + self._done * self.step_wall_s

    def due(self, now: float) -> int:
        """The steps wall time has covered by ``now`` and not yet run; counted as run."""
        covered = int((now - self._origin) * self.speedup / SIM_DT_S + 1e-9)
        steps = covered - self._done
        if steps > self._max_lag_steps:
            # Far behind (a stalled machine): one tick now, the rest not made up.
            steps = self.steps_per_tick
            self.restart(now)
            self._origin -= steps * self.step_wall_s
            self._done = steps
            return steps
        if steps <= 0:
            return 0
        self._done = covered
        return steps


class SimClock:
    """Steps every attached vehicle that is due, once per wall tick (see module doc).

    ``time``: the wall clock (monotonic seconds); ``threaded``: run a thread that
    ticks (else call :meth:`tick` yourself).  Thread-safe: vehicles attach, poke
    and detach from any thread.
    """

    def __init__(
        self,
        name: str = "sim-clock",
        *,
        time_fn: Callable[[], float] = time.monotonic,
        threaded: bool = True,
    ) -> None:
        self.name = name
        self.now = time_fn
        self._cond = threading.Condition()
        self._attached: set[Paced] = set()
        self._ticking: set[Paced] = set()  # moving: paced every tick
        self._poked: set[Paced] = set()  # a request came: paced at the next tick
        self._resting: dict[Paced, float] = {}  # -> when its rest ends (a heap entry each)
        self._heap: list[tuple[float, int, Paced]] = []
        self._order = itertools.count()
        self._closed = False
        self._threaded = threaded
        self._thread: threading.Thread | None = None
        self.ticks = 0  # rounds run (cheap to watch: a resting fleet makes few)
        self.errors: list[tuple[Paced, Exception]] = []  # vehicles whose pace() raised

    # -- vehicles ------------------------------------------------------------------

    def attach(self, vehicle: Paced) -> None:
        """Step ``vehicle`` from the next tick on (the thread starts with the first)."""
        with self._cond:
            if self._closed:
                raise RuntimeError(f"{self.name}: clock closed")
            self._attached.add(vehicle)
            self._poked.add(vehicle)
            if self._threaded and self._thread is None:
                self._thread = threading.Thread(target=self._run, name=self.name, daemon=True)
                self._thread.start()
            self._cond.notify()

    def detach(self, vehicle: Paced) -> None:
        """Step ``vehicle`` no more (a tick already calling it finishes that call)."""
        with self._cond:
            self._attached.discard(vehicle)
            self._ticking.discard(vehicle)
            self._poked.discard(vehicle)
            self._resting.pop(vehicle, None)

    def poke(self, vehicle: Paced) -> None:
        """``vehicle`` has news (a request): pace it at the next tick, resting or not."""
        with self._cond:
            if vehicle in self._attached:
                self._poked.add(vehicle)
                self._cond.notify()

    @property
    def attached(self) -> int:
        """How many vehicles it steps."""
        with self._cond:
            return len(self._attached)

    def close(self) -> None:
        """Stop the thread (vehicles still attached are stepped no more). Idempotent."""
        with self._cond:
            self._closed = True
            thread = self._thread
            self._cond.notify()
        if thread is not None and thread is not threading.current_thread():
            thread.join()

    # -- ticking ---------------------------------------------------------------------

    def tick(self) -> float:
        """One round: pace every vehicle due now; the wall seconds until the next is due
        (``math.inf``: none is, until a poke)."""
        now = self.now()
        with self._cond:
            due = set(self._ticking) | self._poked
            self._poked = set()
            heap = self._heap
            while heap and heap[0][0] <= now:
                _, _, vehicle = heapq.heappop(heap)
                if self._resting.get(vehicle) is not None and self._resting[vehicle] <= now:
                    del self._resting[vehicle]
                    due.add(vehicle)
            self.ticks += 1
        results: list[tuple[Paced, float | None]] = []
        for vehicle in due:
            try:
                results.append((vehicle, vehicle.pace(now)))
            except Exception as exc:  # pace() promises not to raise: a bug, kept to see
                self.errors.append((vehicle, exc))
                self.detach(vehicle)  # one broken vehicle does not stop the others
        with self._cond:
            for vehicle, wake in results:
                if vehicle not in self._attached:
                    continue  # detached meanwhile
                if wake is None or vehicle in self._poked:
                    self._ticking.add(vehicle)
                    self._resting.pop(vehicle, None)
                    continue
                self._ticking.discard(vehicle)
                if math.isfinite(wake):
                    self._resting[vehicle] = wake
                    heapq.heappush(self._heap, (wake, next(self._order), vehicle))
                else:
                    self._resting.pop(vehicle, None)
            return self._until_next(now)

    def _until_next(self, now: float) -> float:
        """Wall seconds from ``now`` to the next round (lock held)."""
        if self._poked:
            return 0.0
        while self._heap and self._resting.get(self._heap[0][2]) != self._heap[0][0]:
            heapq.heappop(self._heap)  # an entry no longer true (woken meanwhile)
        wait = max(0.0, self._heap[0][0] - now) if self._heap else math.inf
        if self._ticking:
            wait = min(wait, min(v.wall_tick_s for v in self._ticking))
        return wait

    def _run(self) -> None:
        wait = 0.0
        while True:
            with self._cond:
                if wait > 0 and not self._poked and not self._closed:
                    # The wait is the simulator's clock, ended early by a poke or close.
                    self._cond.wait(None if math.isinf(wait) else wait)
                if self._closed:
                    return
            started = self.now()
            wait = self.tick()
            if math.isfinite(wait):
                wait -= self.now() - started  # the round's own time is part of the tick
