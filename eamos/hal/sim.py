"""A simulated quadcopter adapter built on the kinematic model.

:class:`SimAdapter` runs one thread that steps a :class:`~eamos.hal.kinematics.Quadcopter`
every :data:`SIM_DT_S` simulated seconds.  The thread paces itself in wall time
with ``stop_event.wait(...)``: that wait *is* the simulator's clock, and
``speedup`` makes it run faster than real time.  Everything else (action
durations, timeouts, telemetry rate, pause lengths) is counted in simulated
steps, so a mission behaves the same at any speed-up, only faster.

Actions complete on real criteria checked after every step:

* ``Arm``: the armed flag is set (possible ``arm_delay_s`` after start, like
  pre-flight checks passing; an earlier ``Arm`` waits).
* ``Takeoff``/``FlyBy*``/``FlyTo*``: within ``tolerance_m`` of the target and
  slower than ``settle_speed_mps``.
* ``Land``: the landed flag is set.  ``Disarm``: immediate, on the ground only.
* ``PauseFor(s)``: ``s`` simulated seconds.  Payload actions: 0.2 simulated s.

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

import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, fields
from typing import Any, Literal

from eamos.hal.api import (
    ActionHandle,
    ActionResult,
    AdapterError,
    DoneCallback,
    Telemetry,
    TelemetryCallback,
)
from eamos.hal.kinematics import GeoFrame, Limits, Quadcopter, VehicleState
from eamos.hal.settings import (
    COMMON_KEYS,
    as_number,
    check_keys,
    did_you_mean,
    field_error,
    number,
    require_mapping,
    string_list,
)
from eamos.logs import make_logger
from eamos.program.uniform import ACTIONS, MOTION_ACTIONS, decode_command, target_xyz

#: Simulated seconds per model step.
SIM_DT_S = 0.02
#: Shortest wall-clock tick: at high speed-ups several steps run per tick, so
#: the thread wakes at most ~200 times a second on a shared machine.
MIN_WALL_TICK_S = 0.005
#: If the thread falls this far behind its wall schedule (a loaded machine),
#: the simulation slows down instead of bursting to catch up.
MAX_LAG_S = 0.1
#: Simulated duration of payload actions.
PAYLOAD_DELAY_S = 0.2
#: Simulated seconds between position log lines.
POSITION_LOG_PERIOD_S = 1.0

#: Motion actions that wait for the scripted pilot to finish its path (all of
#: them: the pilot only starts after Takeoff, so only a repeated one can meet it).
PILOT_DEFERRED = MOTION_ACTIONS


@dataclass(frozen=True)
class Waypoint:
    """One point of the scripted pilot's path (metres from home, hold in sim seconds)."""

    x_m: float
    y_m: float
    z_m: float
    hold_s: float = 0.0


