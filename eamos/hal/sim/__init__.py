"""The simulated drone adapter: a kinematic quadcopter in this process.

:class:`SimCore` is the vehicle with no thread and no clock (``step()`` advances it
one :data:`SIM_DT_S`); :class:`SimAdapter` paces it in (scaled) real time for
``eamos-node``; the virtual-time driver (:mod:`eamos.virtual`) steps cores itself.
Plugin actions' simulator implementations see a :class:`SimView` and return a
:class:`SimOutcome` (docs/plugins.md).

Names load on first use: the configs read :mod:`.settings` alone, and must not pay
for the adapter's thread, its logs (structlog) and the core's action rules
(``eamos-node`` start-up, docs/performance.md).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from eamos.lazy import lazy_exports

if TYPE_CHECKING:
    from .adapter import SimAdapter, paced_ticks, sim_adapter_from_settings
    from .core import PAYLOAD_DELAY_S, SIM_DT_S, Finished, SimCore
    from .plugin_api import SimOutcome, SimView
    from .settings import SimSettings, Waypoint

#: Each public name -> the module defining it.
_WHERE = {
    "SimAdapter": "adapter",
    "paced_ticks": "adapter",
    "sim_adapter_from_settings": "adapter",
    "PAYLOAD_DELAY_S": "core",
    "SIM_DT_S": "core",
    "Finished": "core",
    "SimCore": "core",
    "SimOutcome": "plugin_api",
    "SimView": "plugin_api",
    "SimSettings": "settings",
    "Waypoint": "settings",
}

__all__ = [
    "PAYLOAD_DELAY_S",
    "SIM_DT_S",
    "Finished",
    "SimAdapter",
    "SimCore",
    "SimOutcome",
    "SimSettings",
    "SimView",
    "Waypoint",
    "paced_ticks",
    "sim_adapter_from_settings",
]

# Each public name, imported from its module on first use.
__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
