"""A fleet file (``eamos run --fleet``, ``eamos check --fleet``): :class:`FleetConfig`.

Fleet config (TOML), for ``eamos run``::

    [defaults.hal]                            # applied to every drone
    adapter = "sim"
    [types.DroneType2.hal]                    # per drone type, merged over the defaults
    battery_pct = 60                          # (docs/safety.md; eamos.config.types)
    [drones.Drone3.hal]                       # per drone, merged over its type and the defaults
    pilot = [{x_m = 0, y_m = 0, z_m = 5, hold_s = 2}]
    [drones.Drone3]
    home_m = [0.0, 10.0]                      # its home in the fleet frame (north, east)
    [safety]                                  # checked by eamos check (docs/safety.md)
    min_separation_m = 2.0
    max_altitude_m = 30
    geofence_m = [[-50, -50], [-50, 50], [50, 50], [50, -50]]
    battery_reserve_pct = 20
    [net]                                     # eamos run's links (docs/configuration.md)
    ground_telemetry_hz = 2                   # telemetry to the ground station, newest only

A fleet file may also say how to reach real drones for ``eamos rollout``
(``[ground]``, ``[defaults.ssh]``, ``[drones.X.ssh]``, ``drones.X.bind``); those
tables are kept as written here and validated by :mod:`eamos.ops.targets`
(see ``docs/operations.md``), so ``eamos run`` ignores them.

A ``[drones.X]`` table must name a drone of the mission
(:meth:`FleetConfig.check_drones`), and ``adapter = "ground"`` is the ground
station's, refused for a drone.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..hal.kinematics import GeoFrame
from ..hal.settings import did_you_mean
from ..net.settings import LinkSettings
from ..program.uniform import GROUND_STATION
from .types import check_type_names, embedded_names, load_types, merge_hal, type_lineage
from .validation import (
    ConfigError,
    check_hal,
    check_keys,
    key_shown,
    number,
    participant_name,
    point,
    read_toml,
)

#: Spacing of a fleet lined up east when the fleet file gives no homes (metres).
HOME_SPACING_M = 5.0
#: Bounds of [safety]: the largest minimum separation and ceiling (metres), the most
#: corners of a geofence (docs/configuration.md, "Ranges").
MAX_SEPARATION_M = 1_000.0
MAX_ALTITUDE_M = 10_000.0
MAX_FENCE_POINTS = 1_000

#: ``[net] ground_telemetry_hz`` when the fleet file does not say: a few samples a
#: second are enough for people watching; a drone whose telemetry a peer's condition
#: reads still sends at ``telemetry_max_hz`` (see :meth:`FleetConfig.telemetry_hz`).
DEFAULT_GROUND_TELEMETRY_HZ = 2.0
#: Its range: at least one sample every 2 s, within the receivers' ``telemetry_stale_s``
#: (2.5 s), so the ground station never sees a moving drone's telemetry as stale.
GROUND_TELEMETRY_HZ_RANGE = (0.5, 1000.0)
#: The rate of a drone whose telemetry another drone's conditions read: the link's default.
PEER_TELEMETRY_HZ = LinkSettings.telemetry_max_hz


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


@dataclass(frozen=True)
class LookAheadSettings:
    """The fleet's ``[look_ahead]`` section: the ground station's live look-ahead
    (docs/operations.md, "The live look-ahead").

    ``period_s``: how often it re-simulates the rest of the mission (0: never);
    ``hold_before_s``: it holds the drones of a separation conflict predicted within
    this many seconds (0: it only says so).
    """

    period_s: float = 0.0
    hold_before_s: float = 0.0


#: The look-ahead's longest period and hold horizon (seconds).
MAX_LOOK_AHEAD_S = 3600.0


def _look_ahead(w: str, table: Any) -> LookAheadSettings:
    """Validate the ``[look_ahead]`` table (every error names the field)."""
    if not isinstance(table, dict):
        raise ConfigError(f"{w}look_ahead: must be a table")
    check_keys(f"{w}look_ahead.", table, {"period_s", "hold_before_s"})
    values = {
        key: number(f"{w}look_ahead.{key}", table[key], low=0.0, high=MAX_LOOK_AHEAD_S)
        for key in ("period_s", "hold_before_s")
        if key in table
    }
    out = LookAheadSettings(**values)
    if out.hold_before_s and not out.period_s:
        raise ConfigError(f"{w}look_ahead.hold_before_s: needs look_ahead.period_s above 0")
    return out


def _safety(w: str, table: Any) -> SafetySettings:
    """Validate the ``[safety]`` table (every error names the field)."""
    if not isinstance(table, dict):
        raise ConfigError(f"{w}safety: must be a table")
    check_keys(
        f"{w}safety.",
        table,
        {"min_separation_m", "max_altitude_m", "geofence_m", "battery_reserve_pct"},
    )
    out = SafetySettings()
    if "min_separation_m" in table:
        sep = number(
            f"{w}safety.min_separation_m",
            table["min_separation_m"],
            positive=True,
            high=MAX_SEPARATION_M,
        )
        out = dataclasses.replace(out, min_separation_m=sep)
    if "max_altitude_m" in table:
        top = number(
            f"{w}safety.max_altitude_m", table["max_altitude_m"], positive=True, high=MAX_ALTITUDE_M
        )
        out = dataclasses.replace(out, max_altitude_m=top)
    if "battery_reserve_pct" in table:
        where = f"{w}safety.battery_reserve_pct"
        reserve = number(where, table["battery_reserve_pct"])
        if not 0 <= reserve <= 100:
            raise ConfigError(f"{where}: must be between 0 and 100, got {reserve!r}")
        out = dataclasses.replace(out, battery_reserve_pct=reserve)
    if "geofence_m" in table:
        where = f"{w}safety.geofence_m"
        raw = table["geofence_m"]
        if not isinstance(raw, list) or not 3 <= len(raw) <= MAX_FENCE_POINTS:
            raise ConfigError(
                f"{where}: must be a polygon, a list of 3 to {MAX_FENCE_POINTS} "
                "[north_m, east_m] points"
            )
        fence = tuple(point(f"{where}[{i}]", p) for i, p in enumerate(raw))
        out = dataclasses.replace(out, geofence_m=tuple((p[0], p[1]) for p in fence))
    return out


def _ground_telemetry_hz(w: str, table: Any) -> float:
    """Validate the ``[net]`` table; its ``ground_telemetry_hz`` (default when absent)."""
    if not isinstance(table, dict):
        raise ConfigError(f"{w}net: must be a table")
    check_keys(f"{w}net.", table, {"ground_telemetry_hz"})
    if "ground_telemetry_hz" not in table:
        return DEFAULT_GROUND_TELEMETRY_HZ
    where = f"{w}net.ground_telemetry_hz"
    hz = number(where, table["ground_telemetry_hz"])
    low, high = GROUND_TELEMETRY_HZ_RANGE
    if not low <= hz <= high:
        raise ConfigError(f"{where}: must be between {low:g} and {high:g} Hz, got {hz!r}")
    return hz


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
    # [types.NAME.hal] tables, and each drone's type lineage once bound to a mission
    # (:meth:`for_mission`): its type, then the types that type embeds.
    types: dict[str, dict[str, Any]] = field(default_factory=dict)
    lineages: dict[str, tuple[str, ...]] = field(default_factory=dict)
    # [net] ground_telemetry_hz: how often a drone's telemetry leaves for the ground station.
    ground_telemetry_hz: float = DEFAULT_GROUND_TELEMETRY_HZ
    look_ahead: LookAheadSettings = field(default_factory=LookAheadSettings)

    def telemetry_hz(self, read_by_peers: bool) -> float:
        """A drone's outgoing telemetry rate (its node config's ``net.telemetry_max_hz``).

        Telemetry is one stream per drone, the newest sample only (a burst is
        coalesced): ``ground_telemetry_hz`` when only the ground station reads it;
        at least :data:`PEER_TELEMETRY_HZ` when another drone's conditions read it
        (``read_by_peers``), so those conditions see what they saw before.
        """
        if read_by_peers:
            return max(self.ground_telemetry_hz, PEER_TELEMETRY_HZ)
        return self.ground_telemetry_hz

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
        """The merged ``[hal]`` table of one drone.

        Strongest first: ``[drones.X.hal]``, ``[types.T.hal]`` of its type (then
        of the types it embeds), ``[defaults.hal]``, its type's built-in battery
        model (simulated drones).  Types apply once the fleet is bound to a
        mission (:meth:`for_mission`); unbound, a drone has no type.
        """
        lineage = self.lineages.get(drone, ())
        return merge_hal(self.defaults, self.types, lineage, self.drones.get(drone, {}))

    def drone_type(self, drone: str) -> str:
        """The drone's type as bound by :meth:`for_mission` (``""`` if unbound)."""
        lineage = self.lineages.get(drone, ())
        return lineage[0] if lineage else ""

    def for_mission(
        self, programs: Mapping[str, Any], declared: Mapping[str, Any] | None = None
    ) -> FleetConfig:
        """This fleet bound to a mission: each drone knows its type (and what it embeds).

        ``programs``: each participant's :class:`~eamos.program.DroneProgram`
        (its ``drone_type``); ``declared``: the mission's declared types by name
        (``CompiledMission.mission.types``: what each embeds; or name -> list of
        embedded names).  Without ``declared``, a custom type the fleet does not
        name flies the Quadcopter's built-in model.  Raises :class:`ConfigError`
        for a ``[types.NAME]`` table that names no type of the mission.
        """
        embeds = {name: embedded_names(d) for name, d in (declared or {}).items()}
        used = {d: getattr(p, "drone_type", "") for d, p in programs.items() if d != GROUND_STATION}
        check_type_names(self.path, self.types, embeds, used.values())
        lineages = {d: type_lineage(t, embeds) for d, t in used.items() if t}
        return dataclasses.replace(self, lineages=lineages)

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
        check_keys(w, doc, {"defaults", "types", "drones", "ground", "safety", "net", "look_ahead"})
        safety = _safety(w, doc.get("safety", {}))
        look_ahead = _look_ahead(w, doc.get("look_ahead", {}))
        ground_telemetry_hz = _ground_telemetry_hz(w, doc.get("net", {}))
        homes_m: dict[str, tuple[float, float]] = {}
        homes_lla: dict[str, tuple[float, ...]] = {}
        defaults = doc.get("defaults", {})
        if not isinstance(defaults, dict):
            raise ConfigError(f"{w}defaults: must be a table")
        check_keys(f"{w}defaults.", defaults, {"hal", "ssh"})
        drones: dict[str, dict[str, Any]] = {}
        ssh: dict[str, dict[str, Any]] = {}
        binds: dict[str, Any] = {}
        drone_tables = doc.get("drones", {})
        if not isinstance(drone_tables, dict):
            raise ConfigError(f"{w}drones: must be a table of drones, such as [drones.Drone1]")
        for name, table in drone_tables.items():
            participant_name(f"{w}drones.{key_shown(name)}", name, "drone name")
            if not isinstance(table, dict):
                raise ConfigError(f"{w}drones.{name}: must be a table")
            check_keys(f"{w}drones.{name}.", table, {"hal", "ssh", "bind", "home_m", "home_lla"})
            if "home_m" in table and "home_lla" in table:
                raise ConfigError(f"{w}drones.{name}: give home_m or home_lla, not both")
            if "home_m" in table:
                north, east = point(f"{w}drones.{name}.home_m", table["home_m"])
                homes_m[name] = (north, east)
            if "home_lla" in table:
                lla = point(f"{w}drones.{name}.home_lla", table["home_lla"], (2, 3))
                if not (-90 <= lla[0] <= 90 and -180 <= lla[1] <= 180):
                    raise ConfigError(
                        f"{w}drones.{name}.home_lla: latitude -90..90 and longitude "
                        f"-180..180 degrees, got {list(lla)}"
                    )
                if len(lla) > 2 and not -1_000 <= lla[2] <= MAX_ALTITUDE_M:
                    raise ConfigError(
                        f"{w}drones.{name}.home_lla[2]: an altitude from -1000 to "
                        f"{MAX_ALTITUDE_M:g} m, got {lla[2]!r}"
                    )
                homes_lla[name] = lla
            hal = table.get("hal", {})
            if not isinstance(hal, dict):
                raise ConfigError(f"{w}drones.{name}.hal: must be a table")
            check_hal(f"{w}drones.{name}.hal.", hal, drone=True)
            drones[name] = dict(hal)
            if not isinstance(table.get("ssh", {}), dict):
                raise ConfigError(f"{w}drones.{name}.ssh: must be a table")
            ssh[name] = dict(table.get("ssh", {}))
            if "bind" in table:
                binds[name] = table["bind"]
        default_hal = defaults.get("hal", {})
        if not isinstance(default_hal, dict):
            raise ConfigError(f"{w}defaults.hal: must be a table")
        check_hal(f"{w}defaults.hal.", default_hal, drone=True)
        types = load_types(w, doc.get("types", {}), default_hal)
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
            types,
            ground_telemetry_hz=ground_telemetry_hz,
            look_ahead=look_ahead,
        )
