"""The simulated quadcopter as pure logic: no threads, no clock reads.

:class:`SimCore` holds everything the simulated vehicle does (the kinematic
model, the action rules and timeouts, the scripted pilot, battery drain,
telemetry sampling and the adapter log events, all described in
:mod:`eamos.hal.sim.adapter`) and advances only when told: each :meth:`SimCore.step`
is one :data:`SIM_DT_S` step of simulated time.  Whoever owns the core is its
clock: :class:`eamos.hal.sim.adapter.SimAdapter` steps it from a thread paced in wall
time; a virtual-time driver steps it as fast as it likes.

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

import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

from eamos.hal.api import POSITION_LOG_HZ, ActionHandle, ActionResult, DoneCallback, Telemetry
from eamos.hal.kinematics import GeoFrame, Quadcopter, VehicleState
from eamos.hal.sim.settings import SimSettings, Waypoint
from eamos.program.uniform import (
    Arm,
    Command,
    Disarm,
    FlyToLLA,
    Land,
    PauseFor,
    Payload,
    Takeoff,
    target_xyz,
)

#: Simulated seconds per model step.
SIM_DT_S = 0.02
#: Simulated duration of payload actions.
PAYLOAD_DELAY_S = 0.2
#: Simulated seconds between position log lines.
POSITION_LOG_PERIOD_S = 1.0 / POSITION_LOG_HZ
#: Absorbs float error in summed step times when comparing simulated times.
_EPS_S = 1e-9

#: A finished action: its done callback and its result (the caller invokes it).
Finished = tuple[DoneCallback, ActionResult]

_Kind = Literal["arm", "motion", "land", "timer"]


@dataclass(eq=False)
class _Action:
    """A running action inside the simulator."""

    handle: ActionHandle
    command: Command
    done: DoneCallback
    kind: _Kind = "timer"
    started_s: float = 0.0  # sim time the action (really) started
    until_s: float = 0.0  # "timer": when it completes
    deadline_s: float = math.inf  # "arm"/"motion"/"land": when it times out
    target: tuple[float, float, float] | None = None
    deferred: bool = False  # waiting for the scripted pilot


@dataclass(frozen=True)
class _Request:
    op: Literal["run", "cancel", "abort"]
    action: _Action | None = None
    handle: ActionHandle | None = None


class _Telemetry:
    """Telemetry sampling: quantized samples at ``telemetry_hz``, sent only on change.

    Also writes the ``adapter.position`` log line at ``POSITION_LOG_HZ`` of
    simulated time while the position or the armed/landed flags change.
    """

    def __init__(
        self, drone: str, settings: SimSettings, log: Any, clock: Callable[[], float]
    ) -> None:
        self._drone = drone
        self._period_s = 1.0 / settings.telemetry_hz
        self._frame: GeoFrame = settings.frame
        self._log = log
        self._clock = clock
        self._next_sample_s = 0.0
        self._last_sample_key: tuple[Any, ...] | None = None
        self._next_position_log_s = 0.0
        self._last_position_key: tuple[Any, ...] | None = None
        # The raw state the last sample and the last position line showed
        # (for settled(); None until the first of each).
        self._sampled_raw: tuple[Any, ...] | None = None
        self._sampled_battery: float | None = None
        self._logged_raw: tuple[Any, ...] | None = None

    def first(self, st: VehicleState) -> Telemetry:
        """The sample sent at start; the next one is due one period later."""
        sample = self.sample(st)
        self._last_sample_key = sample.state()
        self._sampled_raw = (st.x_m, st.y_m, st.z_m, st.armed, st.landed)
        self._sampled_battery = sample.battery_pct
        self._next_sample_s = self._period_s
        return sample

    def sample(self, st: VehicleState) -> Telemetry:
        """``st`` as a telemetry sample, quantized to 1 cm / 1e-7 degree / 0.1 %."""
        lat, lon, alt = self._frame.to_lla(st.x_m, st.y_m, st.z_m)
        return Telemetry(
            drone=self._drone,
            time_s=self._clock(),
            x_m=round(st.x_m, 2) + 0.0,  # + 0.0 turns -0.0 into 0.0
            y_m=round(st.y_m, 2) + 0.0,
            z_m=round(st.z_m, 2) + 0.0,
            lat_deg=round(lat, 7),
            lon_deg=round(lon, 7),
            alt_m=round(alt, 2) + 0.0,
            battery_pct=round(st.battery_pct, 1),
            armed=st.armed,
            landed=st.landed,
        )

    def settled(self, raw: tuple[Any, ...], shown_battery_pct: float) -> bool:
        """True when the last sample and position line already show this state.

        ``raw`` is ``(x_m, y_m, z_m, armed, landed)``, ``shown_battery_pct`` the
        battery as a sample shows it (0.1 %).  Then the coming steps of a vehicle
        at rest emit nothing until that changes.  Compared on the raw state
        (exact at rest): costs no sample.
        """
        return (
            shown_battery_pct == self._sampled_battery
            and raw == self._sampled_raw == self._logged_raw
        )

    def catch_up(self, t_s: float) -> None:
        """Move the sampling schedule to ``t_s`` as the skipped steps would have."""
        while self._next_sample_s <= t_s + _EPS_S:
            self._next_sample_s += self._period_s
        while t_s >= self._next_position_log_s - _EPS_S:
            self._next_position_log_s += POSITION_LOG_PERIOD_S

    def observe(self, t_s: float, st: VehicleState, samples: list[Telemetry]) -> None:
        """After a step at ``t_s``: append a sample if one is due and differs."""
        if t_s >= self._next_sample_s - _EPS_S:
            while self._next_sample_s <= t_s + _EPS_S:
                self._next_sample_s += self._period_s
            raw = (st.x_m, st.y_m, st.z_m, st.armed, st.landed)
            # Unchanged since the last sample (a vehicle at rest): the same sample, not sent.
            if raw != self._sampled_raw or round(st.battery_pct, 1) != self._sampled_battery:
                sample = self.sample(st)
                key = sample.state()
                if key != self._last_sample_key:
                    self._last_sample_key = key
                    samples.append(sample)
                self._sampled_raw = raw
                self._sampled_battery = sample.battery_pct
        if t_s >= self._next_position_log_s - _EPS_S:
            self._next_position_log_s += POSITION_LOG_PERIOD_S
            raw = (st.x_m, st.y_m, st.z_m, st.armed, st.landed)
            if raw == self._logged_raw:
                return  # unchanged: no line
            self._logged_raw = raw
            key = (round(st.x_m, 2), round(st.y_m, 2), round(st.z_m, 2), st.armed, st.landed)
            if key != self._last_position_key:
                self._last_position_key = key
                self._log.info(
                    "adapter.position",
                    x_m=key[0],
                    y_m=key[1],
                    z_m=key[2],
                    speed_mps=round(st.speed_mps, 2),
                    armed=st.armed,
                    landed=st.landed,
                    battery_pct=round(st.battery_pct, 1),
                    t_sim=round(t_s, 3),
                )


class _Pilot:
    """The scripted pilot: flies its waypoints in order, holding at each (a hand-flown drone)."""

    def __init__(self, path: tuple[Waypoint, ...], settings: SimSettings, log: Any) -> None:
        self._path = path
        self._settings = settings
        self._log = log
        self.state: Literal["idle", "flying", "done"] = "idle" if path else "done"
        self._index = 0
        self._hold_until: float | None = None

    @property
    def flying(self) -> bool:
        """True while the pilot has the controls."""
        return self.state == "flying"

    def take_off(self, model: Quadcopter) -> None:
        """The mission's Takeoff completed: the pilot takes the controls (once)."""
        if self.state != "idle" or model.landed:
            return
        self.state = "flying"
        self._index = 0
        self._hold_until = None
        self._log.info("adapter.pilot.start", waypoints=len(self._path))
        self._fly_to(model, self._path[0])

    def abort(self) -> None:
        """Abort takes the controls back at once."""
        if self.state == "flying":
            self._log.info("adapter.pilot.end", reason="aborted")
        self.state = "done"

    def update(self, t_s: float, model: Quadcopter) -> bool:
        """After a step at ``t_s``; True when the path has just ended."""
        if self.state != "flying":
            return False
        s = self._settings
        wp = self._path[self._index]
        if self._hold_until is None:
            if model.at_target(s.tolerance_m, s.settle_speed_mps):
                self._hold_until = t_s + wp.hold_s
                x, y, z = model.position
                self._log.info(
                    "adapter.pilot.waypoint",
                    index=self._index,
                    x_m=round(x, 3),
                    y_m=round(y, 3),
                    z_m=round(z, 3),
                    t_sim=round(t_s, 3),
                )
            return False
        if t_s < self._hold_until - _EPS_S:
            return False
        self._index += 1
        self._hold_until = None
        if self._index < len(self._path):
            self._fly_to(model, self._path[self._index])
            return False
        self.state = "done"
        self._log.info("adapter.pilot.end", reason="path finished", t_sim=round(t_s, 3))
        return True

    @staticmethod
    def _fly_to(model: Quadcopter, wp: Waypoint) -> None:
        model.set_target(wp.x_m, wp.y_m, wp.z_m)


