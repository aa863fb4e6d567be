"""Validation helpers for adapter settings (the ``hal`` section of a drone's config).

Every problem raises :class:`AdapterError` with a message that starts with the
dotted name of the offending field, e.g. ``"hal.speedup: must be > 0, got -1"``,
so the user can find it in the mission configuration.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

from eamos.hal.api import AdapterError
from eamos.hints import closest

#: Keys every adapter accepts and ignores: ``adapter`` selects the adapter itself.
COMMON_KEYS = frozenset({"adapter"})

#: The autopilots' delay between touchdown and disarming by themselves (PX4
#: ``COM_DISARM_LAND``, ArduCopter after "Land complete"), and the simulated drone's
#: default (:mod:`eamos.hal.sim.landing`; here so a config reads it without the simulator).
DISARM_AFTER_LANDING_S = 2.0


def field_error(path: str, problem: str) -> AdapterError:
    """An :class:`AdapterError` naming the field ``path`` (e.g. ``"hal.speedup"``)."""
    return AdapterError(f"{path}: {problem}")


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """A ``" (did you mean 'x'?)"`` suffix, or ``""`` when nothing is close."""
    close = closest(word, choices)
    return f" (did you mean '{close}'?)" if close else ""


def require_mapping(value: Any, path: str) -> Mapping[str, Any]:
    """``value`` as a mapping, or an error naming ``path``."""
    if not isinstance(value, Mapping):
        raise field_error(path, f"expected a mapping, got {type(value).__name__}")
    return value


def check_keys(mapping: Mapping[str, Any], allowed: Iterable[str], prefix: str) -> None:
    """Reject keys of ``mapping`` not in ``allowed``, suggesting the nearest valid key."""
    allowed = set(allowed)
    for key in mapping:
        if not isinstance(key, str):
            raise field_error(prefix, f"keys must be strings, got {key!r}")
        if key not in allowed:
            valid = ", ".join(sorted(allowed))
            raise field_error(
                f"{prefix}.{key}",
                f"unknown setting{did_you_mean(key, allowed)}; valid settings: {valid}",
            )


def number(
    mapping: Mapping[str, Any],
    key: str,
    default: float,
    prefix: str,
    *,
    gt: float | None = None,
    ge: float | None = None,
    le: float | None = None,
) -> float:
    """Read a finite number ``mapping[key]`` (or ``default``) within the given bounds."""
    if key not in mapping:
        return default
    return as_number(mapping[key], f"{prefix}.{key}", gt=gt, ge=ge, le=le)


def as_number(
    value: Any,
    path: str,
    *,
    gt: float | None = None,
    ge: float | None = None,
    le: float | None = None,
) -> float:
    """``value`` as a finite float within the given bounds, or an error naming ``path``."""
    # bool is an int subclass, but "speedup: true" is surely a mistake.
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise field_error(path, f"expected a number, got {value!r}")
    result = float(value)
    if not math.isfinite(result):
        raise field_error(path, f"must be finite, got {value!r}")
    if gt is not None and not result > gt:
        raise field_error(path, f"must be > {gt:g}, got {value!r}")
    if ge is not None and not result >= ge:
        raise field_error(path, f"must be >= {ge:g}, got {value!r}")
    if le is not None and not result <= le:
        raise field_error(path, f"must be <= {le:g}, got {value!r}")
    return result


def string_list(value: Any, path: str) -> list[str]:
    """``value`` as a list of strings (a single string is not accepted: likely a typo)."""
    if isinstance(value, str) or not isinstance(value, list | tuple):
        raise field_error(path, f"expected a list of strings, got {value!r}")
    for i, item in enumerate(value):
        if not isinstance(item, str):
            raise field_error(f"{path}[{i}]", f"expected a string, got {item!r}")
    return list(value)
