"""The simulator's ``Spray``: takes ``duration_s``, needs the air, logs where it sprayed."""

from eamos.hal.sim.plugin_api import SimOutcome, SimView
from eamos.program.uniform import PluginAction


def spray(view: SimView, command: PluginAction) -> SimOutcome:
    """Spray for ``duration_s`` simulated seconds (refused on the ground)."""
    if view.landed:
        return SimOutcome(failed="cannot spray on the ground")
    duration = command.value("duration_s")
    total = view.payload.get("sprayed_s", 0.0) + duration
    return SimOutcome(
        duration_s=duration,
        payload={"sprayed_s": total},
        log={"sprayed_s": total, "x_m": round(view.x_m, 2), "y_m": round(view.y_m, 2)},
    )
