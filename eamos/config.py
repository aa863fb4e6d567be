"""Configuration files: one per drone (eamos-node --config), one per fleet (eamos run --fleet).

Drone config (TOML)::

    drone = "Drone1"                          # must match the program
    program = "programs/Drone1.program.json"  # relative to this file
    log_dir = "logs/Drone1"                   # relative to this file (default: logs/<drone>)
    ready_timeout_s = 60                      # how long to wait for the peers' subscriptions
    land_timeout_s = 120                      # after an abort, how long to wait for touchdown
    mission_timeout_s = 600                   # ground station only: abort after this long
    peer_wait_limit_s = 20                    # waiting on a lost peer (or for Complete from a
                                              # silent ground station) at most this long, then
    on_stranded = "land"                      # the end policy: land | hold | return (lands now)

    [net]
    bind = "tcp://127.0.0.1:6001"             # this drone's out-bridge
    keys = "keys/Drone1"                      # from `eamos keys` (relative to this file)
    # plain = true                            # instead of keys: no security, loopback only
    heartbeat_s = 1                           # heartbeat period (and telemetry refresh)
    peer_timeout_s = 3                        # a peer silent this long is reported lost
    telemetry_stale_s = 2.5                   # older telemetry is not used by conditions
    telemetry_max_hz = 20                     # outgoing telemetry cap (latest always sent)
    peer_give_up_s = 30                       # ground station only: stop waiting for a
                                              # drone silent this long (default: never)
    [net.peers]                               # every other participant's out-bridge
    GCS = "tcp://127.0.0.1:6000"
    Drone2 = "tcp://127.0.0.1:6002"

    [hal]
    adapter = "sim"                           # sim | ground | fake | mavlink
    speedup = 10                              # the adapter's own settings follow

Fleet config (TOML), for ``eamos run``::

    [defaults.hal]                            # applied to every drone
    adapter = "sim"
    [drones.Drone3.hal]                       # per drone, merged over the defaults
    pilot = [{x_m = 0, y_m = 0, z_m = 5, hold_s = 2}]
    [drones.Drone3]
    home_m = [0.0, 10.0]                      # its home in the fleet frame (north, east)
    [safety]                                  # checked by eamos check (docs/safety.md)
    min_separation_m = 2.0
    max_altitude_m = 30
    geofence_m = [[-50, -50], [-50, 50], [50, 50], [50, -50]]
    battery_reserve_pct = 20

A fleet file may also say how to reach real drones for ``eamos rollout``
(``[ground]``, ``[defaults.ssh]``, ``[drones.X.ssh]``, ``drones.X.bind``); those
tables are kept as written here and validated by :mod:`eamos.ops.targets`
(see ``docs/operations.md``), so ``eamos run`` ignores them.

Every error names the file and the field.  Numbers must be finite and within
:data:`RANGES`:

    ready_timeout_s    0 < value <= 86400 s      peer_timeout_s     0 < value <= 3600 s
    land_timeout_s     0 < value <= 3600 s       telemetry_stale_s  0 < value <= 3600 s
    mission_timeout_s  0 < value <= 604800 s     telemetry_max_hz   0.01 <= value <= 1000 Hz
    peer_give_up_s     0 < value <= 86400 s      hal.speedup        0 < value <= 1000
    heartbeat_s        0.01 <= value <= 60 s     (and peer_timeout_s, telemetry_stale_s
                                                  longer than heartbeat_s)

A ``[drones.X]`` table must name a drone of the mission
(:meth:`FleetConfig.check_drones`), and ``adapter = "ground"`` is the ground
station's, refused for a drone.  A ``log_dir`` must be a folder (or not exist yet).
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import tomllib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .hal.kinematics import GeoFrame
from .hal.settings import did_you_mean
from .net.keys import FleetKeys, KeysError, plain_refusal
from .net.link import LinkSettings
from .program.uniform import GROUND_STATION

#: Spacing of a fleet lined up east when the fleet file gives no homes (metres).
HOME_SPACING_M = 5.0


def fleet_order(programs: Mapping[str, Any]) -> list[str]:
    """The mission's drones (not the ground station) in declaration order.

    ``programs``: every participant's drone program (they all carry the
    ``fleet`` list); drones missing from it come last, sorted.  The order of
    the default homes (:meth:`FleetConfig.homes`).
    """
    if not programs:
        return []
    first = next(iter(programs.values()))
    names = [d for d in first.fleet if d != GROUND_STATION and d in programs]
    return names + sorted(d for d in programs if d not in names and d != GROUND_STATION)


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


def _check_keys(where: str, table: Mapping[str, Any], allowed: set[str]) -> None:
    for key in table:
        if key not in allowed:
            raise ConfigError(f"{where}{key}: unknown field{did_you_mean(key, allowed)}")


def _endpoint(where: str, value: Any) -> str:
    if not isinstance(value, str) or "://" not in value:
        raise ConfigError(f'{where}: must be a ZeroMQ endpoint such as "tcp://127.0.0.1:6001"')
    return value


@dataclass(frozen=True)
class NodeConfig:
    """Everything ``eamos-node`` needs to run one drone."""

    path: Path
    drone: str
    program: Path
    log_dir: Path
    bind: str
    peers: dict[str, str]
    hal: dict[str, Any] = field(default_factory=dict)
    ready_timeout_s: float = 60.0
    land_timeout_s: float = 120.0
    mission_timeout_s: float = 600.0
    keys_dir: Path | None = None
    keys: FleetKeys | None = None  # None: plain sockets (asked for, loopback only)
    link: LinkSettings = field(default_factory=LinkSettings)
    peer_give_up_s: float | None = None
    # Waiting on a lost peer, or for Complete from a silent ground station, at
    # most this long; then the drone applies ``on_stranded`` (actors/stranded.py).
    peer_wait_limit_s: float = 20.0
    on_stranded: str = "land"

    @classmethod
    def load(cls, path: Path) -> NodeConfig:
        """Read and validate a drone config file."""
        path = Path(path)
        doc = read_toml(path)
        w = f"{path}: "
        _check_keys(
            w,
            doc,
            {
                "drone",
                "program",
                "log_dir",
                "ready_timeout_s",
                "land_timeout_s",
                "mission_timeout_s",
                "peer_wait_limit_s",
                "on_stranded",
                "net",
                "hal",
            },
        )
        drone = doc.get("drone")
        if not isinstance(drone, str) or not drone:
            raise ConfigError(
                f'{w}drone: required, the drone\'s name as in the mission (e.g. "Drone1")'
            )
        program = doc.get("program")
        if not isinstance(program, str) or not program:
            raise ConfigError(f"{w}program: required, the path of the drone's .program.json")
        net = doc.get("net")
        if not isinstance(net, dict):
            raise ConfigError(f"{w}net: required table with 'bind' and 'peers'")
        _check_keys(f"{w}net.", net, NET_FIELDS)
        bind = _endpoint(f"{w}net.bind", net.get("bind"))
        peers = net.get("peers", {})
        if not isinstance(peers, dict):
            raise ConfigError(f"{w}net.peers: must be a table of name = endpoint")
        peers = {str(k): _endpoint(f"{w}net.peers.{k}", v) for k, v in peers.items()}
        keys_dir, keys = _net_security(w, net, path.parent, drone, bind, peers)
        link = _link_settings(w, net)
        give_up = net.get("peer_give_up_s")
        if give_up is not None:
            give_up = in_range(f"{w}net.peer_give_up_s", give_up, "peer_give_up_s")
        hal = doc.get("hal", {"adapter": "sim"})
        if not isinstance(hal, dict):
            raise ConfigError(f"{w}hal: must be a table")
        _check_hal(f"{w}hal.", hal, drone=drone != GROUND_STATION)
        timeouts = {}
        for key in ("ready_timeout_s", "land_timeout_s", "mission_timeout_s", "peer_wait_limit_s"):
            if key in doc:
                timeouts[key] = in_range(f"{w}{key}", doc[key], key)
        on_stranded = doc.get("on_stranded", "land")
        if on_stranded not in END_POLICIES:
            raise ConfigError(
                f"{w}on_stranded: must be one of {', '.join(END_POLICIES)}, got {on_stranded!r}"
            )
        base = path.parent
        log_dir = doc.get("log_dir", f"logs/{drone}")
        if not isinstance(log_dir, str) or not log_dir:
            raise ConfigError(f"{w}log_dir: must be a path")
        _log_folder(f"{w}log_dir", (base / log_dir).resolve())
        return cls(
            path=path,
            drone=drone,
            program=(base / program).resolve(),
            log_dir=(base / log_dir).resolve(),
            bind=bind,
            peers=peers,
            hal=dict(hal),
            keys_dir=keys_dir,
            keys=keys,
            link=link,
            peer_give_up_s=give_up,
            on_stranded=on_stranded,
            **timeouts,
        )

    def to_toml(self) -> str:
        """This config as the TOML text :meth:`load` reads back: ``load(to_toml()) == self``.

        Paths (program, log folder, keys) are written relative to the folder of
        :attr:`path`, so a config and the files it names can move together (the
        roll-out writes a drone's config on the operator's machine for a folder on
        the drone).  The loaded :attr:`keys` are not written: they are read again
        from :attr:`keys_dir`; no ``keys_dir`` means ``plain = true``.  Raises
        ``ValueError`` for what a config file cannot say (link settings beyond
        the ``[net]`` fields, values TOML cannot hold).
        """
        link = {key: getattr(self.link, key) for key in _LINK_FIELDS}
        if LinkSettings(**link) != self.link:
            raise ValueError(
                f"{self.drone}: link settings beyond {', '.join(_LINK_FIELDS)} "
                "cannot be written to a config file"
            )
        base = Path(self.path).parent
        lines = [
            f"drone = {_toml_value(self.drone)}",
            f"program = {_toml_value(_relative(self.program, base))}",
            f"log_dir = {_toml_value(_relative(self.log_dir, base))}",
            f"ready_timeout_s = {_toml_value(self.ready_timeout_s)}",
            f"land_timeout_s = {_toml_value(self.land_timeout_s)}",
            f"mission_timeout_s = {_toml_value(self.mission_timeout_s)}",
            f"peer_wait_limit_s = {_toml_value(self.peer_wait_limit_s)}",
            f"on_stranded = {_toml_value(self.on_stranded)}",
            "",
            "[net]",
            f"bind = {_toml_value(self.bind)}",
        ]
        if self.keys_dir is not None:
            lines.append(f"keys = {_toml_value(_relative(self.keys_dir, base))}")
        else:
            lines.append("plain = true")
        lines += [f"{key} = {_toml_value(value)}" for key, value in link.items()]
        if self.peer_give_up_s is not None:
            lines.append(f"peer_give_up_s = {_toml_value(self.peer_give_up_s)}")
        lines += ["", "[net.peers]"]
        lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in self.peers.items()]
        lines += ["", "[hal]"]
        lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in self.hal.items()]
        return "\n".join(lines) + "\n"

    def write(self) -> Path:
        """Write :meth:`to_toml` to :attr:`path` (its folder is made); return the path."""
        path = Path(self.path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(self.to_toml(), encoding="utf-8")
        return path


NET_FIELDS = {
    "bind",
    "peers",
    "keys",
    "plain",
    "heartbeat_s",
    "peer_timeout_s",
    "telemetry_stale_s",
    "telemetry_max_hz",
    "peer_give_up_s",
}
"""Fields of a drone config's ``[net]`` table."""

