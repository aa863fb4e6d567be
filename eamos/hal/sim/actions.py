"""How the simulated vehicle's actions start, progress and end (the base of ``SimCore``).

Split from :mod:`eamos.hal.sim.core` by responsibility: :class:`ActionRules` holds the
action lifecycle (refusals, timers, arming, moves to a target, the guided motions of
:mod:`eamos.hal.sim.motions`, ``ReturnHome``'s two phases, plugin actions, timeouts);
:class:`~eamos.hal.sim.core.SimCore` adds requests, stepping, idling and observation.
Pure: no thread, no clock read, but for one thing it does not control: a plugin action's
"sim" implementation runs on a thread of its own under a wall-clock deadline
(:meth:`~eamos.program.plugins.PluginRegistry.call`).  Its owner says whether the core
waits for the outcome (the virtual-time driver: a run stays the same run) or looks for it
at every step (the real-time adapter: the vehicle flies on, and can land, meanwhile).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

from eamos.hal.api import ActionHandle, ActionResult, DoneCallback
from eamos.hal.kinematics import GeoFrame, Quadcopter
from eamos.hal.sim.motions import (
    YAW_RATE_DEG_S,
    OrbitGuide,
    orbit_speed_mps,
    refusal,
    turn_towards,
)
from eamos.hal.sim.pilot import ScriptedPilot
from eamos.hal.sim.plugin_api import SimOutcome, SimView
from eamos.hal.sim.settings import SimSettings
from eamos.hal.sim.telemetry import EPS_S
from eamos.program.plugins import PluginCall, PluginRegistry
from eamos.program.uniform import (
    Arm,
    Command,
    Disarm,
    FlyToLLA,
    Hold,
    Land,
    Orbit,
    PauseFor,
    Payload,
    PluginAction,
    ReturnHome,
    SetSpeed,
    Takeoff,
    Yaw,
    target_xyz,
)

if TYPE_CHECKING:
    from eamos.logs import EventLog

#: Simulated seconds per model step.
SIM_DT_S = 0.02
#: Simulated duration of payload actions.
PAYLOAD_DELAY_S = 0.2
_EPS_S = EPS_S

#: Fields of an ``adapter.plugin`` line the line (or the logger) writes itself: a
#: plugin's ``SimOutcome.log`` may not use them.
PLUGIN_LOG_TAKEN = frozenset(
    {"event", "action", "args", "handle", "t_sim", "drone", "level", "ts", "exc_info", "exception"}
)

#: A finished action: its done callback and its result (the caller invokes it).
Finished = tuple[DoneCallback, ActionResult]

# "motion": to a fixed target; "orbit": a moving one (guide); "home": above home, then
# "land"; "yaw": turning on the spot; "plugin": its implementation computes the outcome.
_Kind = Literal["arm", "motion", "liftoff", "land", "timer", "orbit", "home", "yaw", "plugin"]


@dataclass(eq=False)
class SimAction:
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
    touched_down: bool = False  # "land": on the ground, its detector not yet reporting
    guide: OrbitGuide | None = None  # "orbit": the moving setpoint
    heading_deg: float = 0.0  # "yaw": the heading turned to
    call: PluginCall | None = None  # "plugin": the implementation's call


@dataclass(frozen=True)
class SimRequest:
    """A request queued for the next step: run an action, cancel one, or abort."""

    op: Literal["run", "cancel", "abort"]
    action: SimAction | None = None
    handle: ActionHandle | None = None


class ActionRules:
    """The action lifecycle of one simulated vehicle; :class:`SimCore` is the only subclass.

    The state it works on is created by ``SimCore.__init__``.
    """

    drone: str
    settings: SimSettings
    plugins: PluginRegistry
    #: Wait for a plugin's outcome when the action starts (else: look at every step).
    wait_for_plugins: bool
    _log: EventLog
    _frame: GeoFrame
    _model: Quadcopter
    _pilot: ScriptedPilot
    _actions: dict[int, SimAction]
    _motion: SimAction | None
    _aborting: bool
    _heading_deg: float
    _payload: dict[str, float]
    _step_count: int

    @property
    def t_s(self) -> float:
        """Simulated seconds since start (from the step count, never summed)."""
        return self._step_count * SIM_DT_S

    def _finish(self, act: SimAction, result: ActionResult, finished: list[Finished]) -> None:
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
            heading_deg=round(self._heading_deg, 1),
            **({"payload": dict(self._payload)} if isinstance(act.command, PluginAction) else {}),
        )
        finished.append((act.done, result))

    def _begin(self, act: SimAction, finished: list[Finished]) -> None:
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
            case PluginAction():
                return self._begin_plugin(act, command, finished)
            case PauseFor(duration_s=duration) | Hold(duration_s=duration):
                act.until_s = self.t_s + duration
            case SetSpeed(speed_m_s=speed):
                speed *= self.settings.disturbance_speed_factor  # the disturbance stays
                model.limits = dataclasses.replace(model.limits, horizontal_speed_mps=speed)
                return self._finish(act, ActionResult("ok"), finished)
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

    def _begin_plugin(
        self, act: SimAction, command: PluginAction, finished: list[Finished]
    ) -> None:
        """Start a plugin action's "sim" implementation on its own thread (docs/plugins.md).

        Its outcome makes the action a timer counted from the action's start (or fails
        it); until the outcome comes the action is ``"plugin"``, looked at every step.
        """
        x, y, z = self._model.position
        view = SimView(
            self.drone,
            self.t_s,
            x,
            y,
            z,
            self._heading_deg,
            self._model.armed,
            self._model.landed,
            dict(self._payload),
        )
        act.kind = "plugin"
        act.call = self.plugins.call(
            command.name, "sim", (view, command), self.settings.plugin_deadline_s
        )
        if self.wait_for_plugins:
            act.call.wait()
        self._plugin_progress(act, command, finished)

    def _plugin_progress(
        self, act: SimAction, command: PluginAction, finished: list[Finished]
    ) -> None:
        """Apply a plugin action's outcome once its implementation gave one (or failed)."""
        assert act.call is not None
        answer = act.call.poll()
        if answer is None:
            return  # still computing, its deadline ahead
        act.call = None
        outcome = answer.value
        if answer.failed:
            reason = answer.failed
        elif not isinstance(outcome, SimOutcome):
            reason = (
                f"plugin action {command.name!r} failed in its sim implementation: "
                f"returned {type(outcome).__name__}, not SimOutcome"
            )
        else:
            reason = outcome.failed or _outcome_problem(command.name, outcome)
        if reason:
            return self._finish(act, ActionResult("failed", reason), finished)
        assert isinstance(outcome, SimOutcome)
        self._payload.update(outcome.payload)
        self._log.info(
            "adapter.plugin",
            action=command.name,
            args=list(command.values),
            handle=act.handle.id,
            t_sim=round(self.t_s, 3),
            **dict(outcome.log),
        )
        act.kind = "timer"
        act.until_s = act.started_s + outcome.duration_s
        return None

    def _guide(self) -> None:
        """Before a model step: move the setpoints of guided motions (orbit, yaw)."""
        motion = self._motion
        if motion is None or motion.deferred:
            return
        if motion.kind == "orbit" and motion.guide is not None:
            guide = motion.guide
            if guide.finished:
                return
            self._model.set_target(*guide.advance(SIM_DT_S))
            self._heading_deg = guide.heading_deg()
            if guide.finished:
                # Whole turns end exactly where the orbit started (no float drift);
                # a fractional last turn ends on the circle, never across it.
                if isinstance(motion.command, Orbit) and motion.command.turns.is_integer():
                    motion.target = motion.target or guide.point(guide.total_rad)
                else:
                    motion.target = guide.point(guide.total_rad)
                self._model.set_target(*motion.target)
        elif motion.kind == "yaw":
            self._heading_deg = turn_towards(
                self._heading_deg, motion.heading_deg, YAW_RATE_DEG_S * SIM_DT_S
            )

    def _start_motion(self, act: SimAction, finished: list[Finished]) -> None:
        """Command the model for a motion action (now, or when the pilot hands over)."""
        command, model, s = act.command, self._model, self.settings
        act.deferred = False
        act.deadline_s = self.t_s + self.settings.action_timeout_s
        if isinstance(command, Land):
            if model.landed:
                return self._finish(act, ActionResult("ok"), finished)
            act.kind = "land"
            model.land()
            return None
        if isinstance(command, Yaw):
            act.kind = "yaw"
            act.heading_deg = command.heading_deg % 360.0
            return None
        if isinstance(command, ReturnHome):
            act.kind = "home"  # above home at the current height, then "land"
            act.target = (0.0, 0.0, max(model.position[2], s.tolerance_m))
            model.set_target(*act.target)
            return None
        if isinstance(command, Orbit):
            lim = model.limits
            speed = orbit_speed_mps(lim.horizontal_speed_mps, lim.accel_mps2, command.radius_m)
            here = self._base_point()
            guide = OrbitGuide.start(here, self._heading_deg, command, speed)
            act.kind, act.guide, act.target = "orbit", guide, here
            act.deadline_s += guide.duration_s  # the timeout counts after the circle's time
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
        act.target = target
        if isinstance(command, Takeoff) and model.landed and s.liftoff_delay_s > 0:
            act.kind = "liftoff"  # the motors spool up first
            act.until_s = self.t_s + s.liftoff_delay_s
            return None
        act.kind = "motion"
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
            if act.kind == "plugin" and isinstance(act.command, PluginAction):
                self._plugin_progress(act, act.command, finished)
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
            elif act.kind == "liftoff":
                if self.t_s >= act.until_s - _EPS_S and act.target is not None:
                    act.kind = "motion"
                    model.set_target(*act.target)
            elif act.kind == "land":
                if model.landed and s.land_detect_s > 0 and not act.touched_down:
                    act.touched_down = True  # its land detector reports it a moment later
                    act.until_s = self.t_s + s.land_detect_s
                if model.landed and (s.land_detect_s <= 0 or self.t_s >= act.until_s - _EPS_S):
                    if isinstance(act.command, ReturnHome):
                        model.disarm()  # as both autopilots' RTL does after touchdown
                    self._finish(act, ActionResult("ok"), finished)
                    continue
            elif act.kind == "yaw":
                if self._heading_deg == act.heading_deg:
                    self._finish(act, ActionResult("ok"), finished)
                    continue
            elif act.kind == "orbit":
                if (
                    act.guide is not None
                    and act.guide.finished
                    and model.at_target(s.tolerance_m, s.settle_speed_mps)
                ):
                    self._finish(act, ActionResult("ok"), finished)
                    continue
            elif act.kind == "home":
                if act.target is not None and model.at_target(s.tolerance_m, s.settle_speed_mps):
                    act.kind = "land"  # above home: now land there
                    act.deadline_s = self.t_s + s.action_timeout_s
                    model.land()
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


