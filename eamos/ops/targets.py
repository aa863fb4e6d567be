"""Where the drones are and how to reach them: the roll-out part of a fleet file.

A fleet file (``eamos run --fleet``; :class:`eamos.config.FleetConfig`) may add,
for ``eamos rollout``::

    [ground]
    bind = "tcp://198.18.0.1:6000"    # the ground station's out-bridge, reachable from the drones
    ready_timeout_s = 120             # how long started drones wait for the ground station
    # keys = "keys/"                  # a folder copied to every drone (network keys), optional

    [defaults.ssh]                    # applied to every drone, merged under drones.X.ssh
    user = "pi"
    port = 22
    folder = "eamos"                  # on the drone; relative to the login's home, or absolute
    identity = "keys/id_ed25519"      # private key; relative to the fleet file
    known_hosts = "known_hosts"       # optional, else ssh's own (~/.ssh/known_hosts)
    node_command = "eamos-node"       # how to run eamos-node on the drone (e.g. a venv path)
    min_free_kb = 2048                # refuse to deploy with less free space (logs need room)
    connect_timeout_s = 5

    [drones.Drone1.ssh]
    host = "198.18.0.2"               # required for every drone of the mission
    [drones.Drone1]
    bind = "tcp://198.18.0.2:6001"    # optional; default tcp://<ssh.host>:<6001 + position>

Validation errors name the file and the field, like every configuration error.
"""

from __future__ import annotations

import shlex
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

from ..config import ConfigError, FleetConfig, check_keys

DEFAULT_FOLDER = "eamos"
DEFAULT_NODE_COMMAND = "eamos-node"
DEFAULT_MIN_FREE_KB = 2048
DEFAULT_CONNECT_TIMEOUT_S = 5.0
DEFAULT_READY_TIMEOUT_S = 120.0
FIRST_DRONE_PORT = 6001

SSH_FIELDS = {
    "host",
    "user",
    "port",
    "folder",
    "identity",
    "known_hosts",
    "node_command",
    "options",
    "min_free_kb",
    "connect_timeout_s",
}
GROUND_FIELDS = {"bind", "ready_timeout_s", "keys"}


@dataclass(frozen=True)
class SshTarget:
    """One drone as an SSH destination, with the folder EAMOS uses there."""

    drone: str
    host: str
    user: str | None = None
    port: int = 22
    folder: str = DEFAULT_FOLDER
    identity: Path | None = None
    known_hosts: Path | None = None
    node_command: str = DEFAULT_NODE_COMMAND
    options: tuple[str, ...] = ()
    min_free_kb: int = DEFAULT_MIN_FREE_KB
    connect_timeout_s: float = DEFAULT_CONNECT_TIMEOUT_S

    @property
    def destination(self) -> str:
        """``user@host`` (or ``host``) as ssh takes it."""
        return f"{self.user}@{self.host}" if self.user else self.host

    @property
    def label(self) -> str:
        """How messages name this drone's host: ``ubuntu@198.18.0.2:22``."""
        return f"{self.destination}:{self.port}"

    def mission_dir(self, mission: str) -> str:
        """The mission's folder on the drone (POSIX path, maybe relative to the home)."""
        return str(PurePosixPath(self.folder) / mission)

    def _options(self) -> list[str]:
        # BatchMode: never prompt (a password prompt would hang the roll-out);
        # accept-new: trust a drone seen for the first time, refuse a changed key.
        opts = [
            "-o",
            "BatchMode=yes",
            "-o",
            f"ConnectTimeout={max(1, round(self.connect_timeout_s))}",
            "-o",
            "StrictHostKeyChecking=accept-new",
            "-o",
            "ServerAliveInterval=5",
            "-o",
            "ServerAliveCountMax=3",
            "-o",
            "LogLevel=ERROR",
        ]
        if self.identity is not None:
            opts += ["-i", str(self.identity), "-o", "IdentitiesOnly=yes"]
        if self.known_hosts is not None:
            opts += ["-o", f"UserKnownHostsFile={self.known_hosts}"]
        for option in self.options:
            opts += ["-o", option]
        return opts

    def ssh_argv(self, command: str) -> list[str]:
        """``ssh`` running ``command`` (a POSIX shell command line) on the drone."""
        return ["ssh", *self._options(), "-p", str(self.port), self.destination, command]

    def scp_argv(self, sources: Iterable[Path], remote_dir: str) -> list[str]:
        """``scp`` copying local files (or folders) into ``remote_dir`` on the drone."""
        return [
            "scp",
            "-q",
            "-r",
            "-p",  # keep modification times: the stamp compares content, people compare dates
            *self._options(),
            "-P",
            str(self.port),
            *[str(s) for s in sources],
            f"{self.destination}:{remote_dir}/",
        ]

    def scp_from_argv(self, remote_path: str, local_dir: Path) -> list[str]:
        """``scp`` copying a remote folder's contents into ``local_dir``."""
        return [
            "scp",
            "-q",
            "-r",
            "-p",
            *self._options(),
            "-P",
            str(self.port),
            f"{self.destination}:{remote_path}",
            str(local_dir),
        ]

    def describe(self) -> dict[str, Any]:
        """JSON-ready settings (``rollout.json``)."""
        return {
            "host": self.host,
            "user": self.user,
            "port": self.port,
            "folder": self.folder,
            "identity": None if self.identity is None else str(self.identity),
            "known_hosts": None if self.known_hosts is None else str(self.known_hosts),
            "node_command": self.node_command,
            "options": list(self.options),
            "min_free_kb": self.min_free_kb,
            "connect_timeout_s": self.connect_timeout_s,
        }

    @classmethod
    def from_description(cls, drone: str, doc: dict[str, Any]) -> SshTarget:
        """Inverse of :meth:`describe`."""
        return cls(
            drone=drone,
            host=doc["host"],
            user=doc.get("user"),
            port=int(doc.get("port", 22)),
            folder=doc.get("folder", DEFAULT_FOLDER),
            identity=Path(doc["identity"]) if doc.get("identity") else None,
            known_hosts=Path(doc["known_hosts"]) if doc.get("known_hosts") else None,
            node_command=doc.get("node_command", DEFAULT_NODE_COMMAND),
            options=tuple(doc.get("options", ())),
            min_free_kb=int(doc.get("min_free_kb", DEFAULT_MIN_FREE_KB)),
            connect_timeout_s=float(doc.get("connect_timeout_s", DEFAULT_CONNECT_TIMEOUT_S)),
        )


