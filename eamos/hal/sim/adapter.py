"""A simulated quadcopter adapter built on the kinematic model.

The vehicle itself is the pure :class:`~eamos.hal.sim.core.SimCore` (no
threads, no clock); :class:`SimAdapter` has it stepped every :data:`SIM_DT_S`
simulated seconds by a :class:`~eamos.hal.sim.clock.SimClock`: the process's one
clock when drones share a process (``eamos-node`` with several configs passes
it), else a clock of its own.  The clock paces the steps against the wall clock
(:meth:`SimAdapter.pace`): that pacing *is* the simulator's clock, and
``speedup`` makes it run faster than real time.  Everything else (action
durations, timeouts, telemetry rate, pause lengths) is counted in simulated
steps, so a mission behaves the same at any speed-up, only faster.  While the
vehicle rests (nothing but the clock and an unseen battery change, as
:meth:`~eamos.hal.sim.core.SimCore.idle_steps` says), the clock leaves it out
of its ticks for as long as the rest lasts in wall time, and a new request
pokes it awake; the steps rested through are skipped exactly, so simulated time,
telemetry and the position log are those of stepping every step (100 hovering
drones cost next to nothing).

Actions complete on real criteria checked after every step:

* ``Arm``: the armed flag is set (possible ``arm_delay_s`` after start, like
  pre-flight checks passing; an earlier ``Arm`` waits).
* ``Takeoff``/``FlyBy*``/``FlyTo*``: within ``tolerance_m`` of the target and
  slower than ``settle_speed_mps``.
* ``Land``: the landed flag is set.  ``Disarm``: immediate, on the ground only.
  After a touchdown that ends a flight the vehicle disarms by itself
  ``disarm_after_landing_s`` later (2 s; 0: never), as PX4 (``COM_DISARM_LAND``)
  and ArduCopter do (:mod:`eamos.hal.sim.landing`, ``adapter.disarm_after_landing``).
* ``PauseFor(s)``: ``s`` simulated seconds.  Payload actions: 0.2 simulated s.
* ``Hold(s)``: ``s`` simulated seconds of hover (only in the air, not during a move).
* ``SetSpeed(v)``: at once; later horizontal moves cruise at ``v``.
* ``Yaw(deg)``: the heading reaches ``deg`` (90 degrees per second, the shorter way).
* ``Orbit(r, turns)``: the circle swept and the vehicle settled at its end
  (:mod:`eamos.hal.sim.motions`).
* ``ReturnHome``: above home at the current height, then landed.
* Plugin actions: their "sim" implementation's duration (:mod:`eamos.hal.sim.plugin_api`;
  the plugins come from entry points, docs/plugins.md).  The implementation computes the
  outcome on a thread of its own within ``plugin_deadline_s`` wall-clock seconds; the
  simulator never waits for it (the vehicle hovers, and can land, meanwhile).

Rules: ``Takeoff`` needs the vehicle armed ("not armed"); ``FlyBy*``/``FlyTo*``
need it airborne ("not flying"); ``Disarm`` fails in the air ("in the air");
only one motion action (``Takeoff``, ``Land``, ``FlyBy*``, ``FlyTo*``) runs at a
time, another one fails ("busy").  Arm and motion actions fail after
``action_timeout_s`` simulated seconds (a deferred motion action's timeout
starts when it actually starts, see below).

Scripted pilot.  ``pilot`` stands in for a hand-flown drone (D3 in the
paper's experiment D): once the drone is airborne and its ``Takeoff`` has
completed, the pilot flies the listed waypoints in order, holding ``hold_s``
simulated seconds at each.  While the pilot flies, mission motion actions
(``FlyBy*``, ``FlyTo*``, ``Land``, a repeated ``Takeoff``) are accepted but
wait, occupying the motion slot (a second one fails "busy"), until the pilot's
path ends; then they start from wherever the pilot
left the drone.  Non-motion actions (``PauseFor``, payload) run meanwhile.
``abort()`` takes the controls back from the pilot at once.

Telemetry is sampled at ``telemetry_hz`` (simulated) and sent only when the
sample, quantized to 1 cm / 1e-7 degree / 0.1 %, differs from the last one
sent: a drone at rest produces no samples (battery drain aside).  One sample
is sent synchronously by :meth:`SimAdapter.start`.

Adapter log events: ``adapter.start``, ``adapter.action.start`` (when the
simulator takes the action up), ``adapter.action.deferred`` (waiting for the
pilot), ``adapter.action.end`` (status, reason, simulated duration, position),
``adapter.cancel``, ``adapter.abort``/``adapter.abort.done``,
``adapter.pilot.start``/``.waypoint``/``.end``, ``adapter.close``, and
``adapter.position`` once per simulated second while the position or the
armed/landed flags change.  ``t_sim`` fields are simulated seconds since start.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from typing import Any

from eamos.hal.api import (
    ActionHandle,
    ActionResult,
    AdapterError,
    DoneCallback,
    Telemetry,
    TelemetryCallback,
)
from eamos.hal.kinematics import VehicleState
from eamos.hal.sim.clock import MAX_LAG_S, MIN_WALL_TICK_S, Pacer, SimClock
from eamos.hal.sim.core import SIM_DT_S, Finished, SimCore
from eamos.hal.sim.settings import SimSettings, Waypoint
from eamos.hal.sim.telemetry import ReadRate
from eamos.logs import EventLog, make_logger
from eamos.program.plugins import EMPTY_PLUGINS, PluginRegistry, discover_plugins
from eamos.program.uniform import Command

#: The longest rest taken at once (steps; the core says how many are idle, at most this many).
MAX_REST_STEPS = 1_000_000


def paced_ticks(stop: threading.Event, speedup: float) -> Iterator[int]:
    """The simulation clock: yields how many SIM_DT_S steps to run, until ``stop`` is set.

    Each wait targets a fixed schedule on the monotonic clock (no drift); at high
    speed-ups several steps run per wake-up.  A machine that falls behind by more
    than MAX_LAG_S slows the simulation down instead of catching up in a burst.
    The wait is the simulator's clock, not synchronisation: ``stop`` ends it early.
    """
    steps = max(1, round(MIN_WALL_TICK_S * speedup / SIM_DT_S))
    wall_tick = steps * SIM_DT_S / speedup
    next_tick = time.monotonic()
    while True:
        next_tick += wall_tick
        delay = next_tick - time.monotonic()
        if delay < -MAX_LAG_S:
            next_tick = time.monotonic()
            delay = 0.0
        if stop.wait(max(0.0, delay)):
            return
        yield steps


class SimAdapter:
    """An :class:`~eamos.hal.api.Adapter` driving a simulated quadcopter (see module doc).

    A thin pacer over its :class:`SimCore`, stepped by a :class:`SimClock`
    (``clock``: the process's; None: one of its own, with a thread of its own).
    """

    #: The adapter family plugins name implementations for (docs/plugins.md).
    family = "sim"

    def __init__(
        self,
        drone: str,
        settings: SimSettings | None = None,
        adapter_log: EventLog | None = None,
        plugins: PluginRegistry = EMPTY_PLUGINS,
        clock: SimClock | None = None,
    ) -> None:
        """A simulated ``drone``; ``plugins``: the plugin actions it runs (their "sim" code);
        ``clock``: the stepping clock it shares (None: its own)."""
        self.drone = drone
        self.settings = settings or SimSettings()
        self.plugins = plugins
        self._log = adapter_log if adapter_log is not None else make_logger(None)
        # A plugin's outcome is looked for at every step, never waited for: the
        # vehicle flies on (and can land) whatever its implementation does.
        self._core = SimCore(
            drone, self.settings, self._log, plugins=plugins, wait_for_plugins=False
        )
        self._own_clock = clock is None
        self._clock = clock if clock is not None else SimClock(f"sim-{drone}")
        self._pacer = Pacer(self.settings.speedup)
        # One lock guards the core; the condition lets observers (tests, tools)
        # wait for the next simulator tick.
        self._lock = threading.Lock()
        self._tick_cond = threading.Condition(self._lock)
        # Held through a whole pace() (callbacks included): close() waits for one
        # under way, so nothing is delivered after it returns (reentrant: a callback
        # may close the adapter).
        self._pacing = threading.RLock()
        # While resting: (wall time the rest was last caught up to, idle steps left).
        self._asleep: tuple[float, int] | None = None
        self._wakeups = 0  # times the clock paced it (ticks and rests): cheap to watch
        self._started = False
        self._closed = False
        self._on_telemetry: TelemetryCallback | None = None
        # read_at_most(): the samples that go out, and when the last one did.
        self._reads = ReadRate()

    # -- Adapter protocol ----------------------------------------------------

    def start(self, on_telemetry: TelemetryCallback) -> None:
        """Hand the vehicle to the clock and send the first telemetry sample."""
        with self._lock:
            if self._closed:
                raise AdapterError(f"{self.drone}: simulator already closed")
            if self._started:
                raise AdapterError(f"{self.drone}: simulator already started")
            self._started = True
            self._on_telemetry = on_telemetry
            first = self._core.start()
            self._reads.sent_at = self._clock.now()
            self._pacer.restart(self._reads.sent_at)
        self._emit([first])
        self._clock.attach(self)

    def run(self, command: Command, done: DoneCallback) -> ActionHandle:
        """Queue ``command``; the clock starts it at the vehicle's next step."""
        with self._lock:
            if self._closed:
                raise AdapterError(f"{self.drone}: simulator closed")
            self._catch_up(waking=True)  # the rest ends: news
            handle = self._core.run(command, done)
        self._clock.poke(self)
        return handle

    def cancel(self, handle: ActionHandle) -> None:
        """Interrupt ``handle``: the vehicle holds where it is; done gets "cancelled"."""
        with self._lock:
            if not self._closed:
                self._catch_up(waking=True)  # the rest ends: news
                self._core.cancel(handle)
        self._clock.poke(self)

    def abort(self) -> None:
        """Cancel every action, take control from the pilot, land, then disarm."""
        with self._lock:
            if not self._closed:
                self._catch_up(waking=True)  # the rest ends: news
                self._core.abort()
        self._clock.poke(self)

    def read_at_most(self, hz: float | None) -> None:
        """Its samples are read at most ``hz`` times a wall second (None: as they come).

        A vehicle at rest then wakes for its draining battery alone only that often:
        the samples in between would be coalesced unread.  Hovering at a high
        speed-up, the shown battery (0.1 %) changes several times a wall second, and
        each change was a wake-up and a sample.  A moving vehicle sends its latest
        sample once a period (:class:`~eamos.hal.sim.telemetry.ReadRate`); what arms,
        lands, ends an action or comes to rest is sent at once; the battery a late
        sample shows is exact.
        """
        if hz is not None and not hz > 0:
            raise ValueError(f"hz must be > 0 or None, got {hz!r}")
        with self._lock:
            self._reads.period_s = None if hz is None else 1.0 / hz
        self._log.info("adapter.read_rate", hz=hz)
        self._clock.poke(self)  # a rest computed for the old rate ends at the next tick

    def close(self) -> None:
        """Stop stepping; actions still running end "cancelled". Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._clock.detach(self)
        if self._own_clock:
            self._clock.close()
        with self._pacing:  # a pace() under way finishes first
            with self._lock:
                self._catch_up()
                finished = self._core.finish_all(ActionResult("cancelled", "adapter closed"))
                self._log.info("adapter.close", t_sim=round(self._core.t_s, 3))
                self._tick_cond.notify_all()
            self._deliver(finished)

    # -- observation (tests, tools) ------------------------------------------

    @property
    def state(self) -> VehicleState:
        """A snapshot of the simulated vehicle."""
        with self._lock:
            self._catch_up()
            return self._core.state()

    @property
    def sim_time_s(self) -> float:
        """Simulated seconds since :meth:`start`."""
        with self._lock:
            self._catch_up()
            return self._core.t_s

    @property
    def wakeups(self) -> int:
        """How often the clock has paced it (a resting vehicle costs next to none)."""
        with self._lock:
            return self._wakeups

    @property
    def pilot_flying(self) -> bool:
        """True while the scripted pilot has the controls."""
        with self._lock:
            return self._core.pilot_flying

    def wait_until(self, predicate: Callable[[VehicleState], bool], timeout: float) -> bool:
        """Block until ``predicate(state)`` holds after a tick; False on timeout or close.

        The predicate runs with the simulator's lock held: it must only look at
        the state it is given (not call this adapter).
        """
        deadline = time.monotonic() + timeout
        with self._tick_cond:
            while not predicate(self._core.state()):
                remaining = deadline - time.monotonic()
                if remaining <= 0 or self._closed:
                    return False
                self._tick_cond.wait(remaining)
            return True

    # -- stepped by the clock --------------------------------------------------

    @property
    def wall_tick_s(self) -> float:
        """Wall seconds between two of its ticks while it moves (several steps each, fast)."""
        return self._pacer.wall_tick_s

    def pace(self, now: float) -> float | None:
        """The clock's call at wall time ``now``: run the steps wall time has covered.

        Returns None to be paced again next tick, or, when the core says its next
        steps are idle (more than a tick's), the wall time that rest ends: the clock
        leaves the vehicle out until then or a request's poke.  Never raises: an
        error of the simulator fails the running actions and stops the vehicle.
        """
        with self._pacing:
            try:
                return self._pace(now)
            except BaseException as exc:  # keep the adapter's promise: done is always called
                # (BaseException too: this thread is never the main one, so a KeyboardInterrupt
                # here is no Ctrl-C, and a SystemExit would end the thread silently.)
                # Fail the running actions first: logging may itself fail (a full disk).
                self._crash(exc)
                with contextlib.suppress(Exception):
                    self._log.exception("adapter.error", error=repr(exc))
                return math.inf

    def _pace(self, now: float) -> float | None:
        finished: list[Finished] = []
        samples: list[Telemetry] = []
        wake: float | None = None
        try:
            with self._lock:
                self._wakeups += 1
                if self._closed:
                    return math.inf
                if self._asleep is not None:
                    self._catch_up(now, waking=True)  # the rest is over (or a request came)
                    if self._reads.period_s is not None:
                        skipped = self._core.unsent()  # what the rest left unread, now
                        if skipped is not None:
                            samples.append(skipped)
                steps = self._pacer.due(now)
                for _ in range(steps):
                    done, sampled = self._core.step()
                    finished += done
                    samples += sampled
                if steps:
                    self._tick_cond.notify_all()
                rest = self._core.idle_steps(MAX_REST_STEPS)
                period = self._reads.period_s
                quiet = rest
                if period is not None and rest < MAX_REST_STEPS:
                    quiet = self._core.quiet_steps(MAX_REST_STEPS)
                news = bool(finished) or quiet > self._pacer.steps_per_tick
                samples = self._reads.pass_on(samples, now, news)
                if period is not None and rest < MAX_REST_STEPS:
                    rest = max(rest, min(quiet, self._unread(period)))
                if rest > self._pacer.steps_per_tick:
                    # From the last step run, on the grid every vehicle of this
                    # speed-up shares (Pacer): rests that end together wake once.
                    since = self._pacer.stepped_to()
                    self._asleep = (since, rest)
                    wake = since + rest * self._pacer.step_wall_s
        finally:
            # Actions that ended in the steps before an exception still get their answer.
            self._deliver(finished)
        self._emit(samples)
        return wake

    def _unread(self, period_s: float) -> int:
        """The steps from the last one run until a sample is read again, one read every
        ``period_s`` (lock held; :meth:`read_at_most`).

        The read falls on a multiple of ``period_s`` of the clock's wall time, the
        one nearest a period after the last sample (half a period early at most):
        resting vehicles read at the same rate then wake together, the clock once a
        period for all of them instead of once for each.
        """
        read_at = math.ceil((self._reads.sent_at + period_s) / period_s - 0.5) * period_s
        ahead = (read_at - self._pacer.stepped_to()) / self._pacer.step_wall_s
        return max(0, math.ceil(ahead - 1e-6))

    def _catch_up(self, now: float | None = None, waking: bool = False) -> None:
        """Skip the idle steps wall time has covered while resting (lock held).

        The rest goes on for what is left of it (someone only looked), unless
        ``waking`` (a request, or the clock at its end) or nothing is left; then
        the pacing counts from ``now``.
        """
        if self._asleep is None:
            return
        now = self._clock.now() if now is None else now
        since, most = self._asleep
        # The tolerance keeps a rest's end, computed on the step grid, a whole step.
        covered = min(most, int((now - since) / self._pacer.step_wall_s + 1e-6))
        self._core.skip(covered)
        if waking or covered >= most:
            self._asleep = None
            self._pacer.restart(now)
        else:
            # Counted from the last whole step skipped: no fraction of a step is lost.
            self._asleep = (since + covered * self._pacer.step_wall_s, most - covered)

    def _crash(self, exc: BaseException) -> None:
        with self._lock:
            self._closed = True
            finished = self._core.finish_all(ActionResult("failed", f"simulator error: {exc!r}"))
            self._tick_cond.notify_all()
        self._clock.detach(self)
        self._deliver(finished)

    def _deliver(self, finished: list[Finished]) -> None:
        # Callbacks run outside the lock so they may call run()/cancel() freely.
        for done, result in finished:
            try:
                done(result)
            except Exception as exc:
                self._log.exception("adapter.callback_error", error=repr(exc))

    def _emit(self, samples: list[Telemetry]) -> None:
        callback = self._on_telemetry
        for sample in samples:
            if callback is None:
                return
            try:
                callback(sample)
            except Exception as exc:
                self._log.exception("adapter.telemetry_error", error=repr(exc))


def sim_adapter_from_settings(
    drone: str,
    settings: Mapping[str, Any],
    adapter_log: EventLog | None = None,
    clock: SimClock | None = None,
) -> SimAdapter:
    """Build a :class:`SimAdapter` from a drone's ``hal`` settings mapping.

    It runs the plugin actions installed through entry points (``eamos.actions``);
    broken plugins are logged (``adapter.plugin_problem``) and left out.  ``clock``:
    the process's stepping clock, shared by its simulated drones (None: its own).
    """
    log = adapter_log if adapter_log is not None else make_logger(None)
    # Looked up on first use (a mission without plugin actions never reads the entry
    # points: reading them costs a measurable part of a node's start-up, see
    # docs/performance.md); problems logged then.
    plugins = discover_plugins(
        on_problem=lambda problem: log.warning("adapter.plugin_problem", problem=problem)
    )
    return SimAdapter(drone, SimSettings.from_mapping(settings), log, plugins, clock)


__all__ = [
    "MAX_LAG_S",
    "MIN_WALL_TICK_S",
    "SIM_DT_S",
    "SimAdapter",
    "SimClock",
    "SimSettings",
    "Waypoint",
    "paced_ticks",
    "sim_adapter_from_settings",
]
