"""A drone's config file (``eamos-node --config``): :class:`NodeConfig`.

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
    battery_reserve_pct = 20                  # inside a Try, an action fails below this battery
                                              # (the fleet's [safety] value; default: none)
    deployment = "a1b2c3d4e5f60718"           # the roll-out (or eamos run) this config is of:
                                              # the node starts only on its Start (default:
                                              # none, any Start)

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

Every error names the file and the field.  Numbers must be finite and within
their range:

    ready_timeout_s    0 < value <= 86400 s      peer_timeout_s     0 < value <= 3600 s
    land_timeout_s     0 < value <= 3600 s       telemetry_stale_s  0 < value <= 3600 s
    mission_timeout_s  0 < value <= 604800 s     telemetry_max_hz   0.01 <= value <= 1000 Hz
    peer_give_up_s     0 < value <= 86400 s      hal.speedup        0 < value <= 1000
    battery_reserve_pct  0 < value <= 100 %
    heartbeat_s        0.01 <= value <= 60 s     (and peer_timeout_s, telemetry_stale_s
                                                  longer than heartbeat_s)

``adapter = "ground"`` is the ground station's, refused for a drone.  A
``log_dir`` must be a folder (or not exist yet).  The ranges are
:data:`eamos.config.validation.RANGES`.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..hal.settings import DISARM_AFTER_LANDING_S
from ..net.keys import FleetKeys, KeysError, plain_refusal
from ..net.link import LinkSettings
from ..program.uniform import GROUND_STATION
from .toml_text import relative, toml_key, toml_value
from .validation import (
    END_POLICIES,
    ConfigError,
    check_adapter,
    check_hal,
    check_keys,
    endpoint,
    in_range,
    key_shown,
    log_folder,
    participant_name,
    path_field,
    read_toml,
)

#: A deployment id (the roll-out's, or ``eamos run``'s): what the wire's Start carries.
DEPLOYMENT_ID = re.compile(r"[A-Za-z0-9._-]{0,64}")

#: In a drone's log folder: its exit code, written when it ran in a process shared
#: with other drones (the process's own exit code is the worst of theirs).
EXIT_CODE_FILE = "exit_code"


#: Vehicle seconds a MAVLink autopilot may take to disarm by itself after the landing
#: its Land action saw: PX4's COM_DISARM_LAND (2 s) after its land detector, ArduCopter's
#: about 2 s after "Land complete", with room for the land detector and a HEARTBEAT.
AUTOPILOT_DISARM_WAIT_S = 10.0
#: Wall seconds added to a simulated drone's wait (its pacing thread on a loaded machine).
SIM_DISARM_SLACK_S = 2.0


def disarm_wait_s(hal: Mapping[str, Any]) -> float:
    """How long a drone with these ``[hal]`` settings waits after its part for its vehicle
    to disarm by itself after landing, in wall seconds (0: it never does).

    The simulated drone disarms ``disarm_after_landing_s`` after touchdown (0: never;
    :mod:`eamos.hal.sim.landing`); a MAVLink autopilot within
    :data:`AUTOPILOT_DISARM_WAIT_S`; both scaled by the adapter's ``speedup``.  The
    wait ends as soon as the telemetry shows the vehicle disarmed (or in the air).
    """
    adapter = hal.get("adapter", "sim")
    speedup = hal.get("speedup", 1.0)
    speedup = float(speedup) if isinstance(speedup, int | float) and speedup > 0 else 1.0
    if adapter == "sim":
        delay = hal.get("disarm_after_landing_s", DISARM_AFTER_LANDING_S)
        if not isinstance(delay, int | float) or delay <= 0:
            return 0.0
        return float(delay) / speedup + SIM_DISARM_SLACK_S
    if adapter == "mavlink":
        return AUTOPILOT_DISARM_WAIT_S / speedup
    return 0.0  # the fake and the ground adapters never stand armed on the ground


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
    # Inside a Try's Body an action fails when the battery drops below this
    # (actors/logic/actions.py); None: a low battery fails nothing.
    battery_reserve_pct: float | None = None
    # The roll-out (or ``eamos run``) this config belongs to: the node starts only on
    # the ground station's Start naming it (actors/inbound.py); "": any Start.
    deployment: str = ""

    @property
    def disarm_wait_s(self) -> float:
        """How long (wall seconds) the drone waits, once its part is over, for its vehicle
        to disarm by itself after a landing (0: not at all); see :func:`disarm_wait_s`."""
        return disarm_wait_s(self.hal)

    @classmethod
    def load(cls, path: Path) -> NodeConfig:
        """Read and validate a drone config file."""
        path = Path(path)
        doc = read_toml(path)
        w = f"{path}: "
        check_keys(
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
                "battery_reserve_pct",
                "deployment",
                "net",
                "hal",
            },
        )
        drone = doc.get("drone")
        if drone is None or drone == "":
            raise ConfigError(
                f'{w}drone: required, the drone\'s name as in the mission (e.g. "Drone1")'
            )
        participant_name(f"{w}drone", drone, "drone name")
        program = doc.get("program")
        if program is None or program == "":
            raise ConfigError(f"{w}program: required, the path of the drone's .program.json")
        path_field(f"{w}program", program, "path of the drone's .program.json")
        net = doc.get("net")
        if not isinstance(net, dict):
            raise ConfigError(f"{w}net: required table with 'bind' and 'peers'")
        check_keys(f"{w}net.", net, NET_FIELDS)
        bind = endpoint(f"{w}net.bind", net.get("bind"), bind=True)
        peers = net.get("peers", {})
        if not isinstance(peers, dict):
            raise ConfigError(f"{w}net.peers: must be a table of name = endpoint")
        for name, value in peers.items():
            participant_name(f"{w}net.peers.{key_shown(name)}", name)
            endpoint(f"{w}net.peers.{name}", value)
        keys_dir, keys = _net_security(w, net, path.parent, drone, bind, peers)
        link = _link_settings(w, net)
        give_up = net.get("peer_give_up_s")
        if give_up is not None:
            give_up = in_range(f"{w}net.peer_give_up_s", give_up, "peer_give_up_s")
        hal = doc.get("hal", {"adapter": "sim"})
        if not isinstance(hal, dict):
            raise ConfigError(f"{w}hal: must be a table")
        check_hal(f"{w}hal.", hal, drone=drone != GROUND_STATION)
        check_adapter(w, hal, drone)
        timeouts: dict[str, float] = {}
        for key in ("ready_timeout_s", "land_timeout_s", "mission_timeout_s", "peer_wait_limit_s"):
            if key in doc:
                timeouts[key] = in_range(f"{w}{key}", doc[key], key)
        if "battery_reserve_pct" in doc:
            timeouts["battery_reserve_pct"] = in_range(
                f"{w}battery_reserve_pct", doc["battery_reserve_pct"], "battery_reserve_pct"
            )
        on_stranded = doc.get("on_stranded", "land")
        if on_stranded not in END_POLICIES:
            raise ConfigError(
                f"{w}on_stranded: must be one of {', '.join(END_POLICIES)}, got {on_stranded!r}"
            )
        deployment = doc.get("deployment", "")
        if not isinstance(deployment, str) or not DEPLOYMENT_ID.fullmatch(deployment):
            raise ConfigError(
                f"{w}deployment: must be at most 64 of the characters A-Z a-z 0-9 . _ - "
                "(the roll-out's id, written by eamos rollout and eamos run)"
            )
        base = path.parent
        log_dir = path_field(f"{w}log_dir", doc.get("log_dir", f"logs/{drone}"))
        log_folder(f"{w}log_dir", (base / log_dir).resolve(), base)
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
            deployment=deployment,
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
            f"drone = {toml_value(self.drone)}",
            f"program = {toml_value(relative(self.program, base))}",
            f"log_dir = {toml_value(relative(self.log_dir, base))}",
            f"ready_timeout_s = {toml_value(self.ready_timeout_s)}",
            f"land_timeout_s = {toml_value(self.land_timeout_s)}",
            f"mission_timeout_s = {toml_value(self.mission_timeout_s)}",
            f"peer_wait_limit_s = {toml_value(self.peer_wait_limit_s)}",
            f"on_stranded = {toml_value(self.on_stranded)}",
            *(
                [f"battery_reserve_pct = {toml_value(self.battery_reserve_pct)}"]
                if self.battery_reserve_pct is not None
                else []
            ),
            *([f"deployment = {toml_value(self.deployment)}"] if self.deployment else []),
            "",
            "[net]",
            f"bind = {toml_value(self.bind)}",
        ]
        if self.keys_dir is not None:
            lines.append(f"keys = {toml_value(relative(self.keys_dir, base))}")
        else:
            lines.append("plain = true")
        lines += [f"{key} = {toml_value(value)}" for key, value in link.items()]
        if self.peer_give_up_s is not None:
            lines.append(f"peer_give_up_s = {toml_value(self.peer_give_up_s)}")
        lines += ["", "[net.peers]"]
        lines += [f"{toml_key(k)} = {toml_value(v)}" for k, v in self.peers.items()]
        lines += ["", "[hal]"]
        lines += [f"{toml_key(k)} = {toml_value(v)}" for k, v in self.hal.items()]
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
    path_field(f"{w}net.keys", net["keys"], "path of a key folder")
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
