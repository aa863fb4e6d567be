"""A roll-out's record and timings: ``rollout.json`` in the run folder, the steps' durations.

``eamos start``, ``eamos status``, ``eamos abort`` and ``eamos logs fetch`` read
the record (:func:`read_rollout`) to find the drones a roll-out used.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .. import __version__
from .plan import DronePlan
from .ssh import RunFolderError
from .targets import FleetTargets, SshTarget

ROLLOUT_FILE = "rollout.json"
ROLLOUT_FORMAT = "eamos-rollout"
ROLLOUT_VERSION = 1

Say = Callable[[str], None]


@dataclass
class Steps:
    """Prints each step and each drone's part with its duration; keeps the durations."""

    say: Say
    durations: dict[str, float] = field(default_factory=dict)

    @contextmanager
    def step(self, name: str) -> Iterator[None]:
        """Time the ``with`` block as step ``name``; say its duration when it ends."""
        t0 = time.monotonic()
        try:
            yield
        finally:
            self.durations[name] = round(time.monotonic() - t0, 3)
        self.say(f"{name} {self.durations[name]:.2f} s")


def paper_table(durations: dict[str, float]) -> list[tuple[str, float]]:
    """Paper Table 7's roll-out rows from the step durations.

    Compilation = compile; deployment = the file transfers (deploy); total
    roll-out = every step until the fleet is ready (compile, probe, deploy,
    launch, and ready when ``eamos start`` ran).
    """
    rows = [
        ("mission compilation", durations.get("compile", 0.0)),
        ("mission deployment", durations.get("deploy", 0.0)),
    ]
    total = sum(durations.get(k, 0.0) for k in ("compile", "probe", "deploy", "launch", "ready"))
    rows.append(("total roll-out", round(total, 3)))
    return rows


@dataclass
class Rollout:
    """The result of a roll-out (also ``rollout.json`` in the run folder)."""

    run_dir: Path
    mission: str
    mission_id: str
    plans: dict[str, DronePlan]
    targets: FleetTargets
    durations: dict[str, float]
    speedup: float | None
    deployment: str = ""  # this roll-out's id: its Start names it, its nodes take only that

    def to_json(self) -> dict[str, Any]:
        """The ``rollout.json`` document."""
        return {
            "format": ROLLOUT_FORMAT,
            "version": ROLLOUT_VERSION,
            "eamos": __version__,
            "mission": self.mission,
            "mission_id": self.mission_id,
            "deployment": self.deployment,
            "run_dir": str(self.run_dir),
            "fleet_file": None if self.targets.path is None else str(self.targets.path),
            "speedup": self.speedup,
            "ground": {
                "bind": self.targets.ground.bind,
                "ready_timeout_s": self.targets.ground.ready_timeout_s,
                "keys": None if self.targets.ground.keys is None else str(self.targets.ground.keys),
            },
            "drones": {name: plan.describe() for name, plan in self.plans.items()},
            "durations": self.durations,
            "created": time.time(),
        }


def write_rollout(result: Rollout) -> Path:
    """Write ``rollout.json`` into the run folder."""
    path = result.run_dir / ROLLOUT_FILE
    path.write_text(json.dumps(result.to_json(), indent=1) + "\n")
    return path


def read_rollout(run_dir: Path) -> dict[str, Any]:
    """Read a run folder's ``rollout.json``; :class:`RunFolderError` if missing or not one."""
    path = Path(run_dir) / ROLLOUT_FILE
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError as exc:
        raise RunFolderError(
            f"{run_dir}: not a roll-out folder (no {ROLLOUT_FILE}); run `eamos rollout` first"
        ) from exc
    except (OSError, json.JSONDecodeError) as exc:
        raise RunFolderError(f"{path}: cannot read it: {exc}") from exc
    if not isinstance(doc, dict) or doc.get("format") != ROLLOUT_FORMAT:
        raise RunFolderError(f"{path}: not an EAMOS roll-out record")
    return doc


def targets_of(doc: dict[str, Any]) -> dict[str, SshTarget]:
    """The drones' SSH targets recorded in ``rollout.json``."""
    return {
        name: SshTarget.from_description(name, entry["ssh"])
        for name, entry in doc["drones"].items()
    }


__all__ = [
    "ROLLOUT_FILE",
    "ROLLOUT_FORMAT",
    "ROLLOUT_VERSION",
    "Rollout",
    "Say",
    "Steps",
    "paper_table",
    "read_rollout",
    "targets_of",
    "write_rollout",
]
