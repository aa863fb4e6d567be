"""The plan of a roll-out on one drone: what to copy (partial deployment), stage and launch.

:func:`decide` compares what the probe found with what this roll-out would
deploy; :func:`stage` writes the changed files into a local staging folder;
:func:`launch_script` installs them on the drone and starts ``eamos-node``.
"""

from __future__ import annotations

import json
import shlex
import socket
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .. import __version__
from ..config import ConfigError, NodeConfig
from ..net.link import LinkSettings
from ..program.format import DroneProgram
from ..program.uniform import GROUND_STATION
from .identity import sha256_bytes
from .probe import PROBE_TIMEOUT_S, RUNNING_SH, Probe
from .ssh import DroneError, run_remote
from .targets import FleetTargets, SshTarget

STOP_OLD_NODE_S = 150  # an old node lands before it exits (its land timeout is 120 s)


@dataclass
class DronePlan:
    """What the roll-out does on one drone."""

    drone: str
    target: SshTarget
    endpoint: str
    program: DroneProgram
    digest: str
    config_text: str
    staging: Path
    copy_program: bool = True
    copy_config: bool = True
    copy_keys: bool = False
    deployed_checksum: str = ""  # the program the drone will run (kept or new)
    deployment: str = ""  # the roll-out's id (in the drone's config and stamp)
    run_dir: str = ""  # the operator's run folder of this roll-out (in the stamp)
    state: str = ""
    pid: int | None = None
    old_node: int | None = None
    old_stamp: dict[str, Any] = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)
    durations: dict[str, float] = field(default_factory=dict)

    @property
    def changed(self) -> bool:
        return self.copy_program or self.copy_config or self.copy_keys

    def copied(self) -> str:
        """What is copied, for people: ``program, config``."""
        parts = [("program", self.copy_program), ("config", self.copy_config)]
        parts.append(("keys", self.copy_keys))
        return ", ".join(name for name, copied in parts if copied) or "nothing"

    def describe(self) -> dict[str, Any]:
        return {
            "target": self.target.label,
            "ssh": self.target.describe(),
            "dir": self.target.mission_dir(self.program.mission),
            "endpoint": self.endpoint,
            "program_checksum": self.deployed_checksum,
            "compiled_checksum": self.program.checksum,
            "digest": self.digest,
            "state": self.state,
            "copied": {
                "program": self.copy_program,
                "config": self.copy_config,
                "keys": self.copy_keys,
            },
            "pid": self.pid,
            "durations": self.durations,
        }


def stamp_text(plan: DronePlan, keys_sha: str | None) -> str:
    """The stamp of what the drone has after this roll-out (``state/<Drone>.deployed.json``)."""
    doc = dict(plan.old_stamp)  # a kept program keeps its checksum, digest and file hash
    if plan.copy_program:
        doc.update(
            checksum=plan.program.checksum,
            digest=plan.digest,
            program_sha256=sha256_bytes(plan.program.to_json().encode()),
            deployed_at=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        )
    doc.update(
        drone=plan.drone,
        mission=plan.program.mission,
        mission_id=plan.program.mission_id,
        fleet=list(plan.program.fleet),
        endpoint=plan.endpoint,
        keys_sha256=keys_sha,
        eamos=__version__,
        operator=socket.gethostname(),
        # The next roll-out finds this one's ground station (eamos start) by these.
        deployment=plan.deployment,
        run_dir=plan.run_dir,
        updated_at=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    )
    return json.dumps(doc, indent=1) + "\n"