def refusal(
    command: Command, settings: SimSettings, model: Quadcopter, busy: bool, aborting: bool
) -> str | None:
    """Why the vehicle refuses ``command`` now (its rules), or None.

    ``busy``: a motion action runs (one at a time); ``aborting``: an abort
    is landing the vehicle.
    """
    if command.action in settings.reject_actions:
        return "rejected by vehicle"
    if aborting and not isinstance(command, Payload | PauseFor):
        return "aborting"
    if isinstance(command, PauseFor) and command.duration_s < 0:
        return "duration_s must be >= 0"
    if isinstance(command, Disarm) and model.armed:
        if not model.landed:
            return "in the air"
        if busy:
            return "busy"  # e.g. a Takeoff about to lift off
    if not command.moves:
        return None
    if busy:
        return "busy"  # one motion action at a time
    if isinstance(command, Takeoff):
        if command.height_m <= 0:
            return "height_m must be > 0"
        if not model.armed:
            return "not armed"
    elif not isinstance(command, Land) and model.landed:
        return "not flying"
    return None


class SimCore:
    """One simulated quadcopter, advanced step by step by its owner (see module doc).

    Not thread-safe: the owner serialises every call (``SimAdapter`` holds a lock).
    """

    def __init__(
        self,
        drone: str,
        settings: SimSettings,
        log: Any,
        clock: Callable[[], float] = time.time,
    ) -> None:
        """A core for ``drone``; ``clock`` gives the epoch time stamped on telemetry."""
        self.drone = drone
        self.settings = settings
        self._log = log
        self._frame = settings.frame
        self._model = Quadcopter(settings.limits, battery_pct=settings.battery_pct)
        self._telemetry = _Telemetry(drone, settings, log, clock)
        self._requests: deque[_Request] = deque()
        self._actions: dict[int, _Action] = {}
        self._motion: _Action | None = None
        self._step_count = 0  # time is step_count * SIM_DT_S: no summing error, skips in O(1)
        self._started = False
        self._aborting = False
        self._pilot = _Pilot(settings.pilot, settings, log)

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
        self._requests.append(_Request("run", action=_Action(handle, command, done)))
        return handle

    def cancel(self, handle: ActionHandle) -> None:
        """Queue a cancel: the vehicle holds where it is; done gets ``cancelled``."""
        self._requests.append(_Request("cancel", handle=handle))

    def abort(self) -> None:
        """Queue an abort: cancel every action, take control from the pilot, land, disarm."""
        self._requests.append(_Request("abort"))

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
        self._model.step(SIM_DT_S)
        self._step_count += 1
        if self._pilot.update(self.t_s, self._model):
            self._pilot_handed_over(finished)
        self._update_actions(finished)
        self._update_abort()
        self._telemetry.observe(self.t_s, self._model.state, samples)
        return finished, samples

    def idle_steps(self, limit: int) -> int:
        """How many of the next steps (at most ``limit``) change only the clock and battery.

        0 while anything may happen: a request queued, a motion, an abort or
        the pilot flying, a sample or position line not yet showing the
        current state.  Otherwise the steps before the first timer or arming
        is due and before the battery's shown value (0.1 %) can change,
        counted exactly; a virtual-time driver may :meth:`skip` them.
        """
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
        battery = model.battery_pct
        shown = round(battery, 1)
        if not self._telemetry.settled((*model.position, model.armed, model.landed), shown):
            return 0
        per_step = model.drain_pct_per_min() * SIM_DT_S / 60.0
        if per_step > 0.0 and battery > 0.0:
            # round(b, 1) changes when b crosses the next x.x5 below it; the
            # drain is summed step by step, so stop two steps short of it.
            edge = shown - 0.05
            crossing = int((battery - edge) / per_step) - 2
            limit = min(limit, max(0, crossing))
        if due == math.inf:
            return max(0, limit)
        # A timer ends at the first step k with k * SIM_DT_S >= due (less _EPS_S):
        # the steps before it are idle.
        first = math.ceil((due - _EPS_S) / SIM_DT_S)
        while first > 0 and (first - 1) * SIM_DT_S >= due - _EPS_S:
            first -= 1  # float rounding put it one late
        while first * SIM_DT_S < due - _EPS_S:
            first += 1  # ... or one early
        return max(0, min(limit, first - self._step_count - 1))

    def skip(self, steps: int) -> None:
        """Advance ``steps`` steps known idle (:meth:`idle_steps`): as many :meth:`step` calls."""
        if steps <= 0:
            return
        if self._requests or not self._model.at_rest:
            raise RuntimeError(f"{self.drone}: skip({steps}) over steps that are not idle")
        self._model.rest(SIM_DT_S, steps)
        self._step_count += steps
        self._telemetry.catch_up(self.t_s)

    # -- observation ---------------------------------------------------------

    @property
    def t_s(self) -> float:
        """Simulated seconds since :meth:`start` (from the step count, never summed)."""
        return self._step_count * SIM_DT_S

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
    def pilot_flying(self) -> bool:
        """True while the scripted pilot has the controls."""
        return self._pilot.flying

    # -- bookkeeping ---------------------------------------------------------

    def _finish(self, act: _Action, result: ActionResult, finished: list[Finished]) -> None:
        self._actions.pop(act.handle.id, None)
        if self._motion is act:
            self._motion = None
        x, y, z = self._model.position
        self._log.info(
            "adapter.action.end",
            action=act.handle.action,
            args=list(act.handle.args),
            handle=act.handle.id,
            status=result.status,
            reason=result.reason,
            t_sim=round(self.t_s, 3),
            duration_sim_s=round(self.t_s - act.started_s, 3),
            x_m=round(x, 3),
            y_m=round(y, 3),
            z_m=round(z, 3),
        )
        finished.append((act.done, result))

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

    def _begin(self, act: _Action, finished: list[Finished]) -> None:
        command = act.command
        act.started_s = self.t_s
        self._log.info(
            "adapter.action.start",
            action=act.handle.action,
            args=list(act.handle.args),
            handle=act.handle.id,
            t_sim=round(self.t_s, 3),
        )
        reason = refusal(
            command, self.settings, self._model, self._motion is not None, self._aborting
        )
        if reason is not None:
            return self._finish(act, ActionResult("failed", reason), finished)
        self._actions[act.handle.id] = act
        model = self._model
        match command:
            case Payload():
                act.until_s = self.t_s + PAYLOAD_DELAY_S
            case PauseFor(duration_s=duration):
                act.until_s = self.t_s + duration
            case Arm():
                if model.armed:
                    return self._finish(act, ActionResult("ok"), finished)
                act.kind = "arm"
                act.deadline_s = self.t_s + self.settings.action_timeout_s
            case Disarm():
                if model.armed:
                    model.disarm()
                return self._finish(act, ActionResult("ok"), finished)
            case Land() if model.landed:
                return self._finish(act, ActionResult("ok"), finished)
            case _:  # a motion action, checked by _refusal
                self._motion = act
                if self._pilot.flying:
                    # Every motion action waits for the pilot's path to end (the
                    # pilot only starts after Takeoff, so only a repeated one meets it).
                    act.deferred = True
                    self._log.info(
                        "adapter.action.deferred", action=command.action, handle=act.handle.id
                    )
                    return None
                self._start_motion(act, finished)
        return None

    def _start_motion(self, act: _Action, finished: list[Finished]) -> None:
        """Command the model for a motion action (now, or when the pilot hands over)."""
        command, model = act.command, self._model
        act.deferred = False
        act.deadline_s = self.t_s + self.settings.action_timeout_s
        if isinstance(command, Land):
            if model.landed:
                return self._finish(act, ActionResult("ok"), finished)
            act.kind = "land"
            model.land()
            return None
        target = target_xyz(command, self._base_point())
        if target is None and isinstance(command, FlyToLLA):
            target = self._frame.from_lla(command.lat_deg, command.lon_deg, command.alt_m)
        if target is None:
            reason = f"{command.action} is not a motion the simulator knows"
            return self._finish(act, ActionResult("failed", reason), finished)
        if target[2] <= 0:
            reason = f"target z {target[2]:.2f} m is not above ground (use Land)"
            return self._finish(act, ActionResult("failed", reason), finished)
        act.kind = "motion"
        act.target = target
        model.set_target(*target)
        return None

    def _base_point(self) -> tuple[float, float, float]:
        """Where relative moves start: the held setpoint if we are there, else here.

        Using the setpoint keeps FlyBy sequences from accumulating the
        tolerance of each previous leg.
        """
        target = self._model.target
        if target is not None and self._model.distance_to(target) <= self.settings.tolerance_m:
            return target
        return self._model.position

    def _update_actions(self, finished: list[Finished]) -> None:
        model, s = self._model, self.settings
        for act in list(self._actions.values()):
            if act.deferred:
                continue
            if act.kind == "timer":
                if self.t_s >= act.until_s - _EPS_S:
                    self._finish(act, ActionResult("ok"), finished)
                continue
            if act.kind == "arm":
                if self.t_s >= s.arm_delay_s:
                    model.arm()
                if model.armed:
                    self._finish(act, ActionResult("ok"), finished)
                    continue
            elif act.kind == "land":
                if model.landed:
                    self._finish(act, ActionResult("ok"), finished)
                    continue
            elif (
                act.target is not None
                and model.distance_to(act.target) <= s.tolerance_m
                and model.state.speed_mps <= s.settle_speed_mps
            ):
                self._finish(act, ActionResult("ok"), finished)
                if isinstance(act.command, Takeoff):
                    self._pilot.take_off(model)
                continue
            if self.t_s >= act.deadline_s:
                if act.kind != "arm":
                    model.hold()
                what = "vehicle not armable" if act.kind == "arm" else "target not reached"
                self._finish(
                    act,
                    ActionResult("failed", f"timeout after {s.action_timeout_s:g} s: {what}"),
                    finished,
                )

    def _pilot_handed_over(self, finished: list[Finished]) -> None:
        """The pilot's path ended: a deferred motion action starts from where it left."""
        if self._motion is not None and self._motion.deferred:
            self._start_motion(self._motion, finished)

    def _update_abort(self) -> None:
        if self._aborting and self._model.landed:
            if self._model.armed:
                self._model.disarm()
            self._aborting = False
            self._log.info("adapter.abort.done", t_sim=round(self.t_s, 3))


__all__ = ["PAYLOAD_DELAY_S", "SIM_DT_S", "Finished", "SimCore"]
