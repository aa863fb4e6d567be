"""What a plugin's "sim" implementation sees and returns (docs/plugins.md).

A simulator implementation of a plugin action is a pure function::

    def spray(view: SimView, command: PluginAction) -> SimOutcome: ...

It reads the vehicle's state in ``view`` and the arguments in ``command``
(``command.value("duration_s")``) and says how long the action takes in simulated
seconds, whether it fails (a reason), what it changes in the payload state (numbers
by name, kept by the simulator and shown in ``adapter.action.end``) and what it logs
(the fields of one ``adapter.plugin`` line).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from eamos.program.uniform import PluginAction

#: The default simulated duration of a plugin action.
PLUGIN_DELAY_S = 0.2


@dataclass(frozen=True)
class SimView:
    """The simulated vehicle when a plugin action starts (mission frame, metres, degrees)."""

    drone: str
    t_s: float
    x_m: float
    y_m: float
    z_m: float
    heading_deg: float
    armed: bool
    landed: bool
    payload: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class SimOutcome:
    """What a plugin action does in the simulator: duration, failure, payload, log fields."""

    duration_s: float = PLUGIN_DELAY_S
    failed: str = ""
    payload: Mapping[str, float] = field(default_factory=dict)
    log: Mapping[str, float | str | bool] = field(default_factory=dict)


#: The type of a "sim" implementation.
SimImplementation = Callable[[SimView, PluginAction], SimOutcome]

__all__ = ["PLUGIN_DELAY_S", "SimImplementation", "SimOutcome", "SimView"]
