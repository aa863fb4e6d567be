"""Arming and disarming a MAVLink vehicle (:class:`Arming`), and what comes before them.

Before arming: wait for a settled position estimate (``adapter.estimator.*`` in the log);
before re-arming: see that the vehicle really disarmed itself.

PX4 main accepts arming long before its estimate settles (the notes), so the
adapter's Arm waits, after the pre-arm checks, for the estimator's flags
(:mod:`eamos.hal.mavlink.estimator`).  An autopilot that reports neither
ESTIMATOR_STATUS nor EKF_STATUS_REPORT within
:data:`~eamos.hal.mavlink.estimator.REPORT_GRACE_S` (older firmware, other
stacks) is not waited for.

The armed flag comes only with a HEARTBEAT (1 Hz), so the adapter's view may
lag an auto-disarm (DISARM_DELAY, COM_DISARM_PRFLT) by up to a period: a
Takeoff sent in that moment is refused (ArduCopter: MAV_CMD_NAV_TAKEOFF
FAILED), and :func:`disarmed_on_ground` asks a newer HEARTBEAT before the
adapter re-arms.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

from eamos.hal.api import ActionResult
from eamos.hal.mavlink.autopilots import CommandRejected
from eamos.hal.mavlink.command_protocol import MAV_RESULT_TEMPORARILY_REJECTED
from eamos.hal.mavlink.control import RunControl
from eamos.hal.mavlink.estimator import REPORT_GRACE_S, describe, estimator_message, verdict
from eamos.hal.mavlink.state import result_name
from eamos.hal.mavlink.waits import Failed, Run, Waiter

if TYPE_CHECKING:
    from eamos.hal.mavlink.vehicle import MavlinkVehicle

MAV_CMD_COMPONENT_ARM_DISARM = 400
ARM = (1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
DISARM = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
#: After a refused arming (TEMPORARILY_REJECTED), try again this much later.
ARM_RETRY_S = 1.0


def await_settled(waiter: Waiter, v: MavlinkVehicle, run: Run, deadline: float) -> None:
    """Before arming: wait until the estimator reports a settled estimate (until ``deadline``).

    Logs ``adapter.estimator.wait`` (with what is missing) and
    ``adapter.estimator.settled`` (with how long it took), or
    ``adapter.estimator.unreported`` when no report came within
    :data:`REPORT_GRACE_S`; raises :class:`~eamos.hal.mavlink.waits.TimedOut` with the
    flags still missing at ``deadline``.
    """
    s = v.settings
    name = v.autopilot.name

    def good(flags: int | None) -> bool | None:
        return verdict(flags, name)  # before arming: on the ground

    with v.cond:
        flags = v.state.estimator_flags
    if good(flags):
        return
    began = time.monotonic()
    if flags is None:
        waiter.wait(
            run,
            lambda st: st.estimator_flags is not None,
            min(deadline, began + s.scaled(REPORT_GRACE_S)),
            lambda st: "",
            quiet_timeout=True,
        )
        with v.cond:
            flags = v.state.estimator_flags
        if flags is None:
            v.log.info(
                "adapter.estimator.unreported",
                message=estimator_message(v.autopilot.name),
                note="no estimator report: arming on the pre-arm checks alone",
            )
            return
        if good(flags):
            return
    v.log.info("adapter.estimator.wait", flags=flags, why=describe(flags, name))
    waiter.wait(
        run,
        lambda st: bool(good(st.estimator_flags)),
        deadline,
        lambda st: (
            f"the vehicle's position estimate did not settle within {s.armable_timeout_s:g} s "
            f"({describe(st.estimator_flags or 0, name)})"
        ),
    )
    v.log.info("adapter.estimator.settled", waited_s=round(time.monotonic() - began, 2))


def disarmed_on_ground(waiter: Waiter, v: MavlinkVehicle, run: Run) -> bool:
    """After a refused or failed take-off: is the vehicle disarmed on the ground?

    While the latest HEARTBEAT still shows it armed, waits (at most
    ``waiter.confirm_s()``) for one that arrives after the refusal: it was sent
    after the vehicle refused, so it shows the state the vehicle refused in.
    """
    with v.cond:
        armed, seen = v.state.armed, v.state.heartbeats
    if armed:
        waiter.wait(
            run,
            lambda st: st.heartbeats > seen,
            time.monotonic() + waiter.confirm_s(),
            lambda st: "",
            quiet_timeout=True,
        )
    with v.cond:
        st = v.state
        return not st.armed and v.on_ground(st)


class Arming:
    """Arming and disarming one vehicle, and whether the mission wants it armed.

    Arm waits until the vehicle is armable and its estimate settled, prepares it (mode,
    stream), arms (again after a temporary refusal) and sees the armed flag in a
    HEARTBEAT; Disarm only on the ground, seen in a HEARTBEAT too.  ``armed_by_us``
    (condition held) is what a take-off reads to re-arm a vehicle that disarmed itself.
    """

    def __init__(self, waiter: Waiter) -> None:
        self.waiter = waiter
        self.v = waiter.v
        self.s = waiter.v.settings
        #: Our Arm succeeded and no Disarm of ours followed (the mission wants it armed).
        self.armed_by_us = False

    def arm(self, run: Run, ctl: RunControl) -> ActionResult:
        """Wait until armable, prepare (mode, stream), arm, see the armed flag."""
        v, s = self.v, self.s
        with v.cond:
            if v.state.armed:
                return ActionResult("ok")  # already armed is success
        deadline = run.started + s.scaled(s.armable_timeout_s)
        self.arm_now(run, ctl, deadline)
        return ActionResult("ok")

    def arm_now(self, run: Run, ctl: RunControl, deadline: float) -> None:
        """Wait until armable (until ``deadline``), prepare, arm, see the armed flag."""
        v, s = self.v, self.s
        self.waiter.wait(
            run,
            v.armable,
            deadline,
            lambda st: (
                f"vehicle never became armable within {s.armable_timeout_s:g} s: "
                f"{st.last_statustext or 'no STATUSTEXT from the vehicle'}"
            ),
        )
        # The pre-arm bit is not enough: PX4 main accepts arming long before its estimate
        # settles, and home taken from that estimate is metres off.
        await_settled(self.waiter, v, run, deadline)
        with v.cond:
            v.capture_origin(ground=True)
            here = v.here_ned()
        v.geofence.before_arming(lambda: run.finished)  # the fleet's fence, once (geofence.py)
        v.autopilot.prepare_arm(ctl, here)
        while True:
            try:
                ctl.command(MAV_CMD_COMPONENT_ARM_DISARM, ARM)
                break
            except CommandRejected as exc:
                with v.cond:
                    if v.state.armed:
                        break
                temporary = exc.result == result_name(MAV_RESULT_TEMPORARILY_REJECTED)
                if temporary and time.monotonic() + ARM_RETRY_S < deadline:
                    ctl.pause(ARM_RETRY_S)  # not ready yet: PX4 says so, try again
                    continue
                why = f": {exc.statustext}" if exc.statustext else ""
                until = f" until the {s.armable_timeout_s:g} s armable timeout" if temporary else ""
                raise Failed(f"arming refused ({exc.result}{until}){why}") from exc
        # PX4's HEARTBEAT may show the armed flag up to a second after the ack.
        self.waiter.wait(
            run,
            lambda st: st.armed,
            time.monotonic() + self.waiter.confirm_s(),
            lambda st: "vehicle acknowledged arming but its HEARTBEAT never showed it armed",
        )
        with v.cond:
            self.armed_by_us = True

    def rearm(self, run: Run, ctl: RunControl) -> None:
        """Arm again a vehicle that disarmed itself after our Arm (``adapter.rearm``)."""
        v, s = self.v, self.s
        with v.cond:
            why = v.state.last_statustext
            here = v.here_ned()
        v.log.warning("adapter.rearm", reason=why or "vehicle disarmed itself")
        # PX4 left in OFFBOARD without a stream is never armable: stream first.
        v.autopilot.prepare_arm(ctl, here)
        self.arm_now(run, ctl, time.monotonic() + s.scaled(s.armable_timeout_s))

    def disarm(self, run: Run, ctl: RunControl) -> ActionResult:
        """Disarm on the ground ("in the air" otherwise); see the flag drop."""
        v = self.v
        with v.cond:
            if not v.state.armed:
                return ActionResult("ok")
            if not v.on_ground(v.state):
                raise Failed("in the air")
        try:
            ctl.command(MAV_CMD_COMPONENT_ARM_DISARM, DISARM)
        except CommandRejected:
            with v.cond:
                if not v.state.armed:  # it disarmed by itself meanwhile
                    return ActionResult("ok")
            raise
        self.confirm_disarmed(run)
        return ActionResult("ok")

    def confirm_disarmed(self, run: Run) -> None:
        """Wait until a HEARTBEAT shows the vehicle disarmed (not the acknowledgement alone)."""
        v = self.v
        self.waiter.wait(
            run,
            lambda st: not st.armed,
            time.monotonic() + self.waiter.confirm_s(),
            lambda st: "vehicle acknowledged disarming but its HEARTBEAT still shows armed",
        )
        with v.cond:
            v.stop_steering()
            self.armed_by_us = False


__all__ = ["Arming", "await_settled", "disarmed_on_ground"]
