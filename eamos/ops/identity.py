"""What a roll-out deploys, identified: the fleet mission id and each program's execution digest.

Partial deployment (paper V-E) keeps a drone's program when its own part of the
mission did not change; these digests say when that is.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

from .. import __version__
from ..compiler import CompiledMission
from ..program.format import DroneProgram


def fleet_mission_id(mission: str, participants: list[str]) -> str:
    """The mission id of a roll-out: stable across edits of the same mission on one fleet.

    Drones drop messages of other missions; with the compiler's id (a hash of
    the text) a drone kept by a partial deployment would not talk to a
    redeployed one.  The roll-out stops every earlier node before it starts new
    ones, so stale nodes cannot mix in.
    """
    text = f"eamos-fleet {__version__}\n{mission}\n{','.join(participants)}"
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def restamp(compiled: CompiledMission, mission_id: str) -> CompiledMission:
    """``compiled`` with every program carrying ``mission_id`` (checksums recomputed)."""
    programs = {
        name: dataclasses.replace(prog, mission_id=mission_id)
        for name, prog in compiled.programs.items()
    }
    return dataclasses.replace(compiled, mission_id=mission_id, programs=programs)


# Node fields that describe rather than decide: a proxy stands for another
# drone's node, so only its identity and structure matter here.
_POSITION_FIELDS = ("line", "col")
_PROXY_DESCRIPTIVE = ("label", "action", "args", "cond", "count", "block")


def execution_digest(program: DroneProgram) -> str:
    """``sha256:`` of what the drone executes: the program minus descriptive fields.

    Equal digests mean the drone behaves the same (partial deployment keeps it).
    Left out: the mission id and file name, source positions, and the labels,
    actions, arguments and conditions of proxy nodes (nodes of other drones,
    which this drone never runs).
    """
    body = program.body()
    body.pop("mission_id", None)
    body.pop("source_file", None)
    nodes = []
    for node in body["nodes"]:
        node = {k: v for k, v in node.items() if k not in _POSITION_FIELDS}
        if not node.get("native"):
            node = {k: v for k, v in node.items() if k not in _PROXY_DESCRIPTIVE}
        nodes.append(node)
    body["nodes"] = nodes
    canonical = json.dumps(body, sort_keys=True, separators=(",", ":")).encode()
    return "sha256:" + hashlib.sha256(canonical).hexdigest()


def sha256_bytes(data: bytes) -> str:
    """Hex sha256 of ``data``."""
    return hashlib.sha256(data).hexdigest()


def folder_digest(folder: Path) -> str:
    """Hex sha256 of every file under ``folder`` (names and contents, in sorted order)."""
    digest = hashlib.sha256()
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        digest.update(path.relative_to(folder).as_posix().encode() + b"\0")
        digest.update(path.read_bytes())
    return digest.hexdigest()


__all__ = ["execution_digest", "fleet_mission_id", "folder_digest", "restamp", "sha256_bytes"]
