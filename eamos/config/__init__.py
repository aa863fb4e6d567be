"""Configuration files: one per drone (``eamos-node --config``), one per fleet (``--fleet``).

- :mod:`.node`: a drone's config, :class:`NodeConfig` (read, validate, write back);
- :mod:`.fleet`: a fleet file, :class:`FleetConfig` (defaults, drone types, drones,
  homes, safety) and :func:`fleet_order`;
- :mod:`.types`: ``[types.NAME.hal]`` tables, each drone's type lineage, the precedence
  drone > type > defaults > built-in battery model;
- :mod:`.validation`: located errors (:class:`ConfigError`), ranges of numeric fields;
- :mod:`.toml_text`: TOML literals for writing a config back.

Every error names the file and the field.

:mod:`.fleet` and :mod:`.types` load on first use of their names
(:func:`eamos.lazy.lazy_exports`): a drone's
``eamos-node`` reads a node config only, and need not pay for fleet files, drone
types and the simulator's settings at start-up (docs/performance.md).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..lazy import lazy_exports
from .node import EXIT_CODE_FILE, NET_FIELDS, NodeConfig
from .validation import (
    END_POLICIES,
    MAX_SPEEDUP,
    RANGES,
    ConfigError,
    Range,
    check_keys,
    describe_ranges,
    in_range,
    read_toml,
)

if TYPE_CHECKING:
    from .fleet import HOME_SPACING_M, FleetConfig, LookAheadSettings, SafetySettings, fleet_order
    from .types import merge_hal, type_lineage

#: The names loaded on first use -> their module.
_LAZY = {
    "HOME_SPACING_M": "fleet",
    "FleetConfig": "fleet",
    "LookAheadSettings": "fleet",
    "SafetySettings": "fleet",
    "fleet_order": "fleet",
    "merge_hal": "types",
    "type_lineage": "types",
}

__all__ = [
    "END_POLICIES",
    "EXIT_CODE_FILE",
    "HOME_SPACING_M",
    "MAX_SPEEDUP",
    "NET_FIELDS",
    "RANGES",
    "ConfigError",
    "FleetConfig",
    "LookAheadSettings",
    "NodeConfig",
    "Range",
    "SafetySettings",
    "check_keys",
    "describe_ranges",
    "fleet_order",
    "in_range",
    "merge_hal",
    "read_toml",
    "type_lineage",
]

# The names of .fleet and .types, imported on first use.
__getattr__, __dir__ = lazy_exports(globals(), _LAZY)