@dataclass(frozen=True)
class SimSettings:
    """Settings of one simulated vehicle; build with :meth:`from_mapping`."""

    speedup: float = 1.0
    horizontal_speed_mps: float = 2.0
    climb_speed_mps: float = 1.0
    descent_speed_mps: float = 0.7
    accel_mps2: float = 2.0
    tolerance_m: float = 0.1
    settle_speed_mps: float = 0.2
    arm_delay_s: float = 2.0
    telemetry_hz: float = 10.0
    home_lat_deg: float = 46.6103
    home_lon_deg: float = 14.2640
    home_alt_m: float = 0.0
    battery_pct: float = 100.0
    drain_airborne_pct_per_min: float = 1.5
    drain_idle_pct_per_min: float = 0.1
    action_timeout_s: float = 120.0
    reject_actions: tuple[str, ...] = ()
    pilot: tuple[Waypoint, ...] = ()

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], prefix: str = "hal") -> SimSettings:
        """Validate ``mapping`` (the drone's ``hal`` settings) into settings.

        Raises :class:`AdapterError` ``"hal.<field>: <problem>"`` for a bad value
        or an unknown key (with a "did you mean" suggestion).
        """
        mapping = require_mapping(mapping, prefix)
        names = [f.name for f in fields(cls)]
        check_keys(mapping, set(names) | COMMON_KEYS, prefix)

        def num(key: str, **bounds: float) -> float:
            return number(mapping, key, getattr(cls, key), prefix, **bounds)

        reject: tuple[str, ...] = ()
        if "reject_actions" in mapping:
            path = f"{prefix}.reject_actions"
            reject = tuple(string_list(mapping["reject_actions"], path))
            for i, name in enumerate(reject):
                if name not in ACTIONS:
                    raise field_error(
                        f"{path}[{i}]", f"unknown action {name!r}{did_you_mean(name, ACTIONS)}"
                    )
        pilot = _pilot_path(mapping["pilot"], f"{prefix}.pilot") if "pilot" in mapping else ()
        return cls(
            speedup=num("speedup", gt=0),
            horizontal_speed_mps=num("horizontal_speed_mps", gt=0),
            climb_speed_mps=num("climb_speed_mps", gt=0),
            descent_speed_mps=num("descent_speed_mps", gt=0),
            accel_mps2=num("accel_mps2", gt=0),
            tolerance_m=num("tolerance_m", gt=0),
            settle_speed_mps=num("settle_speed_mps", gt=0),
            arm_delay_s=num("arm_delay_s", ge=0),
            telemetry_hz=num("telemetry_hz", gt=0),
            home_lat_deg=num("home_lat_deg", ge=-90, le=90),
            home_lon_deg=num("home_lon_deg", ge=-180, le=180),
            home_alt_m=num("home_alt_m"),
            battery_pct=num("battery_pct", ge=0, le=100),
            drain_airborne_pct_per_min=num("drain_airborne_pct_per_min", ge=0),
            drain_idle_pct_per_min=num("drain_idle_pct_per_min", ge=0),
            action_timeout_s=num("action_timeout_s", gt=0),
            reject_actions=reject,
            pilot=pilot,
        )

    @property
    def limits(self) -> Limits:
        """The kinematic limits these settings describe."""
        return Limits(
            horizontal_speed_mps=self.horizontal_speed_mps,
            climb_speed_mps=self.climb_speed_mps,
            descent_speed_mps=self.descent_speed_mps,
            accel_mps2=self.accel_mps2,
            drain_airborne_pct_per_min=self.drain_airborne_pct_per_min,
            drain_idle_pct_per_min=self.drain_idle_pct_per_min,
        )

    @property
    def frame(self) -> GeoFrame:
        """The local/global frame around this vehicle's home."""
        return GeoFrame(self.home_lat_deg, self.home_lon_deg, self.home_alt_m)


def _pilot_path(value: Any, path: str) -> tuple[Waypoint, ...]:
    if isinstance(value, str) or not isinstance(value, list | tuple):
        raise field_error(path, f"expected a list of waypoints, got {value!r}")
    points = []
    for i, raw in enumerate(value):
        where = f"{path}[{i}]"
        item = require_mapping(raw, where)
        check_keys(item, ("x_m", "y_m", "z_m", "hold_s"), where)
        for key in ("x_m", "y_m", "z_m"):
            if key not in item:
                raise field_error(f"{where}.{key}", "missing")
        points.append(
            Waypoint(
                x_m=as_number(item["x_m"], f"{where}.x_m"),
                y_m=as_number(item["y_m"], f"{where}.y_m"),
                # The pilot flies; landing is the mission's (or abort's) business.
                z_m=as_number(item["z_m"], f"{where}.z_m", gt=0),
                hold_s=as_number(item.get("hold_s", 0.0), f"{where}.hold_s", ge=0),
            )
        )
    return tuple(points)


_Kind = Literal["arm", "motion", "land", "timer"]