def drone_config(
    drone: str,
    mission_dir: Path,
    endpoints: dict[str, str],
    ground_bind: str,
    hal: dict[str, Any],
    ready_timeout_s: float,
    keys: bool,
    battery_reserve_pct: float | None = None,
    link: LinkSettings | None = None,
    deployment: str = "",
) -> NodeConfig:
    """A drone's ``configs/<Drone>.toml`` in ``mission_dir``, the layout of ``eamos run``.

    ``mission_dir`` is the operator's run folder; the drone's mission folder has
    the same layout, and the config names its files relative to itself, so the
    text written here is the text the drone reads.  ``battery_reserve_pct``: the
    fleet's ``[safety]`` reserve, below which a Try's Body action fails; ``link``:
    its link settings (the telemetry rate of :func:`eamos.ground.local.telemetry_links`);
    ``deployment``: the roll-out's id (the node starts only on the Start naming it).
    """
    peers = {GROUND_STATION: ground_bind}
    peers.update({n: e for n, e in endpoints.items() if n != drone})
    mission_dir = Path(mission_dir)
    # Fleet keys (eamos keys) travel in the mission folder, next to configs/; without
    # them the sockets are plain, which eamos-node allows on loopback only.
    return NodeConfig(
        path=mission_dir / "configs" / f"{drone}.toml",
        drone=drone,
        program=mission_dir / "programs" / f"{drone}.program.json",
        log_dir=mission_dir / "logs" / drone,
        bind=endpoints[drone],
        peers=peers,
        hal=dict(hal),
        ready_timeout_s=float(ready_timeout_s),
        keys_dir=mission_dir / "keys" / drone if keys else None,
        battery_reserve_pct=battery_reserve_pct,
        link=link if link is not None else LinkSettings(),
        deployment=deployment,
    )


def decide(plan: DronePlan, found: Probe, keys_sha: str | None) -> None:
    """Partial deployment: copy only what differs from what the drone has."""
    stamp = found.stamp or {}
    prog_rel = f"programs/{plan.drone}.program.json"
    conf_rel = f"configs/{plan.drone}.toml"
    same_program = (
        stamp.get("digest") == plan.digest
        and stamp.get("mission_id") == plan.program.mission_id
        and stamp.get("eamos") == __version__
        and bool(stamp.get("program_sha256"))
        and found.sums.get(prog_rel) == stamp.get("program_sha256")
    )
    plan.old_stamp = stamp
    plan.copy_program = not same_program
    plan.deployed_checksum = plan.program.checksum if plan.copy_program else stamp["checksum"]
    config_sha = sha256_bytes(plan.config_text.encode())
    plan.copy_config = found.sums.get(conf_rel) != config_sha
    plan.copy_keys = keys_sha is not None and stamp.get("keys_sha256") != keys_sha
    plan.old_node = found.pid if found.alive else None
    if plan.copy_program:
        plan.state = "changed, redeployed" if stamp else "new, deployed"
    else:
        plan.state = "unchanged, kept"


def stage(plan: DronePlan, keys: Path | None, keys_sha: str | None) -> list[Path]:
    """Write what must be copied to the drone into the local staging folder; return the paths.

    Nothing when the drone has everything already; otherwise the changed files
    and the new stamp.
    """
    if not plan.changed:
        return []
    plan.staging.mkdir(parents=True, exist_ok=True)
    files: list[Path] = []
    if plan.copy_program:
        files.append(plan.program.save(plan.staging / f"{plan.drone}.program.json"))
    if plan.copy_config:
        path = plan.staging / f"{plan.drone}.toml"
        path.write_text(plan.config_text)
        files.append(path)
    if plan.copy_keys and keys is not None:
        files.append(keys / plan.drone)  # arrives as .incoming/<Drone>/<Drone>/
    stamp = plan.staging / f"{plan.drone}.deployed.json"
    stamp.write_text(stamp_text(plan, keys_sha))
    files.append(stamp)
    return files


def human_kb(kb: int | None) -> str:
    """``1.5 MB``, ``12 kB``: a size for people."""
    if kb is None:
        return "? kB"
    for unit, size in (("GB", 1 << 20), ("MB", 1 << 10)):
        if kb >= size:
            return f"{kb / size:.1f} {unit}"
    return f"{kb} kB"


def bytes_kb(paths: list[Path]) -> int:
    """How many kB ``paths`` (files or folders) take, rounded up."""
    total = 0
    for path in paths:
        if path.is_dir():
            total += sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
        else:
            total += path.stat().st_size
    return total // 1024 + 1


