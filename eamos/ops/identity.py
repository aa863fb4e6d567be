"""What a roll-out deploys, identified: the fleet mission id and each program's execution digest.

Partial deployment (paper V-E) keeps a drone's program when its own part of the
mission did not change; these digests say when that is.
"""

from __future__ import annotations

import dataclasses
import hashlib
from pathlib import Path

from .. import __version__
from ..compiler import CompiledMission
from ..compiler.amendment import execution_digest


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
