"""The drone runtime: actors that execute one drone's program (paper Section VI).

What other packages may use:

* :class:`DroneRuntime` (build, ``start``, ``announce_ready``, ``fire``, ``abort``,
  ``report``/``drone_report``, ``stop``), :class:`NetSettings`,
  :class:`DroneRuntimeError`, :data:`FINAL_SAMPLE_WAIT_S` (:mod:`.runtime`);
* :class:`DroneReport`, :class:`FinalState`, :class:`ActionEntry`,
  :class:`ReportError` (:mod:`.report`): a drone's part of the run summary;
* :class:`Dispatcher`, :class:`PooledActor` (:mod:`.dispatch`): actors on a shared pool;
* :class:`RuntimeFailure` (:mod:`.failure`): an exception in a part of a runtime;
* :data:`DEFAULT_PEER_WAIT_LIMIT_S`, :data:`END_POLICIES` (:mod:`.stranded`): when and how
  a drone ends its part on its own (a lost peer, no Complete, blocked in the air);
* :func:`telemetry_values`, :func:`stale_values` (:mod:`.logic.telemetry`).

The parts (:mod:`.board`, :mod:`.outbox`, :mod:`.executive`, :mod:`.inbound`,
:mod:`.node`, :mod:`.uniform_api`) are the runtime's own.  Names load on first
use, so importing a pure module of this package (``state``, ``logic``,
``report``) does not load ZeroMQ or Pykka.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .dispatch import Dispatcher, PooledActor
    from .failure import RuntimeFailure
    from .logic.telemetry import stale_values, telemetry_values
    from .report import ActionEntry, DroneReport, FinalState, ReportError
    from .runtime import FINAL_SAMPLE_WAIT_S, DroneRuntime, DroneRuntimeError, NetSettings
    from .stranded import DEFAULT_PEER_WAIT_LIMIT_S, END_POLICIES

_WHERE = {
    "FINAL_SAMPLE_WAIT_S": "runtime",
    "DroneRuntime": "runtime",
    "DroneRuntimeError": "runtime",
    "NetSettings": "runtime",
    "ActionEntry": "report",
    "DroneReport": "report",
    "FinalState": "report",
    "ReportError": "report",
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
    "DroneRuntime",
    "DroneRuntimeError",
    "FinalState",
    "NetSettings",
    "PooledActor",
    "ReportError",
    "RuntimeFailure",
    "stale_values",
    "telemetry_values",
]


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