@dataclass(frozen=True)
class GroundSettings:
    """The operator's machine as a participant: where the ground station binds."""

    bind: str
    ready_timeout_s: float = DEFAULT_READY_TIMEOUT_S
    keys: Path | None = None


@dataclass(frozen=True)
class FleetTargets:
    """Everything the roll-out needs to reach one mission's drones."""

    path: Path | None
    ground: GroundSettings
    drones: dict[str, SshTarget]
    endpoints: dict[str, str]  # each drone's out-bridge: it binds there, the others connect
    hal: dict[str, dict[str, Any]] = field(default_factory=dict)


def _str(where: str, value: Any, *, empty_ok: bool = False) -> str:
    if not isinstance(value, str) or (not value and not empty_ok):
        raise ConfigError(f"{where}: must be a non-empty string")
    return value


def _number(where: str, value: Any, *, integer: bool = False, minimum: float = 0) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or value < minimum:
        raise ConfigError(f"{where}: must be a number >= {minimum:g}")
    if integer and not isinstance(value, int):
        raise ConfigError(f"{where}: must be a whole number")
    return value


def _file(where: str, value: Any, base: Path, must_exist: bool) -> Path:
    path = Path(_str(where, value)).expanduser()
    if not path.is_absolute():
        path = (base / path).resolve()
    if must_exist and not path.exists():
        raise ConfigError(f"{where}: {path}: no such file")
    return path


def _endpoint_host(where: str, endpoint: Any) -> str:
    text = _str(where, endpoint)
    if not text.startswith("tcp://") or ":" not in text[len("tcp://") :]:
        raise ConfigError(f'{where}: must be a TCP endpoint such as "tcp://198.18.0.2:6001"')
    host = text[len("tcp://") :].rsplit(":", 1)[0]
    if host in ("*", "0.0.0.0", "", "::", "[::]"):
        raise ConfigError(
            f"{where}: use the address the others reach it at, not {host!r} "
            "(the same endpoint is bound and connected to)"
        )
    return host