@dataclass(eq=False)
class _Action:
    """A running action inside the simulator thread."""

    handle: ActionHandle
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
    """An :class:`~eamos.hal.api.Adapter` driving a simulated quadcopter (see module doc)."""

    def __init__(
        self, drone: str, settings: SimSettings | None = None, adapter_log: Any = None
    ) -> None:
        self.drone = drone
        self.settings = settings or SimSettings()
        self._log = adapter_log if adapter_log is not None else make_logger(None)
        self._frame = self.settings.frame
        self._model = Quadcopter(self.settings.limits, battery_pct=self.settings.battery_pct)
        # One lock guards the model and all bookkeeping; the condition lets
        # observers (tests, tools) wait for the next simulator tick.
        self._lock = threading.Lock()
        self._tick_cond = threading.Condition(self._lock)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._closed = False
        self._on_telemetry: TelemetryCallback | None = None
        self._requests: deque[_Request] = deque()
        self._actions: dict[int, _Action] = {}
        self._motion: _Action | None = None
        self._t = 0.0  # simulated seconds since start
        self._aborting = False
        self._pilot_state: Literal["idle", "flying", "done"] = (
            "idle" if self.settings.pilot else "done"
        )
        self._pilot_index = 0
        self._pilot_hold_until: float | None = None
        self._next_sample_s = 0.0
        self._last_sample_key: tuple[Any, ...] | None = None
        self._next_position_log_s = 0.0
        self._last_position_key: tuple[Any, ...] | None = None

    # -- Adapter protocol ----------------------------------------------------

    def start(self, on_telemetry: TelemetryCallback) -> None:
        """Start the simulator thread and send the first telemetry sample."""
        with self._lock:
            if self._closed:
                raise AdapterError(f"{self.drone}: simulator already closed")
            if self._thread is not None:
                raise AdapterError(f"{self.drone}: simulator already started")
            self._on_telemetry = on_telemetry
            first = self._sample()
            self._last_sample_key = first.state()
            self._next_sample_s = 1.0 / self.settings.telemetry_hz
            s = self.settings
            self._log.info(
                "adapter.start",
                adapter="sim",
                speedup=s.speedup,
                home_lat_deg=s.home_lat_deg,
                home_lon_deg=s.home_lon_deg,
                home_alt_m=s.home_alt_m,
                battery_pct=s.battery_pct,
                pilot_waypoints=len(s.pilot),
                reject_actions=list(s.reject_actions),
            )
            self._thread = threading.Thread(
                target=self._loop, name=f"sim-{self.drone}", daemon=True
            )
        self._emit([first])
        self._thread.start()

    def run(self, action: str, args: tuple[float, ...], done: DoneCallback) -> ActionHandle:
        """Queue ``action``; the simulator thread starts it at its next step."""
        handle = ActionHandle(action, tuple(args))
        with self._lock:
            if self._closed:
                raise AdapterError(f"{self.drone}: simulator closed")
            self._requests.append(_Request("run", action=_Action(handle, done)))
        return handle

    def cancel(self, handle: ActionHandle) -> None:
        """Interrupt ``handle``: the vehicle holds where it is; done gets "cancelled"."""
        with self._lock:
            if not self._closed:
                self._requests.append(_Request("cancel", handle=handle))

    def abort(self) -> None:
        """Cancel every action, take control from the pilot, land, then disarm."""
        with self._lock:
            if not self._closed:
                self._requests.append(_Request("abort"))

    def close(self) -> None:
        """Stop the simulator thread; actions still running end "cancelled". Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            thread = self._thread
        self._stop.set()
        if thread is not None and thread is not threading.current_thread():
            thread.join()
        finished: list[tuple[DoneCallback, ActionResult]] = []
        with self._lock:
            pending = [r.action for r in self._requests if r.action is not None]
            for act in [*self._actions.values(), *pending]:
                self._finish(act, ActionResult("cancelled", "adapter closed"), finished)
            self._requests.clear()
            self._log.info("adapter.close", t_sim=round(self._t, 3))
            self._tick_cond.notify_all()
        self._deliver(finished)

    # -- observation (tests, tools) ------------------------------------------

    @property
    def state(self) -> VehicleState:
        """A snapshot of the simulated vehicle."""
        with self._lock:
            return self._model.state

    @property
    def sim_time_s(self) -> float:
        """Simulated seconds since :meth:`start`."""
        with self._lock:
            return self._t

    @property
    def pilot_flying(self) -> bool:
        """True while the scripted pilot has the controls."""
        with self._lock:
            return self._pilot_state == "flying"

    def wait_until(self, predicate: Callable[[VehicleState], bool], timeout: float) -> bool:
        """Block until ``predicate(state)`` holds after a tick; False on timeout or close.

        The predicate runs with the simulator's lock held: it must only look at
        the state it is given (not call this adapter).
        """
        deadline = time.monotonic() + timeout
        with self._tick_cond:
            while not predicate(self._model.state):
                remaining = deadline - time.monotonic()
                if remaining <= 0 or self._closed:
                    return False
                self._tick_cond.wait(remaining)
            return True

    # -- simulator thread ----------------------------------------------------

    def _loop(self) -> None:
        for steps in paced_ticks(self._stop, self.settings.speedup):
            try:
                self._tick(steps)
            except Exception as exc:  # keep the adapter's promise: done is always called
                self._log.exception("adapter.error", error=repr(exc))
                self._crash(exc)
                return

    def _crash(self, exc: Exception) -> None:
        finished: list[tuple[DoneCallback, ActionResult]] = []
        with self._lock:
            self._closed = True
            pending = [r.action for r in self._requests if r.action is not None]
            for act in [*self._actions.values(), *pending]:
                self._finish(act, ActionResult("failed", f"simulator error: {exc!r}"), finished)
            self._requests.clear()
            self._tick_cond.notify_all()
        self._deliver(finished)

    def _tick(self, steps: int) -> None:
        finished: list[tuple[DoneCallback, ActionResult]] = []
        samples: list[Telemetry] = []
        with self._lock:
            for _ in range(steps):
                self._handle_requests(finished)
                self._model.step(SIM_DT_S)
                self._t += SIM_DT_S
                self._update_pilot(finished)
                self._update_actions(finished)
                self._update_abort()
                self._observe(samples)
            self._tick_cond.notify_all()
        self._deliver(finished)
        self._emit(samples)

    def _deliver(self, finished: list[tuple[DoneCallback, ActionResult]]) -> None:
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

    # -- bookkeeping (called with the lock held) -----------------------------

    def _finish(
        self,
        act: _Action,
        result: ActionResult,
        finished: list[tuple[DoneCallback, ActionResult]],
    ) -> None:
        self._actions.pop(act.handle.id, None)
        if self._motion is act:
            self._motion = None
        self._log.info(
            "adapter.action.end",
            action=act.handle.action,
            args=list(act.handle.args),
            handle=act.handle.id,
            status=result.status,
            reason=result.reason,
            t_sim=round(self._t, 3),
            duration_sim_s=round(self._t - act.started_s, 3),
            x_m=round(self._model.position[0], 3),
            y_m=round(self._model.position[1], 3),
            z_m=round(self._model.position[2], 3),
        )
        finished.append((act.done, result))

    def _handle_requests(self, finished: list[tuple[DoneCallback, ActionResult]]) -> None:
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

    def _abort(self, finished: list[tuple[DoneCallback, ActionResult]]) -> None:
        self._log.info("adapter.abort", t_sim=round(self._t, 3), pilot=self._pilot_state)
        for act in list(self._actions.values()):
            self._finish(act, ActionResult("cancelled", "aborted"), finished)
        if self._pilot_state == "flying":
            self._log.info("adapter.pilot.end", reason="aborted")
        self._pilot_state = "done"
        self._aborting = True
        self._model.land()

    def _begin(self, act: _Action, finished: list[tuple[DoneCallback, ActionResult]]) -> None:
        name, args = act.handle.action, act.handle.args
        act.started_s = self._t
        self._log.info(
            "adapter.action.start",
            action=name,
            args=list(args),
            handle=act.handle.id,
            t_sim=round(self._t, 3),
        )

        def fail(reason: str) -> None:
            self._finish(act, ActionResult("failed", reason), finished)

        spec = ACTIONS.get(name)
        if spec is None:
            return fail(f"unknown action {name!r}")
        if len(args) != len(spec.params):
            return fail(f"{name} takes {len(spec.params)} argument(s), got {len(args)}")
        if not all(isinstance(a, int | float) and math.isfinite(a) for a in args):
            return fail(f"{name}: arguments must be finite numbers, got {list(args)}")
        if name in self.settings.reject_actions:
            return fail("rejected by vehicle")
        if self._aborting and not spec.payload and name != "PauseFor":
            return fail("aborting")
        self._actions[act.handle.id] = act
        model = self._model

        if spec.payload:
            act.until_s = self._t + PAYLOAD_DELAY_S
        elif name == "PauseFor":
            if args[0] < 0:
                return fail("duration_s must be >= 0")
            act.until_s = self._t + args[0]
        elif name == "Arm":
            if model.armed:
                return self._finish(act, ActionResult("ok"), finished)
            act.kind = "arm"
            act.deadline_s = self._t + self.settings.action_timeout_s
        elif name == "Disarm":
            if not model.armed:
                return self._finish(act, ActionResult("ok"), finished)
            if not model.landed:
                return fail("in the air")
            if self._motion is not None:
                return fail("busy")  # e.g. a Takeoff about to lift off
            model.disarm()
            return self._finish(act, ActionResult("ok"), finished)
        else:  # motion
            if self._motion is not None:
                return fail("busy")
            if name == "Takeoff":
                if args[0] <= 0:
                    return fail("height_m must be > 0")
                if not model.armed:
                    return fail("not armed")
            elif name == "Land":
                if model.landed:
                    return self._finish(act, ActionResult("ok"), finished)
            elif model.landed:
                return fail("not flying")
            self._motion = act
            if self._pilot_state == "flying" and name in PILOT_DEFERRED:
                act.deferred = True
                self._log.info("adapter.action.deferred", action=name, handle=act.handle.id)
                return None
            self._start_motion(act, finished)
        return None

    def _start_motion(
        self, act: _Action, finished: list[tuple[DoneCallback, ActionResult]]
    ) -> None:
        """Command the model for a motion action (now, or when the pilot hands over)."""
        name, args = act.handle.action, act.handle.args
        model = self._model
        act.deferred = False
        act.deadline_s = self._t + self.settings.action_timeout_s
        if name == "Land":
            if model.landed:
                return self._finish(act, ActionResult("ok"), finished)
            act.kind = "land"
            model.land()
            return None
        base = self._base_point()
        target = target_xyz(decode_command(name, args), base)
        if target is None:  # FlyToLLA
            target = self._frame.from_lla(args[0], args[1], args[2])
        if target[2] <= 0:
            return self._finish(
                act,
                ActionResult(
                    "failed", f"target z {target[2]:.2f} m is not above ground (use Land)"
                ),
                finished,
            )
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

    def _update_actions(self, finished: list[tuple[DoneCallback, ActionResult]]) -> None:
        model, s = self._model, self.settings
        for act in list(self._actions.values()):
            if act.deferred:
                continue
            if act.kind == "timer":
                # A small epsilon absorbs float error in the summed step times.
                if self._t >= act.until_s - 1e-9:
                    self._finish(act, ActionResult("ok"), finished)
                continue
            if act.kind == "arm":
                if self._t >= s.arm_delay_s:
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
                if act.handle.action == "Takeoff":
                    self._start_pilot()
                continue
            if self._t >= act.deadline_s:
                if act.kind != "arm":
                    model.hold()
                what = "vehicle not armable" if act.kind == "arm" else "target not reached"
                self._finish(
                    act,
                    ActionResult("failed", f"timeout after {s.action_timeout_s:g} s: {what}"),
                    finished,
                )

    def _start_pilot(self) -> None:
        if self._pilot_state != "idle" or self._model.landed:
            return
        self._pilot_state = "flying"
        self._pilot_index = 0
        self._pilot_hold_until = None
        self._log.info("adapter.pilot.start", waypoints=len(self.settings.pilot))
        wp = self.settings.pilot[0]
        self._model.set_target(wp.x_m, wp.y_m, wp.z_m)

    def _update_pilot(self, finished: list[tuple[DoneCallback, ActionResult]]) -> None:
        if self._pilot_state != "flying":
            return
        s = self.settings
        wp = s.pilot[self._pilot_index]
        if self._pilot_hold_until is None:
            if self._model.at_target(s.tolerance_m, s.settle_speed_mps):
                self._pilot_hold_until = self._t + wp.hold_s
                x, y, z = self._model.position
                self._log.info(
                    "adapter.pilot.waypoint",
                    index=self._pilot_index,
                    x_m=round(x, 3),
                    y_m=round(y, 3),
                    z_m=round(z, 3),
                    t_sim=round(self._t, 3),
                )
            return
        if self._t < self._pilot_hold_until - 1e-9:
            return
        self._pilot_index += 1
        self._pilot_hold_until = None
        if self._pilot_index < len(s.pilot):
            nxt = s.pilot[self._pilot_index]
            self._model.set_target(nxt.x_m, nxt.y_m, nxt.z_m)
            return
        # The path is over: hand the controls back to the mission.
        self._pilot_state = "done"
        self._log.info("adapter.pilot.end", reason="path finished", t_sim=round(self._t, 3))
        if self._motion is not None and self._motion.deferred:
            self._start_motion(self._motion, finished)

    def _update_abort(self) -> None:
        if self._aborting and self._model.landed:
            if self._model.armed:
                self._model.disarm()
            self._aborting = False
            self._log.info("adapter.abort.done", t_sim=round(self._t, 3))

    def _sample(self) -> Telemetry:
        st = self._model.state
        lat, lon, alt = self._frame.to_lla(st.x_m, st.y_m, st.z_m)
        return Telemetry(
            drone=self.drone,
            time_s=time.time(),
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

    def _observe(self, samples: list[Telemetry]) -> None:
        if self._t >= self._next_sample_s - 1e-9:
            while self._next_sample_s <= self._t + 1e-9:
                self._next_sample_s += 1.0 / self.settings.telemetry_hz
            sample = self._sample()
            key = sample.state()
            if key != self._last_sample_key:
                self._last_sample_key = key
                samples.append(sample)
        if self._t >= self._next_position_log_s - 1e-9:
            self._next_position_log_s += POSITION_LOG_PERIOD_S
            st = self._model.state
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
                    t_sim=round(self._t, 3),
                )


def sim_adapter_from_settings(
    drone: str, settings: Mapping[str, Any], adapter_log: Any = None
) -> SimAdapter:
    """Build a :class:`SimAdapter` from a drone's ``hal`` settings mapping."""
    return SimAdapter(drone, SimSettings.from_mapping(settings), adapter_log)


__all__ = [
    "MOTION_ACTIONS",
    "SIM_DT_S",
    "SimAdapter",
    "SimSettings",
    "Waypoint",
    "sim_adapter_from_settings",
]
