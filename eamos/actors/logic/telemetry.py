"""Property values as conditions read them, from a telemetry sample (pure).

The telemetry board of a drone runtime and the virtual-time driver keep the
same table per drone: the uniform properties (``X``, ``Battery`` ...) plus
``_time_s``/``_landed`` (when, and whether on the ground) or ``_stale_s``.
"""

from __future__ import annotations

from typing import Protocol, TypeAlias

from ...program.uniform import PROPERTY_FIELDS

#: One drone's property values by name (``X``, ``Battery``, ``_time_s`` ...): a number or
#: a flag, None while unknown (stale).
PropertyValues: TypeAlias = dict[str, float | bool | None]


class Sample(Protocol):
    """A telemetry sample: an adapter's ``Telemetry`` or a wire ``TelemetrySample``."""

    @property
    def time_s(self) -> float: ...

    @property
    def landed(self) -> bool: ...


def telemetry_values(sample: Sample) -> PropertyValues:
    """Uniform property values (``X``, ``Battery`` ...) of a telemetry sample."""
    values: PropertyValues = {prop: getattr(sample, fld) for prop, fld in PROPERTY_FIELDS.items()}
    values["_time_s"] = sample.time_s
    values["_landed"] = sample.landed
    return values


def stale_values(age_s: float) -> PropertyValues:
    """Property values of a drone whose telemetry went stale: none (conditions wait)."""
    values: PropertyValues = dict.fromkeys(PROPERTY_FIELDS)
    values["_stale_s"] = age_s
    return values


__all__ = ["PropertyValues", "Sample", "stale_values", "telemetry_values"]
