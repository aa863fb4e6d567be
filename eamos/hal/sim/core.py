"""The simulated quadcopter as pure logic: no threads, no clock reads.

:class:`SimCore` holds everything the simulated vehicle does (the kinematic
model, the action rules and timeouts, the scripted pilot, battery drain,
telemetry sampling and the adapter log events, all described in
:mod:`eamos.hal.sim.adapter`) and advances only when told: each
:meth:`SimCore.step` is one :data:`SIM_DT_S` step of simulated time.  The action
lifecycle is its base class (:class:`~eamos.hal.sim.actions.ActionRules`); telemetry,
the pilot and the guided motions have modules of their own.  Whoever owns the core is its
clock: :class:`eamos.hal.sim.adapter.SimAdapter` has it stepped in wall time by the
process's :class:`~eamos.hal.sim.clock.SimClock`; a virtual-time driver steps it as fast
as it likes.

Requests (:meth:`~SimCore.run`, :meth:`~SimCore.cancel`, :meth:`~SimCore.abort`)
are queued and taken up at the start of the next step, in order.  A step never
calls back: it returns the finished actions (their done callbacks and results,
for the caller to invoke) and the telemetry samples to publish.  The only
outside time the core sees is the injected ``clock`` that stamps telemetry
samples with an epoch time (``Telemetry.time_s``).

Usage::

    core = SimCore("D1", SimSettings(), log)
    first = core.start()                 # the first telemetry sample
    handle = core.run(Takeoff(5.0), done)
    while not finished:
        callbacks, samples = core.step()
        for done, result in callbacks:
            done(result)
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import math
import operator
import time
from collections import deque
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING

from eamos.hal.api import ActionHandle, ActionResult, DoneCallback, Telemetry
from eamos.hal.kinematics import Quadcopter, VehicleState
from eamos.hal.sim.actions import (
    PAYLOAD_DELAY_S,
    SIM_DT_S,
    ActionRules,
    Finished,
    SimAction,
    SimRequest,
)
from eamos.hal.sim.landing import LandingDisarm
from eamos.hal.sim.pilot import ScriptedPilot
from eamos.hal.sim.settings import SimSettings
from eamos.hal.sim.telemetry import EPS_S, TelemetrySampler
from eamos.program.plugins import EMPTY_PLUGINS, PluginRegistry
from eamos.program.uniform import Command

if TYPE_CHECKING:
    from eamos.logs import EventLog


class SimCore(ActionRules):
    """One simulated quadcopter, advanced step by step by its owner (see module doc).

    Not thread-safe: the owner serialises every call (``SimAdapter`` holds a lock).
    """

    def __init__(
        self,
        drone: str,
        settings: SimSettings,
        log: EventLog,
        clock: Callable[[], float] = time.time,
        plugins: PluginRegistry = EMPTY_PLUGINS,
        wait_for_plugins: bool = True,
        start: VehicleState | None = None,
    ) -> None:
        """A core for ``drone``; ``clock`` gives the epoch time stamped on telemetry.

        ``start``: where the vehicle is when the core starts (default: standing at home,
        disarmed, at ``settings.battery_pct``); a run continuing a mission's snapshot
        gives where the real vehicle was (:meth:`Quadcopter.at`).

        ``plugins``: the plugin actions it may run (their "sim" implementations, each
        on a thread of its own under ``settings.plugin_deadline_s``).
        ``wait_for_plugins``: the step that starts a plugin action waits for its
        outcome (at most the deadline), so a run in virtual time does not depend on
        how fast the implementation's thread is; False (a vehicle in real time): the
        core looks for the outcome at every step and flies on meanwhile.
        """
        self.drone = drone
        self.settings = settings
        self._log = log
        self._frame = settings.frame
        self._model = (
            Quadcopter(settings.limits, battery_pct=settings.battery_pct)
            if start is None
            else Quadcopter.at(start, settings.limits)
        )
        self._telemetry = TelemetrySampler(drone, settings, log, clock)
        self._requests: deque[SimRequest] = deque()
        self._actions: dict[int, SimAction] = {}
        self._motion: SimAction | None = None
        self._step_count = 0  # time is step_count * SIM_DT_S: no summing error, skips in O(1)
        self._started = False
        self._aborting = False
        self._pilot = ScriptedPilot(settings.pilot, settings, log)
        self.plugins = plugins
        self.wait_for_plugins = wait_for_plugins
        self._heading_deg = 0.0  # compass degrees; Orbit's centre lies ahead along it
        self._payload: dict[str, float] = {}  # plugin state (gimbal pitch, photos, video)
        self._landing = LandingDisarm.of(settings.disarm_after_landing_s, SIM_DT_S)
        self._unsent: Telemetry | None = None  # see unsent()

    # -- requests ------------------------------------------------------------

    def start(self) -> Telemetry:
        """Log ``adapter.start`` and return the first telemetry sample (to publish)."""
        if self._started:
            raise RuntimeError(f"{self.drone}: simulator core already started")
        self._started = True
        s = self.settings
        self._log.info(
            "adapter.start",
            adapter="sim",
            speedup=s.speedup,
            home_lat_deg=s.home_lat_deg,
            home_lon_deg=s.home_lon_deg,
            home_alt_m=s.home_alt_m,
            battery_pct=s.battery_pct,
            home_m=list(s.home_m),
            pilot_waypoints=len(s.pilot),
            reject_actions=list(s.reject_actions),
        )
        return self._telemetry.first(self._model.state)

    def run(self, command: Command, done: DoneCallback) -> ActionHandle:
        """Queue ``command``; it is taken up at the next :meth:`step`."""
        handle = ActionHandle.of(command)
        self._requests.append(SimRequest("run", action=SimAction(handle, command, done)))
        return handle

    def cancel(self, handle: ActionHandle) -> None:
        """Queue a cancel: the vehicle holds where it is; done gets ``cancelled``."""
        self._requests.append(SimRequest("cancel", handle=handle))

    def abort(self) -> None:
        """Queue an abort: cancel every action, take control from the pilot, land, disarm."""
        self._requests.append(SimRequest("abort"))

    def finish_all(self, result: ActionResult) -> list[Finished]:
        """End every running and queued action with ``result`` (closing, crashing)."""
        finished: list[Finished] = []
        pending = [r.action for r in self._requests if r.action is not None]
        for act in [*self._actions.values(), *pending]:
            self._finish(act, result, finished)
        self._requests.clear()
        return finished

    # -- time ----------------------------------------------------------------

    def step(self) -> tuple[list[Finished], list[Telemetry]]:
        """Advance one :data:`SIM_DT_S` step.

        Returns the actions that finished (done callbacks with their results,
        for the caller to invoke, in order) and the telemetry samples to publish.
        """
        if not self._started:
            raise RuntimeError(f"{self.drone}: step() before start()")
        finished: list[Finished] = []
        samples: list[Telemetry] = []
        self._handle_requests(finished)
        self._guide()
        was_landed = self._model.landed
        self._model.step(SIM_DT_S)
        self._step_count += 1
        if self._pilot.update(self.t_s, self._model):
            self._pilot_handed_over(finished)
        self._update_actions(finished)
        self._update_abort()
        self._update_landing(was_landed)
        if self._unsent is not None:
            samples.append(self._unsent)  # what skipped steps left unsent goes first
            self._unsent = None
        self._telemetry.observe(self.t_s, self._model.state, samples)
        return finished, samples

    def idle_steps(self, limit: int) -> int:
        """How many of the next steps (at most ``limit``) change only the clock and battery.

        0 while anything may happen: a request queued, a motion, an abort or
        the pilot flying, a sample or position line not yet showing the
        current position or flags.  Otherwise the steps before the first timer
        or arming is due and before the first sample due once the battery's
        shown value (0.1 %) has changed, counted exactly; a virtual-time
        driver may :meth:`skip` them.
        """
        return self._idle(limit, battery_read=True)

    def quiet_steps(self, limit: int) -> int:
        """:meth:`idle_steps` of a vehicle whose telemetry nobody reads now.

        The battery's shown value then ends no rest: the samples that would show
        it are sent by nobody's leave, and :meth:`skip` keeps what they would have
        shown (the latest of them is :meth:`unsent`, for whoever starts reading).
        """
        return self._idle(limit, battery_read=False)

    def unsent(self) -> Telemetry | None:
        """The latest sample the steps skipped unread would have sent, once (None: none).

        The next :meth:`step` sends it first if nobody asked for it before.
        """
        sample, self._unsent = self._unsent, None
        return sample

    def _idle(self, limit: int, battery_read: bool) -> int:
        if self._requests or self._aborting or self._pilot.flying or not self._model.at_rest:
            return 0
        due = math.inf
        for act in self._actions.values():
            if act.kind == "timer":
                due = min(due, act.until_s)
            elif act.kind == "arm":
                due = min(due, max(self.settings.arm_delay_s, self.t_s), act.deadline_s)
            else:
                return 0
        model = self._model
        telemetry = self._telemetry
        if not telemetry.shows((*model.position, model.armed, model.landed)):
            return 0
        # The battery's shown value (0.1 %) matters only to the sample that shows it:
        # the steps before the first sample due once it has changed are idle.
        now = self._step_count
        if not battery_read:
            pass
        elif not telemetry.shows_battery(round(model.battery_pct, 1)):
            limit = min(limit, telemetry.first_sample_step(now + 1, SIM_DT_S) - now - 1)
        else:
            change = self._battery_change(limit)
            if change is not None:
                limit = min(limit, telemetry.first_sample_step(now + change, SIM_DT_S) - now - 1)
        disarm = self._landing.idle_limit(self._step_count)
        if disarm is not None:
            limit = min(limit, disarm)
        if due == math.inf:
            return max(0, limit)
        # A timer ends at the first step k with k * SIM_DT_S >= due (less EPS_S):
        # the steps before it are idle.
        first = math.ceil((due - EPS_S) / SIM_DT_S)
        while first > 0 and (first - 1) * SIM_DT_S >= due - EPS_S:
            first -= 1  # float rounding put it one late
        while first * SIM_DT_S < due - EPS_S:
            first += 1  # ... or one early
        return max(0, min(limit, first - self._step_count - 1))

    def _battery_change(self, limit: int) -> int | None:
        """In how many steps the shown battery (0.1 %) changes at rest; None: not within ``limit``.

        Counted exactly as the steps drain it (one subtraction each, as
        :meth:`~eamos.hal.kinematics.Quadcopter.rest`), not estimated.
        """
        model = self._model
        battery = model.battery_pct
        per_step = model.drain_pct_per_min() * SIM_DT_S / 60.0
        if not (per_step > 0.0 and battery > 0.0):
            return None
        shown = round(battery, 1)
        if shown <= 0.0:
            return None  # drained to (nearly) empty: it shows 0.0 from now on
        # round(b, 1) changes when b crosses the x.x5 below it: not before ``sure``
        # steps (the summed drain differs from the product by far less than two steps).
        sure = int((battery - (shown - 0.05)) / per_step) - 2
        if sure >= limit:
            return None
        k = 0
        if sure > 0:
            # The first ``sure`` steps' drain, summed in order as the steps sum it
            # (above x.x5 > 0 no step clamps at empty).
            ahead = functools.reduce(operator.sub, itertools.repeat(per_step, sure), battery)
            if round(ahead, 1) == shown:
                k, battery = sure, ahead
        while k < limit:
            k += 1
            battery = max(0.0, battery - per_step)
            if round(battery, 1) != shown:
                return k
        return None

    def skip(self, steps: int) -> None:
        """Advance ``steps`` steps known idle (:meth:`idle_steps`, :meth:`quiet_steps`):
        as many :meth:`step` calls, the samples they would send kept for :meth:`unsent`."""
        if steps <= 0:
            return
        model = self._model
        if self._requests or not model.at_rest:
            raise RuntimeError(f"{self.drone}: skip({steps}) over steps that are not idle")
        before, first = model.battery_pct, self._step_count + 1
        model.rest(SIM_DT_S, steps)
        self._step_count += steps
        telemetry = self._telemetry
        fired = telemetry.catch_up(self.t_s)
        if fired is None or telemetry.shows_battery(round(model.battery_pct, 1)):
            return  # no sample was due, or none would differ (at rest only the battery drains)
        # The last sample due in the skipped steps shows the battery as drained up to it,
        # summed as the steps sum it (the drain at rest is one rate).
        due_step = telemetry.first_step_at(fired, first, SIM_DT_S)
        per_step = model.drain_pct_per_min() * SIM_DT_S / 60.0
        drained = functools.reduce(
            operator.sub, itertools.repeat(per_step, due_step - first + 1), before
        )
        then = dataclasses.replace(model.state, battery_pct=max(0.0, drained))
        sample = telemetry.resample(then)
        if sample is not None:
            self._unsent = sample

    # -- observation ---------------------------------------------------------

    def state(self) -> VehicleState:
        """A snapshot of the simulated vehicle."""
        return self._model.state

    def where(self) -> tuple[float, float, float, bool, bool, float]:
        """(x_m, y_m, z_m, landed, armed, battery_pct) now: :meth:`state` without velocities,
        cheap enough to record every step (the pre-flight check's tracks)."""
        m = self._model
        x, y, z = m.position
        return (x, y, z, m.landed, m.armed, m.battery_pct)

    @property
    def settling(self) -> bool:
        """True while the vehicle will still disarm by itself after its landing.

        A mission may be over while this holds: whoever owns the core steps it on
        until it is false to see the state a real autopilot would be left in.
        """
        return self._landing.pending

    @property
    def pilot_flying(self) -> bool:
        """True while the scripted pilot has the controls."""
        return self._pilot.flying

    @property
    def heading_deg(self) -> float:
        """The compass heading (0 north, 90 east) the vehicle faces."""
        return self._heading_deg

    @property
    def payload(self) -> Mapping[str, float]:
        """The plugins' payload state (``gimbal_pitch_deg``, ``photos``, ``video``), a copy."""
        return dict(self._payload)

    # -- requests (taken up at the start of a step) -----------------------------

    def _handle_requests(self, finished: list[Finished]) -> None:
        while self._requests:
            req = self._requests.popleft()
            if req.op == "run" and req.action is not None:
                self._begin(req.action, finished)
            elif req.op == "cancel" and req.handle is not None:
                act = self._actions.get(req.handle.id)
                if act is None:
                    continue  # already finished: nothing to do
                self._log.info("adapter.cancel", action=act.handle.action, handle=act.handle.id)
                if act is self._motion and not act.deferred:
                    self._model.hold()
                self._finish(act, ActionResult("cancelled", "cancelled"), finished)
            elif req.op == "abort":
                self._abort(finished)

    def _abort(self, finished: list[Finished]) -> None:
        self._log.info("adapter.abort", t_sim=round(self.t_s, 3), pilot=self._pilot.state)
        for act in list(self._actions.values()):
            self._finish(act, ActionResult("cancelled", "aborted"), finished)
        self._pilot.abort()
        self._aborting = True
        self._model.land()

    def _update_landing(self, was_landed: bool) -> None:
        """Disarm ``disarm_after_landing_s`` after a touchdown, as the autopilots do."""
        model = self._model
        if self._landing.update(self._step_count, was_landed, model.landed, model.armed):
            model.disarm()
            self._log.info("adapter.disarm_after_landing", t_sim=round(self.t_s, 3))

    def _update_abort(self) -> None:
        if self._aborting and self._model.landed:
            if self._model.armed:
                self._model.disarm()
            self._aborting = False
            self._log.info("adapter.abort.done", t_sim=round(self.t_s, 3))


__all__ = ["PAYLOAD_DELAY_S", "SIM_DT_S", "Finished", "SimCore"]
