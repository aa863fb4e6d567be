"""The simulated drone adapter: a kinematic quadcopter in this process.

:class:`SimCore` is the vehicle with no thread and no clock (``step()`` advances it
one :data:`SIM_DT_S`); :class:`SimAdapter` paces it in (scaled) real time for
``eamos-node``, stepped by a :class:`SimClock` (one per process: a drone of its own
otherwise); the virtual-time driver (:mod:`eamos.virtual`) steps cores itself.
Plugin actions' simulator implementations see a :class:`SimView` and return a
:class:`SimOutcome` (docs/plugins.md); the project's camera actions' are in
:mod:`.camera`, loaded by the adapter that runs them.
"""

from .adapter import SimAdapter, paced_ticks, sim_adapter_from_settings
from .clock import SimClock
from .core import PAYLOAD_DELAY_S, SIM_DT_S, Finished, SimCore
from .plugin_api import SimOutcome, SimView
from .settings import MAX_DRAIN_FACTOR, SimSettings, Waypoint

__all__ = [
    "MAX_DRAIN_FACTOR",
    "PAYLOAD_DELAY_S",
    "SIM_DT_S",
    "Finished",
    "SimAdapter",
    "SimClock",
    "SimCore",
    "SimOutcome",
    "SimSettings",
    "SimView",
    "Waypoint",
    "paced_ticks",
    "sim_adapter_from_settings",
]
