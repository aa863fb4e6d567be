"""Validation shared by drone and fleet configs: located errors, ranges, known keys.

Every error names the file and the field (``<file>: <field>: <problem>``), so
``eamos`` can print it and exit 2 (bad input).  Before any field is looked at,
:func:`read_toml` bounds the whole document: at most :data:`MAX_CONFIG_BYTES`,
arrays and tables nested at most :data:`MAX_NESTING` deep, no NUL character in
any key or string; names and paths are checked before they become file names
(:func:`participant_name`, :func:`path_field`), endpoints before a socket sees
them (:func:`endpoint`).
"""

from __future__ import annotations

import math
import os
import re
import reprlib
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..hal import ADAPTERS
from ..hal.settings import did_you_mean
from .toml_text import toml_key


class ConfigError(Exception):
    """A configuration file is missing, unreadable, or has a bad field."""


#: Largest config or fleet file read (a fleet of a thousand drones with scripted
#: pilots is far smaller).
MAX_CONFIG_BYTES = 4 << 20
#: Deepest nesting of tables and arrays in a config (the deepest real one is 4:
#: ``drones.X.hal.pilot[i]``).
MAX_NESTING = 32
#: Longest participant name: the compiler's limit on drone names (they become file names).
MAX_NAME_CHARS = 64
MAX_NAME_BYTES = 128
#: Largest coordinate of a fleet file (a home, a geofence corner), metres from the origin.
MAX_COORDINATE_M = 1_000_000.0
#: Longest path, and path component, in UTF-8 bytes (Linux's PATH_MAX and NAME_MAX).
MAX_PATH_BYTES = 4096
MAX_PATH_PART_BYTES = 255

_SHORT = reprlib.Repr()
_SHORT.maxstring = 60
_SHORT.maxother = 60


