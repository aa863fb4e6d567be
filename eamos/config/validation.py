"""Validation shared by drone and fleet configs: located errors, ranges, known keys.

Every error names the file and the field (``<file>: <field>: <problem>``), so
``eamos`` can print it and exit 2 (bad input).
"""

from __future__ import annotations

import math
import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..hal.settings import did_you_mean


class ConfigError(Exception):
    """A configuration file is missing, unreadable, or has a bad field."""


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file; ConfigError with the line on syntax errors."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError as exc:
        raise ConfigError(f"{path}: no such configuration file") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read it: {exc}") from exc
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from exc


def check_keys(where: str, table: Mapping[str, Any], allowed: set[str]) -> None:
    """Refuse a key of ``table`` not in ``allowed``, naming ``where`` and the nearest key."""
    for key in table:
        if key not in allowed:
            raise ConfigError(f"{where}{key}: unknown field{did_you_mean(key, allowed)}")


def endpoint(where: str, value: Any) -> str:
    """``value`` as a ZeroMQ endpoint (``"tcp://host:port"``), or a ConfigError naming ``where``."""
    if not isinstance(value, str) or "://" not in value:
        raise ConfigError(f'{where}: must be a ZeroMQ endpoint such as "tcp://127.0.0.1:6001"')
    return value


@dataclass(frozen=True)
class Range:
    """The values a numeric field accepts: ``low < value <= high`` (``low <= ...`` if closed)."""

    low: float
    high: float
    unit: str
    closed_low: bool = False

    def admits(self, value: float) -> bool:
        """Whether ``value`` (finite) is in the range."""
        above = value >= self.low if self.closed_low else value > self.low
        return above and value <= self.high

    def __str__(self) -> str:
        low = f"{self.low:g} <=" if self.closed_low else f"{self.low:g} <"
        return f"{low} value <= {self.high:g} {self.unit}".rstrip()


_DAY_S = 86_400.0
#: What a drone does when its mission cannot go on (``on_stranded``).
END_POLICIES = ("land", "hold", "return")
MAX_SPEEDUP = 1000.0
"""The largest ``hal.speedup`` (and ``--speedup``): faster, a simulated step no longer fits."""

RANGES: dict[str, Range] = {
    "ready_timeout_s": Range(0, _DAY_S, "s"),
    "land_timeout_s": Range(0, 3600, "s"),
    "mission_timeout_s": Range(0, 7 * _DAY_S, "s"),
    "heartbeat_s": Range(0.01, 60, "s", closed_low=True),
    "peer_timeout_s": Range(0, 3600, "s"),
    "telemetry_stale_s": Range(0, 3600, "s"),
    "telemetry_max_hz": Range(0.01, 1000, "Hz", closed_low=True),
    "peer_give_up_s": Range(0, _DAY_S, "s"),
    "peer_wait_limit_s": Range(0, _DAY_S, "s"),
    "battery_reserve_pct": Range(0, 100, "%"),
    "speedup": Range(0, MAX_SPEEDUP, ""),
}
"""Accepted values of every numeric field of a drone config (and of ``hal.speedup``)."""


def describe_ranges() -> list[str]:
    """One line per numeric field and its range (what ``docs/configuration.md`` shows)."""
    return [f"{name}: {rng}" for name, rng in RANGES.items()]


def in_range(where: str, value: Any, name: str) -> float:
    """``value`` as a finite float within ``RANGES[name]``, or a ConfigError naming ``where``."""
    rng = RANGES[name]
    if not isinstance(value, int | float) or isinstance(value, bool):
        raise ConfigError(f"{where}: must be a number ({rng}), got {value!r}")
    number = float(value)
    if not math.isfinite(number) or not rng.admits(number):
        raise ConfigError(f"{where}: must be finite, {rng}, got {value!r}")
    return number


def check_hal(where: str, hal: Mapping[str, Any], *, drone: bool) -> None:
    """What the config layer checks of a ``[hal]`` table (the adapter checks the rest).

    ``speedup`` is checked here too because ``--speedup`` replaces it before the
    adapter sees it: a wrong value in a file must not pass unnoticed.
    """
    if "speedup" in hal:
        in_range(f"{where}speedup", hal["speedup"], "speedup")
    if drone and hal.get("adapter") == "ground":
        raise ConfigError(
            f"{where}adapter: \"ground\" is the ground station's adapter, not a drone's "
            '(use "sim", "fake" or "mavlink")'
        )


def log_folder(where: str, folder: Path) -> None:
    """Refuse a log folder that names a file (or lies under one)."""
    for part in (folder, *folder.parents):
        if part.exists():
            if not part.is_dir():
                raise ConfigError(f"{where}: {part} is a file, not a folder")
            if not os.access(part, os.W_OK | os.X_OK):
                raise ConfigError(f"{where}: {part} is not writable")
            return


def number(where: str, value: Any, *, positive: bool = False) -> float:
    if not isinstance(value, int | float) or isinstance(value, bool) or value != value:
        raise ConfigError(f"{where}: must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ConfigError(f"{where}: must be finite, got {value!r}")
    if positive and not value > 0:
        raise ConfigError(f"{where}: must be greater than 0, got {value!r}")
    return float(value)


def point(where: str, value: Any, size: tuple[int, ...] = (2,)) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) not in size:
        words = " or ".join(str(n) for n in size)
        raise ConfigError(f"{where}: must be a list of {words} numbers, got {value!r}")
    return tuple(number(f"{where}[{i}]", v) for i, v in enumerate(value))
