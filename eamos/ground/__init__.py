"""The ground station (paper VI-G) in one place: station, run loop, displays, run summary.

* :class:`GroundStation` (``station.py``): what the ground station knows of each
  drone (:class:`DroneView`), the start trigger, completion and abort.
* :func:`fly` (``flight.py``): the one run loop -- ready, start, watch, complete or
  abort, collect the reports -- of ``eamos run``, ``eamos start`` and
  ``eamos-node`` in the ground role; :func:`ground_runtime` builds the ground
  station's own runtime; :func:`install_stop_handler` makes Ctrl-C abort.
* :func:`format_event`, :class:`PlainDisplay`, :class:`LiveDisplay`
  (``display.py``): what the operator sees, the same lines everywhere.
* :class:`RunSummary`, :class:`DroneResult` (``summary.py``): ``summary.json``.
* :func:`fly_local` (``local.py``): ``eamos run``'s drones as local processes;
  :func:`run_ground_node` (``node.py``): ``eamos-node`` given the ground
  station's program; simulated MAVLink vehicles for hybrid runs (``vehicles.py``).

Names load on first use (:func:`eamos.lazy.lazy_exports`): reading a summary
(``eamos report``) starts neither ZeroMQ nor Pykka.  See docs/architecture.md.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from eamos.lazy import lazy_exports

if TYPE_CHECKING:
    from eamos.ground.display import (
        Display,
        LiveDisplay,
        PlainDisplay,
        format_event,
        make_display,
    )
    from eamos.ground.flight import (
        Flight,
        Limits,
        StopRequest,
        fly,
        ground_runtime,
        hurried,
        install_stop_handler,
    )
    from eamos.ground.local import (
        LocalFleet,
        LocalMission,
        check_hal_settings,
        fly_local,
        free_ports,
        new_run_dir,
        use_run_dir,
    )
    from eamos.ground.node import run_ground_node
    from eamos.ground.station import DroneView, GroundStation
    from eamos.ground.summary import (
        ActionEntry,
        DroneReport,
        DroneResult,
        FinalState,
        RunSummary,
        summarize,
    )

#: Each public name -> the module defining it.
_WHERE = {
    "Display": "display",
    "LiveDisplay": "display",
    "PlainDisplay": "display",
    "format_event": "display",
    "make_display": "display",
    "Flight": "flight",
    "Limits": "flight",
    "fly": "flight",
    "ground_runtime": "flight",
    "install_stop_handler": "flight",
    "StopRequest": "flight",
    "hurried": "flight",
    "LocalFleet": "local",
    "LocalMission": "local",
    "check_hal_settings": "local",
    "fly_local": "local",
    "free_ports": "local",
    "new_run_dir": "local",
    "use_run_dir": "local",
    "run_ground_node": "node",
    "DroneView": "station",
    "GroundStation": "station",
    "ActionEntry": "summary",
    "DroneReport": "summary",
    "DroneResult": "summary",
    "FinalState": "summary",
    "RunSummary": "summary",
    "summarize": "summary",
}

__all__ = [
    "ActionEntry",
    "Display",
    "DroneReport",
    "DroneResult",
    "DroneView",
    "FinalState",
    "Flight",
    "GroundStation",
    "Limits",
    "LiveDisplay",
    "LocalFleet",
    "LocalMission",
    "PlainDisplay",
    "RunSummary",
    "StopRequest",
    "check_hal_settings",
    "fly",
    "fly_local",
    "format_event",
    "free_ports",
    "ground_runtime",
    "hurried",
    "install_stop_handler",
    "make_display",
    "new_run_dir",
    "run_ground_node",
    "summarize",
    "use_run_dir",
]


# Each public name, imported from its module on first use.
__getattr__, __dir__ = lazy_exports(globals(), _WHERE)
