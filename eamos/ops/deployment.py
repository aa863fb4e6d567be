"""What is deployed where: read from a run folder's ``rollout.json``, or from the drones.

``eamos start`` takes the run folder a roll-out wrote.  ``eamos status``,
``eamos abort`` and ``eamos logs fetch`` take either that folder or the fleet
file: then each drone's stamp (``state/<Drone>.deployed.json``, written by the
roll-out) says which mission it has, its mission id and its endpoint.
"""

from __future__ import annotations

import json
import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import ConfigError, FleetConfig
from ..program.uniform import GROUND_STATION
from .record import read_rollout, targets_of
from .ssh import DroneError, FleetError, RunFolderError, for_each, run_remote
from .targets import SshTarget, ground_settings, ssh_target

STAMP_TIMEOUT_S = 30.0


@dataclass(frozen=True)
class Deployment:
    """One mission as deployed on a fleet."""

    mission: str
    mission_id: str
    drones: list[str]
    targets: dict[str, SshTarget]
    endpoints: dict[str, str]
    ground_bind: str
    checksums: dict[str, str] = field(default_factory=dict)
    run_dir: Path | None = None
    keys_dir: Path | None = None  # the fleet's keys (`eamos keys`); None: plain sockets
    deployment: str = ""  # the roll-out's id: the Start of `eamos start` names it

    def ground_keys(self) -> Any:
        """The ground station's :class:`~eamos.net.keys.FleetKeys` (None: plain sockets)."""
        if self.keys_dir is None:
            return None
        from ..net.keys import FleetKeys, KeysError

        try:
            return FleetKeys.load(self.keys_dir, GROUND_STATION)
        except KeysError as exc:
            raise FleetError(f"the ground station's keys: {exc}") from exc

    def dir_of(self, drone: str) -> str:
        """The mission folder on ``drone``."""
        return self.targets[drone].mission_dir(self.mission)


def from_run_dir(run_dir: Path) -> Deployment:
    """The deployment a roll-out recorded in ``run_dir/rollout.json``."""
    doc = read_rollout(run_dir)
    drones = list(doc["drones"])
    return Deployment(
        mission=doc["mission"],
        mission_id=doc["mission_id"],
        drones=drones,
        targets=targets_of(doc),
        endpoints={n: doc["drones"][n]["endpoint"] for n in drones},
        ground_bind=doc["ground"]["bind"],
        checksums={n: doc["drones"][n]["program_checksum"] for n in drones},
        run_dir=Path(run_dir).resolve(),
        keys_dir=Path(doc["ground"]["keys"]) if doc["ground"].get("keys") else None,
        deployment=str(doc.get("deployment") or ""),
    )


def _stamps_script(target: SshTarget, mission: str | None) -> str:
    pattern = (
        shlex.quote(target.mission_dir(mission)) if mission else shlex.quote(target.folder) + "/*"
    )
    name = shlex.quote(target.drone)
    return f"""
for f in {pattern}/state/{name}.deployed.json; do
  [ -f "$f" ] || continue
  echo "@@stamp"; cat "$f"; echo
done
echo "@@end"
"""


def _read_stamps(target: SshTarget, mission: str | None) -> list[dict[str, object]]:
    result = run_remote(target, _stamps_script(target, mission), STAMP_TIMEOUT_S)
    stamps = []
    for chunk in result.stdout.split("@@stamp")[1:]:
        text = chunk.split("@@end")[0].strip()
        try:
            doc = json.loads(text)
        except json.JSONDecodeError:
            continue
        if isinstance(doc, dict):
            stamps.append(doc)
    return stamps


def from_fleet(fleet_path: Path, mission: str | None) -> Deployment:
    """The deployment found on the drones of a fleet file (their stamps, over SSH).

    Without ``mission``, the drones must hold exactly one rolled-out mission.
    """
    fleet = FleetConfig.load(fleet_path)
    names = [n for n in fleet.drones.keys() | fleet.ssh.keys() if "host" in fleet.ssh.get(n, {})]
    if not names:
        raise ConfigError(f"{fleet_path}: no drone has an [drones.NAME.ssh] host")
    ground = ground_settings(fleet)
    targets = {n: ssh_target(fleet, n) for n in sorted(names)}
    found, errors = for_each(targets.values(), lambda t: _read_stamps(t, mission))
    if errors:
        raise FleetError("cannot read what is deployed on the drones", errors)
    missions = sorted({str(s.get("mission")) for stamps in found.values() for s in stamps})
    if not missions:
        where = f"mission {mission}" if mission else "any mission"
        raise FleetError(f"no drone of {fleet_path} has {where} rolled out (eamos rollout)")
    if len(missions) > 1:
        raise FleetError(
            f"the drones hold several missions ({', '.join(missions)}): choose one with --mission"
        )
    chosen = missions[0]
    stamps = {
        name: next(s for s in found[name] if s.get("mission") == chosen)
        for name in found
        if any(s.get("mission") == chosen for s in found[name])
    }
    first = next(iter(stamps.values()))
    fleet_list = first.get("fleet")
    participants = (
        [str(n) for n in fleet_list if n != GROUND_STATION]
        if isinstance(fleet_list, list)
        else sorted(stamps)
    )
    missing = [n for n in participants if n not in stamps]
    if missing:
        raise FleetError(
            f"mission {chosen}: no deployment found for {', '.join(missing)} "
            "(not in the fleet file, or never rolled out there)",
            [
                DroneError(n, targets[n].label, "not deployed", f"no stamp of {chosen}")
                for n in missing
                if n in targets
            ],
        )
    return Deployment(
        mission=chosen,
        mission_id=str(first.get("mission_id")),
        drones=participants,
        targets={n: targets[n] for n in participants},
        endpoints={n: str(stamps[n].get("endpoint")) for n in participants},
        ground_bind=ground.bind,
        checksums={n: str(stamps[n].get("checksum")) for n in participants},
        keys_dir=ground.keys,
    )


def resolve(source: Path, mission: str | None = None) -> Deployment:
    """A run folder (with ``rollout.json``) or a fleet file (then ask the drones)."""
    if not Path(source).exists():
        raise RunFolderError(f"{source}: no such run folder or fleet file")
    if Path(source).is_dir():
        deployment = from_run_dir(source)
        if mission and mission != deployment.mission:
            raise RunFolderError(f"{source}: holds mission {deployment.mission}, not {mission}")
        return deployment
    return from_fleet(Path(source), mission)


__all__ = ["Deployment", "from_fleet", "from_run_dir", "resolve"]
