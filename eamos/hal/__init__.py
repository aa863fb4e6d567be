"""The hardware-abstraction layer: the adapters behind the uniform API.

``make_adapter(drone, settings, adapter_log)`` builds the adapter a drone's
``hal`` settings ask for (``settings["adapter"]``).  Adapter modules are
imported only when chosen, so importing :mod:`eamos.hal` stays cheap (a
MAVLink adapter, for instance, must not pull in pymavlink for simulated runs).

What other packages may use, by module:

* :mod:`eamos.hal.api` (re-exported here): the :class:`Adapter` protocol
  (``run(command, done)`` takes a typed :class:`eamos.program.uniform.Command`),
  :class:`Telemetry`, :class:`ActionResult`, :class:`ActionHandle`, :class:`AdapterError`;
* :mod:`eamos.hal.sim.core`: :class:`~eamos.hal.sim.core.SimCore`, the simulated
  quadcopter as pure logic stepped by its owner (virtual-time drivers), with
  :class:`~eamos.hal.sim.settings.SimSettings`;
* :mod:`eamos.hal.sim.adapter`, :mod:`eamos.hal.ground`, :mod:`eamos.hal.fake`,
  :mod:`eamos.hal.mavlink.adapter`: the adapters (``make_adapter`` builds them);
* :mod:`eamos.hal.mavlink.settings`: :class:`MavlinkSettings`;
* :mod:`eamos.hal.sitl.vehicle`: :class:`SimVehicle`, the MAVLink simulated vehicle.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any

from eamos.hal.api import ActionHandle, ActionResult, Adapter, AdapterError, Telemetry
from eamos.hal.settings import did_you_mean, field_error

AdapterFactory = Callable[[str, Mapping[str, Any], Any], Adapter]


def _lazy(module: str, name: str) -> AdapterFactory:
    """A factory importing ``module`` only when an adapter of that kind is built."""

    def factory(drone: str, settings: Mapping[str, Any], adapter_log: Any) -> Adapter:
        build: AdapterFactory = getattr(importlib.import_module(module), name)
        return build(drone, settings, adapter_log)

    factory.__doc__ = f"Build an adapter with {module}.{name}."
    return factory


#: Adapter kinds by their ``hal.adapter`` name (read-only).
ADAPTERS: Mapping[str, AdapterFactory] = MappingProxyType(
    {
        "sim": _lazy("eamos.hal.sim.adapter", "sim_adapter_from_settings"),
        "ground": _lazy("eamos.hal.ground", "ground_adapter_from_settings"),
        "fake": _lazy("eamos.hal.fake", "fake_adapter_from_settings"),
        "mavlink": _lazy("eamos.hal.mavlink.adapter", "mavlink_adapter_from_settings"),
    }
)


def make_adapter(drone: str, settings: Mapping[str, Any], adapter_log: Any) -> Adapter:
    """Build the adapter for ``drone`` chosen by ``settings["adapter"]``.

    ``settings`` is the drone's ``hal`` section; every adapter validates its own
    keys and raises :class:`AdapterError` ``"hal.<field>: <problem>"``.
    """
    if not isinstance(settings, Mapping):
        raise field_error("hal", f"expected a mapping, got {type(settings).__name__}")
    kind = settings.get("adapter")
    choices = ", ".join(sorted(ADAPTERS))
    if kind is None:
        raise field_error("hal.adapter", f"missing; choose one of: {choices}")
    factory = ADAPTERS.get(kind) if isinstance(kind, str) else None
    if factory is None:
        hint = did_you_mean(kind, ADAPTERS) if isinstance(kind, str) else ""
        raise field_error(
            "hal.adapter", f"unknown adapter {kind!r}{hint}; choose one of: {choices}"
        )
    return factory(drone, settings, adapter_log)


__all__ = [
    "ADAPTERS",
    "ActionHandle",
    "ActionResult",
    "Adapter",
    "AdapterError",
    "Telemetry",
    "make_adapter",
]
