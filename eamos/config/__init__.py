"""Configuration files: one per drone (``eamos-node --config``), one per fleet (``--fleet``).

- :mod:`.node`: a drone's config, :class:`NodeConfig` (read, validate, write back);
- :mod:`.fleet`: a fleet file, :class:`FleetConfig` (defaults, drone types, drones,
  homes, safety) and :func:`fleet_order`;
- :mod:`.types`: ``[types.NAME.hal]`` tables, each drone's type lineage, the precedence
  drone > type > defaults > built-in battery model;
- :mod:`.validation`: located errors (:class:`ConfigError`), ranges of numeric fields;
- :mod:`.toml_text`: TOML literals for writing a config back.

Every error names the file and the field.
"""

from .fleet import HOME_SPACING_M, FleetConfig, SafetySettings, fleet_order
from .node import NET_FIELDS, NodeConfig
from .types import merge_hal, type_lineage
from .validation import (
    END_POLICIES,
    MAX_SPEEDUP,
    RANGES,
    ConfigError,
    Range,
    _check_keys,
    check_keys,
    describe_ranges,
    in_range,
    read_toml,
)

__all__ = [
    "END_POLICIES",
    "HOME_SPACING_M",
    "MAX_SPEEDUP",
    "NET_FIELDS",
    "RANGES",
    "ConfigError",
    "FleetConfig",
    "NodeConfig",
    "Range",
    "SafetySettings",
    "_check_keys",
    "check_keys",
    "describe_ranges",
    "fleet_order",
    "in_range",
    "merge_hal",
    "read_toml",
    "type_lineage",
]