def ssh_target(fleet: FleetConfig, drone: str) -> SshTarget:
    """The validated SSH settings of one drone (defaults merged under its own table)."""
    base = fleet.path.parent if fleet.path is not None else Path.cwd()
    w = f"{fleet.path}: " if fleet.path is not None else ""
    merged = dict(fleet.ssh_defaults)
    merged.update(fleet.ssh.get(drone, {}))
    check_keys(f"{w}defaults.ssh.", fleet.ssh_defaults, SSH_FIELDS)
    where = f"{w}drones.{drone}.ssh."
    check_keys(where, fleet.ssh.get(drone, {}), SSH_FIELDS)
    if "host" not in merged:
        raise ConfigError(
            f"{where}host: required for the roll-out: the drone's address "
            f'(add [drones.{drone}.ssh] host = "...")'
        )
    options = merged.get("options", [])
    if not isinstance(options, list) or not all(isinstance(o, str) for o in options):
        raise ConfigError(f'{where}options: must be a list of ssh -o options ("Key=value")')
    node_command = _str(f"{where}node_command", merged.get("node_command", DEFAULT_NODE_COMMAND))
    try:
        shlex.split(node_command)
    except ValueError as exc:
        raise ConfigError(f"{where}node_command: not a valid command line: {exc}") from exc
    user = merged.get("user")
    return SshTarget(
        drone=drone,
        host=_str(f"{where}host", merged["host"]),
        user=None if user is None else _str(f"{where}user", user),
        port=int(_number(f"{where}port", merged.get("port", 22), integer=True, minimum=1)),
        folder=_str(f"{where}folder", merged.get("folder", DEFAULT_FOLDER)),
        identity=None
        if "identity" not in merged
        else _file(f"{where}identity", merged["identity"], base, must_exist=True),
        known_hosts=None
        if "known_hosts" not in merged
        else _file(f"{where}known_hosts", merged["known_hosts"], base, must_exist=False),
        node_command=node_command,
        options=tuple(options),
        min_free_kb=int(
            _number(
                f"{where}min_free_kb", merged.get("min_free_kb", DEFAULT_MIN_FREE_KB), integer=True
            )
        ),
        connect_timeout_s=float(
            _number(
                f"{where}connect_timeout_s",
                merged.get("connect_timeout_s", DEFAULT_CONNECT_TIMEOUT_S),
                minimum=1,
            )
        ),
    )


def ground_settings(fleet: FleetConfig) -> GroundSettings:
    """The validated ``[ground]`` table."""
    base = fleet.path.parent if fleet.path is not None else Path.cwd()
    w = f"{fleet.path}: " if fleet.path is not None else ""
    check_keys(f"{w}ground.", fleet.ground, GROUND_FIELDS)
    if "bind" not in fleet.ground:
        raise ConfigError(
            f"{w}ground.bind: required for the roll-out: the ground station's endpoint on this "
            'machine, reachable from the drones (e.g. bind = "tcp://198.18.0.1:6000")'
        )
    bind = fleet.ground["bind"]
    _endpoint_host(f"{w}ground.bind", bind)
    return GroundSettings(
        bind=bind,
        ready_timeout_s=float(
            _number(
                f"{w}ground.ready_timeout_s",
                fleet.ground.get("ready_timeout_s", DEFAULT_READY_TIMEOUT_S),
                minimum=1,
            )
        ),
        keys=None
        if "keys" not in fleet.ground
        else _file(f"{w}ground.keys", fleet.ground["keys"], base, must_exist=True),
    )


def load_targets(fleet: FleetConfig, drones: Iterable[str]) -> FleetTargets:
    """Validate the roll-out settings of ``drones`` (the mission's, in mission order).

    A drone's endpoint defaults to ``tcp://<ssh host>:<6001 + its position>``,
    so drones sharing one computer (a simulator desktop) get distinct ports.
    """
    names = list(drones)
    w = f"{fleet.path}: " if fleet.path is not None else ""
    ground = ground_settings(fleet)
    targets: dict[str, SshTarget] = {}
    endpoints: dict[str, str] = {}
    for i, name in enumerate(names):
        target = ssh_target(fleet, name)
        targets[name] = target
        if name in fleet.binds:
            where = f"{w}drones.{name}.bind"
            _endpoint_host(where, fleet.binds[name])
            endpoints[name] = fleet.binds[name]
        else:
            host = f"[{target.host}]" if ":" in target.host else target.host
            endpoints[name] = f"tcp://{host}:{FIRST_DRONE_PORT + i}"
    return FleetTargets(
        fleet.path, ground, targets, endpoints, {n: fleet.hal_for(n) for n in names}
    )


__all__ = [
    "FleetTargets",
    "GroundSettings",
    "SshTarget",
    "ground_settings",
    "load_targets",
    "ssh_target",
]