def _outcome_problem(name: str, outcome: SimOutcome) -> str:
    """What in a plugin's outcome the simulator cannot use ("" when nothing): its fields
    are the plugin's, checked here so that a bad one fails the action, not the vehicle."""
    where = f"plugin action {name!r} failed in its sim implementation: SimOutcome"
    duration = outcome.duration_s
    if isinstance(duration, bool) or not isinstance(duration, int | float):
        return f"{where}.duration_s is {duration!r}, not a number"
    if not 0.0 <= duration < math.inf:
        return f"{where}.duration_s is {duration!r}, not a finite number >= 0"
    payload, log = outcome.payload, outcome.log
    if not isinstance(payload, Mapping) or not all(
        isinstance(k, str) and isinstance(v, int | float) and not isinstance(v, bool)
        for k, v in payload.items()
    ):
        return f"{where}.payload must map names to numbers"
    if not isinstance(log, Mapping) or not all(isinstance(k, str) for k in log):
        return f"{where}.log must map field names to values"
    taken = sorted(set(log) & PLUGIN_LOG_TAKEN)
    if taken:
        return f"{where}.log uses field(s) the adapter log writes itself: {', '.join(taken)}"
    return ""


__all__ = [
    "PAYLOAD_DELAY_S",
    "PLUGIN_LOG_TAKEN",
    "SIM_DT_S",
    "ActionRules",
    "Finished",
    "SimAction",
    "SimRequest",
]
