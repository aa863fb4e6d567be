"""The drone runtime: actors that execute one drone's program (paper Section VI).

What other packages may use:

* :class:`DroneRuntime` (build, ``start``, ``announce_ready``, ``fire``, ``abort``,
  ``report``/``drone_report``, ``stop``), :class:`NetSettings`,
  :class:`DroneRuntimeError`, :data:`FINAL_SAMPLE_WAIT_S` (:mod:`.runtime`);
* :class:`DroneReport`, :class:`FinalState`, :class:`ActionEntry`,
  :class:`DroneReportError` (:mod:`.report`): a drone's part of the run summary, and
  the error for one whose JSON cannot be read back;
* :class:`Dispatcher`, :class:`PooledActor` (:mod:`.dispatch`): actors on a shared pool;
* :class:`RuntimeFailure` (:mod:`.failure`): an exception in a part of a runtime;
* :data:`DEFAULT_PEER_WAIT_LIMIT_S`, :data:`END_POLICIES` (:mod:`.stranded`): when and how
  a drone ends its part on its own (a lost peer, no Complete, blocked in the air);
* :func:`telemetry_values`, :func:`stale_values` (:mod:`.logic.telemetry`).

The parts (:mod:`.board`, :mod:`.outbox`, :mod:`.executive`, :mod:`.inbound`,
:mod:`.node`, :mod:`.uniform_api`) are the runtime's own.  Names load on first
use (:func:`eamos.lazy.lazy_exports`), so importing a pure module of this package
(``state``, ``logic``, ``report``) does not load ZeroMQ or Pykka.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from eamos.lazy import lazy_exports

if TYPE_CHECKING:
    from .dispatch import Dispatcher, PooledActor
    from .failure import RuntimeFailure
    from .logic.telemetry import stale_values, telemetry_values
    from .report import ActionEntry, DroneReport, DroneReportError, FinalState
    from .runtime import FINAL_SAMPLE_WAIT_S, DroneRuntime, DroneRuntimeError, NetSettings
    from .stranded import DEFAULT_PEER_WAIT_LIMIT_S, END_POLICIES

#: Each public name -> the module defining it.
_WHERE = {
    "FINAL_SAMPLE_WAIT_S": "runtime",
    "DroneRuntime": "runtime",
    "DroneRuntimeError": "runtime",
    "NetSettings": "runtime",
    "ActionEntry": "report",
    "DroneReport": "report",
    "FinalState": "report",
    "DroneReportError": "report",
    "Dispatcher": "dispatch",
    "PooledActor": "dispatch",
    "RuntimeFailure": "failure",
    "DEFAULT_PEER_WAIT_LIMIT_S": "stranded",
    "END_POLICIES": "stranded",
    "stale_values": "logic.telemetry",
    "telemetry_values": "logic.telemetry",
}

__all__ = [
    "DEFAULT_PEER_WAIT_LIMIT_S",
    "END_POLICIES",
    "FINAL_SAMPLE_WAIT_S",
    "ActionEntry",
    "Dispatcher",
    "DroneReport",
    "DroneReportError",
    "DroneRuntime",
    "DroneRuntimeError",
    "FinalState",
    "NetSettings",
    "PooledActor",
    "RuntimeFailure",
    "stale_values",
    "telemetry_values",
]


# Each public name, imported from its module on first use.
__getattr__, __dir__ = lazy_exports(globals(), _WHERE)