_LINK_FIELDS = ("heartbeat_s", "peer_timeout_s", "telemetry_stale_s", "telemetry_max_hz")


def _relative(target: Path, base: Path) -> str:
    """``target`` relative to ``base`` (both resolved first, as ``load`` resolves), POSIX form."""
    return Path(os.path.relpath(Path(target).resolve(), Path(base).resolve())).as_posix()


_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def _toml_key(key: str) -> str:
    return key if _BARE_KEY.fullmatch(key) else _toml_string(key)


def _toml_string(text: str) -> str:
    """A TOML basic string: quote, backslash and control characters escaped."""
    out = []
    for ch in text:
        if ch in ('"', "\\"):
            out.append("\\" + ch)
        elif ch == "\n":
            out.append("\\n")
        elif ch == "\t":
            out.append("\\t")
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        elif 0xD800 <= ord(ch) <= 0xDFFF:
            raise ValueError(f"{text!r}: a lone surrogate cannot be written to TOML")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _toml_value(value: Any) -> str:
    """A TOML literal for the plain values of our config files (see :meth:`NodeConfig.to_toml`)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)  # inf, nan, 1e+20 and 0.1 are all TOML floats as Python writes them
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, Mapping):
        return (
            "{"
            + ", ".join(f"{_toml_key(str(k))} = {_toml_value(v)}" for k, v in value.items())
            + "}"
        )
    raise ValueError(f"cannot write {value!r} to TOML")


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


def _check_hal(where: str, hal: Mapping[str, Any], *, drone: bool) -> None:
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


def _log_folder(where: str, folder: Path) -> None:
    """Refuse a log folder that names a file (or lies under one)."""
    for part in (folder, *folder.parents):
        if part.exists():
            if not part.is_dir():
                raise ConfigError(f"{where}: {part} is a file, not a folder")
            if not os.access(part, os.W_OK | os.X_OK):
                raise ConfigError(f"{where}: {part} is not writable")
            return


def _net_security(
    w: str, net: Mapping[str, Any], base: Path, drone: str, bind: str, peers: Mapping[str, str]
) -> tuple[Path | None, FleetKeys | None]:
    """``[net] keys`` (loaded and checked) or ``plain = true`` (loopback only): exactly one."""
    plain = net.get("plain", False)
    if not isinstance(plain, bool):
        raise ConfigError(f"{w}net.plain: must be true or false")
    if "keys" in net and plain:
        raise ConfigError(f"{w}net.plain: cannot be combined with net.keys (choose one)")
    if plain:
        refusal = plain_refusal([bind, *peers.values()])
        if refusal:
            raise ConfigError(f"{w}net.plain: {refusal}")
        return None, None
    if "keys" not in net:
        raise ConfigError(
            f"{w}net.keys: required: the folder `eamos keys` made for {drone} "
            "(or plain = true, for development on loopback only)"
        )
    if not isinstance(net["keys"], str) or not net["keys"]:
        raise ConfigError(f"{w}net.keys: must be the path of a key folder")
    folder = (base / net["keys"]).resolve()
    try:
        keys = FleetKeys.load(folder, drone)
    except KeysError as exc:
        raise ConfigError(f"{w}net.keys: {exc}") from exc
    missing = keys.missing(p for p in peers if p != drone)
    if missing:
        raise ConfigError(
            f"{w}net.keys: {folder} has no public key for peer(s) {', '.join(missing)}"
        )
    return folder, keys


def _link_settings(w: str, net: Mapping[str, Any]) -> LinkSettings:
    values: dict[str, Any] = {}
    for key in _LINK_FIELDS:
        if key in net:
            values[key] = in_range(f"{w}net.{key}", net[key], key)
    try:
        return LinkSettings(**values)
    except ValueError as exc:  # the message starts with the field's name
        raise ConfigError(f"{w}net.{exc}") from exc


@dataclass(frozen=True)
class SafetySettings:
    """The fleet's ``[safety]`` section, checked by ``eamos check`` (docs/safety.md).

    Lengths in metres in the fleet frame (north, east, up from the ground);
    ``None`` or an empty polygon: not checked.
    """

    min_separation_m: float = 2.0
    max_altitude_m: float | None = None
    geofence_m: tuple[tuple[float, float], ...] = ()
    battery_reserve_pct: float | None = None


def _number(where: str, value: Any, *, positive: bool = False) -> float:
    if not isinstance(value, int | float) or isinstance(value, bool) or value != value:
        raise ConfigError(f"{where}: must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ConfigError(f"{where}: must be finite, got {value!r}")
    if positive and not value > 0:
        raise ConfigError(f"{where}: must be greater than 0, got {value!r}")
    return float(value)


def _point(where: str, value: Any, size: tuple[int, ...] = (2,)) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) not in size:
        words = " or ".join(str(n) for n in size)
        raise ConfigError(f"{where}: must be a list of {words} numbers, got {value!r}")
    return tuple(_number(f"{where}[{i}]", v) for i, v in enumerate(value))


def _safety(w: str, table: Any) -> SafetySettings:
    """Validate the ``[safety]`` table (every error names the field)."""
    if not isinstance(table, dict):
        raise ConfigError(f"{w}safety: must be a table")
    _check_keys(
        f"{w}safety.",
        table,
        {"min_separation_m", "max_altitude_m", "geofence_m", "battery_reserve_pct"},
    )
    out = SafetySettings()
    if "min_separation_m" in table:
        sep = _number(f"{w}safety.min_separation_m", table["min_separation_m"], positive=True)
        out = dataclasses.replace(out, min_separation_m=sep)
    if "max_altitude_m" in table:
        top = _number(f"{w}safety.max_altitude_m", table["max_altitude_m"], positive=True)
        out = dataclasses.replace(out, max_altitude_m=top)
    if "battery_reserve_pct" in table:
        where = f"{w}safety.battery_reserve_pct"
        reserve = _number(where, table["battery_reserve_pct"])
        if not 0 <= reserve <= 100:
            raise ConfigError(f"{where}: must be between 0 and 100, got {reserve!r}")
        out = dataclasses.replace(out, battery_reserve_pct=reserve)
    if "geofence_m" in table:
        where = f"{w}safety.geofence_m"
        raw = table["geofence_m"]
        if not isinstance(raw, list) or len(raw) < 3:
            raise ConfigError(
                f"{where}: must be a polygon, a list of at least 3 [north_m, east_m] points"
            )
        fence = tuple(_point(f"{where}[{i}]", p) for i, p in enumerate(raw))
        out = dataclasses.replace(out, geofence_m=tuple((p[0], p[1]) for p in fence))
    return out


@dataclass(frozen=True)
class FleetConfig:
    """Per-drone hardware settings for a run: defaults merged with each drone's table."""

    path: Path | None
    defaults: dict[str, Any]
    drones: dict[str, dict[str, Any]]
    # Roll-out over SSH (eamos rollout): the raw tables, validated by eamos.ops.targets.
    ssh_defaults: dict[str, Any] = field(default_factory=dict)
    ssh: dict[str, dict[str, Any]] = field(default_factory=dict)
    binds: dict[str, Any] = field(default_factory=dict)
    ground: dict[str, Any] = field(default_factory=dict)
    # The fleet frame (eamos check): [safety], and each drone's home_m / home_lla.
    safety: SafetySettings = field(default_factory=SafetySettings)
    homes_m: dict[str, tuple[float, float]] = field(default_factory=dict)
    homes_lla: dict[str, tuple[float, ...]] = field(default_factory=dict)

    def homes(self, drones: Iterable[str]) -> dict[str, tuple[float, float]]:
        """Each drone's home in the fleet frame, (north_m, east_m), in ``drones``' order.

        ``home_m`` as given; else ``home_lla`` seen from the first drone (in
        ``drones``' order) with a ``home_lla`` (the frame's origin); else lined
        up :data:`HOME_SPACING_M` apart east, the first at the origin.  Used by
        the pre-flight check, the simulated drones of ``eamos run`` and the
        pictures, so all three show one geometry (docs/safety.md).
        """
        names = list(drones)
        homes = {d: (0.0, i * HOME_SPACING_M) for i, d in enumerate(names)}
        homes.update({d: h for d, h in self.homes_m.items() if d in homes})
        lla = [d for d in names if d in self.homes_lla]
        if lla:
            origin = self.homes_lla[lla[0]]
            frame = GeoFrame(origin[0], origin[1], origin[2] if len(origin) > 2 else 0.0)
            for d in lla:
                here = self.homes_lla[d]
                north, east, _ = frame.from_lla(here[0], here[1], 0.0)
                homes[d] = (north, east)
        return homes

    def hal_for(self, drone: str) -> dict[str, Any]:
        """The merged ``[hal]`` table of one drone."""
        merged = dict(self.defaults)
        merged.update(self.drones.get(drone, {}))
        merged.setdefault("adapter", "sim")
        return merged

    def check_drones(self, drones: Iterable[str]) -> None:
        """Refuse a ``[drones.X]`` table for a drone the mission does not have (a typo, mostly).

        ``drones`` are the mission's drones; the error names the file, the table and the
        nearest name.
        """
        known = set(drones)
        tables = set(self.drones) | set(self.ssh) | set(self.binds)
        tables |= set(self.homes_m) | set(self.homes_lla)
        for name in sorted(tables - known):
            listed = f"; the mission's drones: {', '.join(sorted(known)) or 'none'}"
            raise ConfigError(
                f"{self.path}: drones.{name}: not a drone of the mission"
                f"{did_you_mean(name, known)}{listed}"
            )

    @classmethod
    def empty(cls) -> FleetConfig:
        return cls(None, {"adapter": "sim"}, {})

    @classmethod
    def load(cls, path: Path) -> FleetConfig:
        """Read and validate a fleet config file."""
        doc = read_toml(path)
        w = f"{path}: "
        _check_keys(w, doc, {"defaults", "drones", "ground", "safety"})
        safety = _safety(w, doc.get("safety", {}))
        homes_m: dict[str, tuple[float, float]] = {}
        homes_lla: dict[str, tuple[float, ...]] = {}
        defaults = doc.get("defaults", {})
        if not isinstance(defaults, dict):
            raise ConfigError(f"{w}defaults: must be a table")
        _check_keys(f"{w}defaults.", defaults, {"hal", "ssh"})
        drones: dict[str, dict[str, Any]] = {}
        ssh: dict[str, dict[str, Any]] = {}
        binds: dict[str, Any] = {}
        drone_tables = doc.get("drones", {})
        if not isinstance(drone_tables, dict):
            raise ConfigError(f"{w}drones: must be a table of drones, such as [drones.Drone1]")
        for name, table in drone_tables.items():
            if not isinstance(table, dict):
                raise ConfigError(f"{w}drones.{name}: must be a table")
            _check_keys(f"{w}drones.{name}.", table, {"hal", "ssh", "bind", "home_m", "home_lla"})
            if "home_m" in table and "home_lla" in table:
                raise ConfigError(f"{w}drones.{name}: give home_m or home_lla, not both")
            if "home_m" in table:
                north, east = _point(f"{w}drones.{name}.home_m", table["home_m"])
                homes_m[name] = (north, east)
            if "home_lla" in table:
                lla = _point(f"{w}drones.{name}.home_lla", table["home_lla"], (2, 3))
                if not (-90 <= lla[0] <= 90 and -180 <= lla[1] <= 180):
                    raise ConfigError(
                        f"{w}drones.{name}.home_lla: latitude -90..90 and longitude "
                        f"-180..180 degrees, got {list(lla)}"
                    )
                homes_lla[name] = lla
            hal = table.get("hal", {})
            if not isinstance(hal, dict):
                raise ConfigError(f"{w}drones.{name}.hal: must be a table")
            _check_hal(f"{w}drones.{name}.hal.", hal, drone=True)
            drones[name] = dict(hal)
            if not isinstance(table.get("ssh", {}), dict):
                raise ConfigError(f"{w}drones.{name}.ssh: must be a table")
            ssh[name] = dict(table.get("ssh", {}))
            if "bind" in table:
                binds[name] = table["bind"]
        default_hal = defaults.get("hal", {})
        if not isinstance(default_hal, dict):
            raise ConfigError(f"{w}defaults.hal: must be a table")
        _check_hal(f"{w}defaults.hal.", default_hal, drone=True)
        ssh_defaults = defaults.get("ssh", {})
        ground = doc.get("ground", {})
        for key, value in (("defaults.ssh", ssh_defaults), ("ground", ground)):
            if not isinstance(value, dict):
                raise ConfigError(f"{w}{key}: must be a table")
        return cls(
            path,
            dict(default_hal),
            drones,
            dict(ssh_defaults),
            ssh,
            binds,
            dict(ground),
            safety,
            homes_m,
            homes_lla,
        )