def diagnose_copy_failure(
    target: SshTarget, mission: str, files: list[Path], error: DroneError
) -> DroneError:
    """Say "disk full" when a failed copy left the drone's disk full.

    scp over SFTP reports a full disk only as "failed to upload file", so the
    free space is looked at after the failure.
    """
    if error.kind != "copy failed":
        return error
    script = f"df -Pk {shlex.quote(target.mission_dir(mission))} | tail -n 1"
    try:
        result = run_remote(target, script, PROBE_TIMEOUT_S)
    except DroneError:
        return error
    fields = result.stdout.split()
    if len(fields) >= 4 and fields[3].isdigit():
        free_kb, need_kb = int(fields[3]), bytes_kb(files)
        if free_kb < need_kb:
            return DroneError(
                target.drone,
                target.label,
                "disk full",
                f"{free_kb} kB free in {target.mission_dir(mission)} after the copy failed, the "
                f"files need {need_kb} kB ({error.detail})",
            )
    return error


def launch_script(target: SshTarget, mission: str) -> str:
    """Remote script of the launch step: install staged files, stop an old node, start."""
    d = shlex.quote(target.mission_dir(mission))
    n = shlex.quote(target.drone)
    node = f'{target.node_command} --config "configs/$N.toml"'
    return f"""
D={d}; N={n}
{RUNNING_SH}cd "$D" || exit 90
I=".incoming/$N"
# Install what the deploy step staged (renames within one file system: atomic).
install() {{ if [ -e "$I/$1" ]; then rm -rf "$2" && mv -f "$I/$1" "$2" || exit 91; fi; }}
mkdir -p keys
install "$N.program.json" "programs/$N.program.json"
install "$N.toml" "configs/$N.toml"
install "$N" "keys/$N"
install "$N.deployed.json" "state/$N.deployed.json"
rm -rf "$I"
if [ -f "state/$N.pid" ]; then
  p=$(cat "state/$N.pid")
  if running "$p"; then
    echo "@@stopping $p"
    kill -TERM "$p"
    timeout {STOP_OLD_NODE_S} tail --pid="$p" -f /dev/null 2>/dev/null
    if running "$p"; then kill -KILL "$p"; fi
  fi
fi
rm -rf "logs/$N.prev"
if [ -d "logs/$N" ]; then mv "logs/$N" "logs/$N.prev"; fi
mkdir -p "logs/$N" || exit 91
PYTHONUNBUFFERED=1 nohup {node} > "logs/$N/node.out" 2>&1 < /dev/null &
echo $! > "state/$N.pid"
echo "@@pid $!"
"""


def check_security(targets: FleetTargets, participants: list[str]) -> None:
    """Fleet keys for every participant, or every endpoint on loopback (ConfigError).

    eamos-node refuses plain sockets off loopback, so a fleet on a network
    needs the keys of ``eamos keys``; checked here, before any drone is touched.
    """
    from ..net.keys import FleetKeys, KeysError, is_local_endpoint

    w = f"{targets.path}: " if targets.path is not None else ""
    keys = targets.ground.keys
    if keys is None:
        remote = [
            e
            for e in [targets.ground.bind, *targets.endpoints.values()]
            if not is_local_endpoint(e)
        ]
        if remote:
            raise ConfigError(
                f"{w}ground.keys: required: the drones talk over the network ({remote[0]}), "
                "and plain sockets are allowed on loopback only; make the fleet's keys with "
                f"`eamos keys KEYS --fleet {' '.join(participants)}` and set "
                '[ground] keys = "KEYS"'
            )
        return
    for name in participants:
        try:
            found = FleetKeys.load(keys if name == GROUND_STATION else keys / name, name)
        except KeysError as exc:
            raise ConfigError(f"{w}ground.keys: {exc}") from exc
        missing = found.missing(p for p in participants if p != name)
        if missing:
            raise ConfigError(
                f"{w}ground.keys: {keys} has no public key for {', '.join(missing)} "
                f"(make them again with `eamos keys {keys} --fleet {' '.join(participants)}`)"
            )


__all__ = [
    "STOP_OLD_NODE_S",
    "DronePlan",
    "bytes_kb",
    "check_security",
    "decide",
    "diagnose_copy_failure",
    "drone_config",
    "human_kb",
    "launch_script",
    "stage",
    "stamp_text",
]