def shown(value: Any) -> str:
    """``value`` for an error message: its repr, cut short (a value may be megabytes long)."""
    return _SHORT.repr(value)


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file, bounded; ConfigError with the line (or field) of what is wrong.

    A file over :data:`MAX_CONFIG_BYTES` is not read past the limit (``/dev/zero``
    given as a config ends at once); arrays and tables nested deeper than
    :data:`MAX_NESTING` are refused before the parser recurses into them; a NUL
    character in any key or string is refused, naming the field.
    """
    try:
        with Path(path).open("rb") as file:
            data = file.read(MAX_CONFIG_BYTES + 1)
    except FileNotFoundError as exc:
        raise ConfigError(f"{path}: no such configuration file") from exc
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read it: {exc.strerror or exc}") from exc
    if len(data) > MAX_CONFIG_BYTES:
        raise ConfigError(
            f"{path}: too large for a configuration file (over {MAX_CONFIG_BYTES} bytes)"
        )
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: cannot read it: not UTF-8 text ({exc.reason})") from exc
    line = too_deep_line(text, MAX_NESTING)
    if line is not None:
        raise ConfigError(
            f"{path}: line {line}: arrays and tables nested more than {MAX_NESTING} deep"
        )
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from exc
    except RecursionError as exc:  # a nesting the scan missed: still bad input
        raise ConfigError(f"{path}: arrays and tables nested more than {MAX_NESTING} deep") from exc
    check_document(f"{path}: ", doc)
    return doc


# What the nesting scan skips: comments and the four kinds of TOML strings (a bracket
# in them nests nothing).  An unterminated one runs to the end of its line (or text).
_OPAQUE = re.compile(
    r"#[^\n]*"
    r'|"""(?:[^\\]|\\.)*?(?:"""(?!")|\Z)'
    r"|'''.*?(?:'''(?!')|\Z)"
    r'|"(?:[^"\\\n]|\\.)*(?:"|$)'
    r"|'[^'\n]*(?:'|$)",
    re.MULTILINE | re.DOTALL,
)
_BRACKETS = re.compile(r"[\[\]{}]")


def too_deep_line(text: str, limit: int) -> int | None:
    """The first line on which arrays and tables nest deeper than ``limit`` (None: none).

    A scan of the brackets outside comments and strings: linear and without
    recursion, so the parser is never handed a nesting that would exhaust
    Python's stack (a table header's brackets count too: they never nest deep).
    """
    depth = 0
    opaque = _OPAQUE.search(text)
    for match in _BRACKETS.finditer(text):
        at = match.start()
        while opaque is not None and opaque.end() <= at:
            opaque = _OPAQUE.search(text, opaque.end())
        if opaque is not None and opaque.start() <= at:
            continue  # inside a comment or a string
        if match.group() in "[{":
            depth += 1
            if depth > limit:
                return text.count("\n", 0, at) + 1
        else:
            depth = max(0, depth - 1)
    return None


def check_document(where: str, doc: Mapping[str, Any]) -> None:
    """Refuse a document nested deeper than :data:`MAX_NESTING` (dotted keys nest too)
    or holding a NUL character in a key or a string, naming the field; iterative."""
    todo: list[tuple[Any, str, int]] = [(doc, "", 0)]
    while todo:
        value, field, depth = todo.pop()
        if isinstance(value, dict):
            if depth >= MAX_NESTING and value:
                raise ConfigError(f"{where}{field}: tables nested more than {MAX_NESTING} deep")
            for key, item in value.items():
                name = f"{field}.{key_shown(key)}" if field else key_shown(key)
                if "\x00" in key:
                    raise ConfigError(f"{where}{name}: a key holds a NUL character")
                todo.append((item, name, depth + 1))
        elif isinstance(value, list):
            if depth >= MAX_NESTING and value:
                raise ConfigError(f"{where}{field}: arrays nested more than {MAX_NESTING} deep")
            todo.extend((item, f"{field}[{i}]", depth + 1) for i, item in enumerate(value))
        elif isinstance(value, str) and "\x00" in value:
            raise ConfigError(f"{where}{field}: holds a NUL character")


def participant_name(where: str, value: Any, what: str = "participant name") -> str:
    """``value`` if it can name a participant (a drone, ``GCS``): an identifier of at most
    :data:`MAX_NAME_CHARS` characters, as the compiler accepts; names become file names."""
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{where}: must be a {what}, got {shown(value)}")
    if len(value) > MAX_NAME_CHARS or len(value.encode("utf-8", "surrogatepass")) > MAX_NAME_BYTES:
        raise ConfigError(
            f"{where}: {shown(value)} is longer than a {what} may be "
            f"({MAX_NAME_CHARS} characters, {MAX_NAME_BYTES} bytes in UTF-8)"
        )
    if not value.isidentifier():
        raise ConfigError(
            f"{where}: {shown(value)} is not a {what} (letters, digits and _, as in the mission)"
        )
    return value


def path_field(where: str, value: Any, what: str = "path") -> str:
    """``value`` if it can be a path: a non-empty string without control characters, at
    most :data:`MAX_PATH_BYTES` long in UTF-8 with parts of at most
    :data:`MAX_PATH_PART_BYTES` (what the system takes); else a ConfigError."""
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{where}: must be a {what}, got {shown(value)}")
    if any(ord(ch) < 0x20 or ord(ch) == 0x7F for ch in value):
        raise ConfigError(f"{where}: {shown(value)} holds a control character")
    try:
        size = len(value.encode("utf-8"))
    except UnicodeEncodeError as exc:  # a lone surrogate: no file system takes it
        raise ConfigError(f"{where}: {shown(value)} is not valid Unicode") from exc
    if size > MAX_PATH_BYTES:
        raise ConfigError(f"{where}: a path of {size} bytes is longer than a path may be")
    for part in value.split("/"):
        if len(part.encode("utf-8")) > MAX_PATH_PART_BYTES:
            raise ConfigError(
                f"{where}: {shown(part)} is longer than a file name may be "
                f"({MAX_PATH_PART_BYTES} bytes)"
            )
    return value


def key_shown(key: str) -> str:
    """A key as TOML writes it (quoted unless bare: ``" "``, ``"a.b"``), cut short."""
    quoted = toml_key(key)
    if len(quoted) <= 70:
        return quoted
    return quoted[:60] + ('..."' if quoted.startswith('"') else "...")


def check_keys(where: str, table: Mapping[str, Any], allowed: set[str]) -> None:
    """Refuse a key of ``table`` not in ``allowed``, naming ``where`` and the nearest key."""
    for key in table:
        if key not in allowed:
            hint = did_you_mean(key, allowed) if len(key) <= 100 else ""
            raise ConfigError(f"{where}{key_shown(key)}: unknown field{hint}")


#: The transports a link may use, and the longest endpoint accepted.
ENDPOINT_SCHEMES = ("tcp", "ipc", "inproc")
MAX_ENDPOINT_CHARS = 256
#: The longest ``ipc://`` path a Unix socket takes (``sun_path`` less its NUL).
MAX_IPC_PATH_BYTES = 107


def endpoint(where: str, value: Any, *, bind: bool = False) -> str:
    """``value`` as a ZeroMQ endpoint, or a ConfigError naming ``where``.

    ``tcp://HOST:PORT`` with a port from 1 to 65535 (0, any free port, only for a
    ``bind``), ``ipc://PATH`` or ``inproc://NAME``; no control characters, at most
    :data:`MAX_ENDPOINT_CHARS` long.  Checked here because ZeroMQ accepts some bad
    ones (a port of -1) and fails late, or with an internal error, on others.
    """
    example = 'such as "tcp://127.0.0.1:6001"'
    if not isinstance(value, str) or "://" not in value:
        raise ConfigError(f"{where}: must be a ZeroMQ endpoint {example}, got {shown(value)}")
    if len(value) > MAX_ENDPOINT_CHARS:
        raise ConfigError(f"{where}: longer than {MAX_ENDPOINT_CHARS} characters")
    if any(ord(ch) < 0x21 or ord(ch) == 0x7F for ch in value):
        raise ConfigError(f"{where}: {shown(value)} holds a space or a control character")
    scheme, _, rest = value.partition("://")
    if scheme not in ENDPOINT_SCHEMES:
        raise ConfigError(
            f"{where}: {shown(value)}: the transport must be one of "
            f"{', '.join(ENDPOINT_SCHEMES)} ({example})"
        )
    if scheme == "ipc" and not 0 < len(rest.encode("utf-8", "replace")) <= MAX_IPC_PATH_BYTES:
        raise ConfigError(f"{where}: an ipc:// path of 1 to {MAX_IPC_PATH_BYTES} bytes")
    if scheme == "inproc" and not rest:
        raise ConfigError(f"{where}: an inproc:// endpoint needs a name")
    if scheme == "tcp":
        host, colon, port = rest.rpartition(":")
        low = 0 if bind else 1
        if not colon or not host or not port.isascii() or not port.isdigit():
            raise ConfigError(f"{where}: {shown(value)} must be tcp://HOST:PORT ({example})")
        if not low <= int(port) <= 65535:
            raise ConfigError(f"{where}: port {int(port)} is not from {low} to 65535")
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
    if "adapter" in hal and not (isinstance(hal["adapter"], str) and hal["adapter"] in ADAPTERS):
        kind = hal["adapter"]
        hint = did_you_mean(kind, ADAPTERS) if isinstance(kind, str) else ""
        raise ConfigError(
            f"{where}adapter: unknown adapter {shown(kind)}{hint}; "
            f"choose one of: {', '.join(sorted(ADAPTERS))}"
        )
    if drone and hal.get("adapter") == "ground":
        raise ConfigError(
            f"{where}adapter: \"ground\" is the ground station's adapter, not a drone's "
            '(use "sim", "fake" or "mavlink")'
        )


def check_adapter(where: str, hal: Mapping[str, Any], drone: str) -> None:
    """The whole ``[hal]`` table checked by its adapter's own settings, before anything
    starts: a bad value is bad input naming the file and the field (``<file>: hal.<field>:
    ...``), not a vehicle the adapter cannot use.  ``where`` is ``"<file>: "``.

    The adapter's settings are loaded only for the adapter named (a simulated drone
    never loads the MAVLink adapter's).
    """
    from ..hal.api import AdapterError

    kind = hal.get("adapter")
    try:
        if kind == "sim":
            from ..hal.sim.settings import SimSettings

            SimSettings.from_mapping(hal)
        elif kind == "mavlink":
            from ..hal.mavlink.settings import MavlinkSettings

            MavlinkSettings.from_mapping(hal)
        elif kind == "ground":
            from ..hal.station_adapter import GroundSettings

            GroundSettings.from_mapping(hal)
        else:  # the fake adapter (cheap to make), or a missing or unknown one: its error
            from ..hal import make_adapter

            make_adapter(drone, hal, None).close()
    except AdapterError as exc:
        raise ConfigError(f"{where}{exc}") from exc


def log_folder(where: str, folder: Path, config_dir: Path | None = None) -> None:
    """Refuse a log folder that names a file (or lies under one), is not writable, or is
    not a folder of its own: the file system's root, or a folder above the config's
    (``log_dir = "../../"``), where a drone's ``mission.log`` has no business."""
    if folder.parent == folder:
        raise ConfigError(
            f"{where}: {folder} is the file system's root: give the drone a log folder of its own"
        )
    if config_dir is not None and folder in Path(config_dir).resolve().parents:
        raise ConfigError(
            f"{where}: {folder} is a folder above the config's: give the drone a log folder "
            "of its own (such as logs/<drone>)"
        )
    for part in (folder, *folder.parents):
        if part.exists():
            if not part.is_dir():
                raise ConfigError(f"{where}: {part} is a file, not a folder")
            if not os.access(part, os.W_OK | os.X_OK):
                raise ConfigError(f"{where}: {part} is not writable")
            return


def number(
    where: str,
    value: Any,
    *,
    positive: bool = False,
    low: float = -MAX_COORDINATE_M,
    high: float = MAX_COORDINATE_M,
) -> float:
    """``value`` as a finite float within ``low``..``high`` (and above 0 if ``positive``)."""
    if not isinstance(value, int | float) or isinstance(value, bool) or value != value:
        raise ConfigError(f"{where}: must be a number, got {shown(value)}")
    if not math.isfinite(value):
        raise ConfigError(f"{where}: must be finite, got {value!r}")
    if positive and not value > 0:
        raise ConfigError(f"{where}: must be greater than 0, got {value!r}")
    if not low <= value <= high:
        raise ConfigError(f"{where}: must be between {low:g} and {high:g}, got {value!r}")
    return float(value)


def point(where: str, value: Any, size: tuple[int, ...] = (2,)) -> tuple[float, ...]:
    """A list of ``size`` coordinates (metres, each within :data:`MAX_COORDINATE_M`)."""
    if not isinstance(value, list) or len(value) not in size:
        words = " or ".join(str(n) for n in size)
        raise ConfigError(f"{where}: must be a list of {words} numbers, got {shown(value)}")
    return tuple(number(f"{where}[{i}]", v) for i, v in enumerate(value))
