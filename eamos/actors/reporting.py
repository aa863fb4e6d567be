"""A drone's part of the run summary, gathered from its runtime's parts at the end of a flight.

The executive gives the records and counts; the telemetry board the vehicle's
final state: the first sample after the last action that could change it
(waiting up to a bound), never one before; the Outbox and the link their counts.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import pykka

from ..net.link import Link
from .board import TelemetryBoard, ask_final_sample
from .executive import DroneExecutive, ask_snapshot
from .outbox import Outbox

if TYPE_CHECKING:
    from ..program.format import DroneProgram
    from .report import DroneReport

__all__ = ["gather_report"]

#: How long the report waits for the executive's and the board's answers.
ASK_TIMEOUT_S = 30.0


def gather_report(
    program: DroneProgram,
    executive: pykka.ActorRef[DroneExecutive] | None,
    board: pykka.ActorRef[TelemetryBoard] | None,
    outbox: Outbox | None,
    link: Link | None,
    *,
    final_wait_s: float,
    aborted: bool,
    abort_reason: str,
    adapter_error: str,
    vehicle: Mapping[str, Any] | None = None,
) -> DroneReport:
    """This drone's :class:`~.report.DroneReport` (parts not built count as empty).

    ``final_wait_s``: how long the final state may wait for the vehicle's first
    sample after its last state-changing action; ``vehicle``: the adapter's facts.
    """
    from .report import DroneReport  # loaded here, at a flight's end: not before Ready

    snap = ask_snapshot(executive, ASK_TIMEOUT_S)
    counts = outbox.counts() if outbox else {"triggers_sent": 0}
    return DroneReport.build(
        program,
        snap,
        triggers_sent=counts["triggers_sent"],
        net=link.stats() if link is not None else {},
        final=ask_final_sample(
            board, snap.state_changed_s, snap.state_action, final_wait_s, ASK_TIMEOUT_S
        ),
        aborted=aborted,
        abort_reason=abort_reason,
        adapter_error=adapter_error,
        vehicle=vehicle,
    )
