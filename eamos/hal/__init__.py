"""The hardware-abstraction layer: the adapters behind the uniform API.

``make_adapter(drone, settings, adapter_log)`` builds the adapter a drone's
``hal`` settings ask for (``settings["adapter"]``, one of :data:`ADAPTERS`).  Each
adapter's factory loads with its module when first used
(:func:`eamos.lazy.lazy_exports`), so importing :mod:`eamos.hal` stays cheap: a
simulated drone loads neither the MAVLink adapter nor pymavlink.

What other packages may use:

* from :mod:`eamos.hal.api` (imported here): the :class:`Adapter` protocol
  (``run(command, done)`` takes a typed :class:`eamos.program.uniform.Command`),
  :class:`Telemetry`, :class:`ActionResult`, :class:`ActionHandle`, :class:`AdapterError`;
* :func:`make_adapter`, :data:`ADAPTERS` and the adapters' factories:
  :func:`sim_adapter_from_settings` (:mod:`eamos.hal.sim.adapter`),
  :func:`ground_adapter_from_settings` (:mod:`eamos.hal.station_adapter`: the ground
  station's adapter, pauses only), :func:`fake_adapter_from_settings`
  (:mod:`eamos.hal.fake`), :func:`mavlink_adapter_from_settings`
  (:mod:`eamos.hal.mavlink.adapter`);
* :mod:`eamos.hal.sim`: :class:`~eamos.hal.sim.SimCore`, the simulated quadcopter as
  pure logic stepped by its owner (virtual-time drivers), with
  :class:`~eamos.hal.sim.SimSettings`;
* :mod:`eamos.hal.mavlink`: :class:`~eamos.hal.mavlink.MavlinkSettings`;
* :mod:`eamos.hal.sitl`: :class:`~eamos.hal.sitl.SimVehicle`, the MAVLink simulated vehicle.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from eamos.hal.api import ActionHandle, ActionResult, Adapter, AdapterError, Telemetry
from eamos.hal.settings import did_you_mean, field_error
from eamos.lazy import lazy_exports

if TYPE_CHECKING:
    from .fake import fake_adapter_from_settings
    from .mavlink.adapter import mavlink_adapter_from_settings
    from .sim.adapter import sim_adapter_from_settings
    from .sim.clock import SimClock
    from .station_adapter import ground_adapter_from_settings

AdapterFactory = Callable[[str, Mapping[str, Any], Any], Adapter]

#: Each adapter's factory -> the module defining it (loaded when first used).
_WHERE = {
    "sim_adapter_from_settings": "sim.adapter",
    "ground_adapter_from_settings": "station_adapter",
    "fake_adapter_from_settings": "fake",
    "mavlink_adapter_from_settings": "mavlink.adapter",
}

#: Adapter kinds by their ``hal.adapter`` name -> the name of the factory building one.
ADAPTERS: Mapping[str, str] = MappingProxyType(
    {
        "sim": "sim_adapter_from_settings",
        "ground": "ground_adapter_from_settings",
        "fake": "fake_adapter_from_settings",
        "mavlink": "mavlink_adapter_from_settings",
    }
)


def make_adapter(
    drone: str, settings: Mapping[str, Any], adapter_log: Any, sim_clock: SimClock | None = None
) -> Adapter:
    """Build the adapter for ``drone`` chosen by ``settings["adapter"]``.

    ``settings`` is the drone's ``hal`` section; every adapter validates its own
    keys and raises :class:`AdapterError` ``"hal.<field>: <problem>"``.
    ``sim_clock``: the stepping clock the simulated drones of this process share
    (:class:`~eamos.hal.sim.SimClock`; None: each has its own).
    """
    if not isinstance(settings, Mapping):
        raise field_error("hal", f"expected a mapping, got {type(settings).__name__}")
    kind = settings.get("adapter")
    choices = ", ".join(sorted(ADAPTERS))
    if kind is None:
        raise field_error("hal.adapter", f"missing; choose one of: {choices}")
    factory_name = ADAPTERS.get(kind) if isinstance(kind, str) else None
    if factory_name is None:
        hint = did_you_mean(kind, ADAPTERS) if isinstance(kind, str) else ""
        raise field_error(
            "hal.adapter", f"unknown adapter {kind!r}{hint}; choose one of: {choices}"
        )
    # This package's own lazy export: the adapter's module loads here, the first time.
    factory: AdapterFactory = __getattr__(factory_name)
    if kind == "sim" and sim_clock is not None:
        sim_factory: Callable[..., Adapter] = factory
        return sim_factory(drone, settings, adapter_log, sim_clock)
    return factory(drone, settings, adapter_log)


__all__ = [
    "ADAPTERS",
    "ActionHandle",
    "ActionResult",
    "Adapter",
    "AdapterError",
    "AdapterFactory",
    "Telemetry",
    "fake_adapter_from_settings",
    "ground_adapter_from_settings",
    "make_adapter",
    "mavlink_adapter_from_settings",
    "sim_adapter_from_settings",
]

# Each adapter's factory, imported from its module on first use.
__getattr__, __dir__ = lazy_exports(globals(), _WHERE)
