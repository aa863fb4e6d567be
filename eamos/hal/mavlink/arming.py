"""Before arming: wait for a settled position estimate (``adapter.estimator.*`` in the log);
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

from eamos.hal.mavlink.estimator import REPORT_GRACE_S, describe, estimator_message, verdict

if TYPE_CHECKING:
    from eamos.hal.mavlink.vehicle import MavlinkVehicle
    from eamos.hal.mavlink.waits import Run, Waiter


def await_settled(waiter: Waiter, v: MavlinkVehicle, run: Run, deadline: float) -> None:
    """Before arming: wait until the estimator reports a settled estimate (until ``deadline``).

    Logs ``adapter.estimator.wait`` (with what is missing) and
    ``adapter.estimator.settled`` (with how long it took), or
    ``adapter.estimator.unreported`` when no report came within
    :data:`REPORT_GRACE_S`; raises :class:`~eamos.hal.mavlink.waits.TimedOut` with the
    flags still missing at ``deadline``.
    """
    s = v.settings
    with v.cond:
        flags = v.state.estimator_flags
    if verdict(flags):
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
        if verdict(flags):
            return
    v.log.info("adapter.estimator.wait", flags=flags, why=describe(flags))
    waiter.wait(
        run,
        lambda st: bool(verdict(st.estimator_flags)),
        deadline,
        lambda st: (
            f"the vehicle's position estimate did not settle within {s.armable_timeout_s:g} s "
            f"({describe(st.estimator_flags or 0)})"
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


__all__ = ["await_settled", "disarmed_on_ground"]
