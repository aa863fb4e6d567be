"""Checking an amendment to a mission that flies (``eamos amend``), before anything changes.

An amendment is a new text of the running mission.  It is renumbered against the
programs the drones run (:func:`eamos.compiler.amendment.rekey`: each node keeps its
number where its place by content is the same), compared drone by drone, and then
judged:

1. **The fleet stays.**  An amendment that adds or removes a participant is refused.
2. **What has begun keeps its meaning.**  A node the amendment adds, removes or
   changes, or the head of an arc it adds or removes, must not have begun by the
   snapshot, and the tail of such an arc (a node after which something else follows)
   must not have ended (:func:`eamos.compiler.amendment.node_progress`); otherwise it
   is refused, naming the node, its line and its state.
3. **The rest is checked.**  The snapshot is continued under the amended programs on
   every branch, as ``eamos check --from`` continues it (separation, geofence,
   battery, termination, deadlock); an error finding refuses it, with the finding
   located in the amended text, unless forced.

Pure but for the virtual runs of step 3: programs, a compiled mission, a fleet and a
snapshot document in, an :class:`AmendmentReport` out.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..compiler import CompiledMission
from ..compiler.amendment import DroneChange, NodeRef, compare, node_progress, rekey
from ..config import FleetConfig
from ..program.format import DroneProgram
from ..virtual import SnapshotError, continuation
from .explore import check_mission
from .findings import CheckReport


@dataclass(frozen=True)
class Refusal:
    """Why an amendment cannot be applied; ``node``: the node it names."""

    reason: str
    node: NodeRef | None = None

    def to_json(self) -> dict[str, Any]:
        """As plain data."""
        node = None if self.node is None else self.node.__dict__
        return {"reason": self.reason, "node": node}


@dataclass(frozen=True)
class AmendmentReport:
    """What an amendment changes, and whether it may be applied."""

    mission: str
    mission_id: str
    changes: Mapping[str, DroneChange]
    refusals: tuple[Refusal, ...]
    check: CheckReport | None
    forced: bool
    #: The amended mission, renumbered against the running one (what would be applied).
    amended: CompiledMission
    #: The snapshot it was judged against: why it was written ("pause", "end") and when.
    snapshot_why: str = ""
    snapshot_at: float = 0.0

    @property
    def touched(self) -> list[str]:
        """The drones whose programs change."""
        return [d for d, c in self.changes.items() if c.changes]

    @property
    def accepted(self) -> bool:
        """True when nothing refuses it (an error finding of the check only when forced)."""
        return not self.refusals

    def lines(self, file: str) -> list[str]:
        """The report as the terminal shows it."""
        when = time.strftime("%H:%M:%S", time.localtime(self.snapshot_at))
        out = [
            f"amendment of {self.mission} (mission {self.mission_id}) by {file}, judged "
            f"against the snapshot of {when} ({self.snapshot_why or 'unknown'}):"
        ]
        for drone, change in self.changes.items():
            if not change.changes:
                continue
            parts = [
                f"{len(change.added)} added",
                f"{len(change.removed)} removed",
                f"{len(change.changed)} changed",
            ]
            if change.arcs_added or change.arcs_removed:
                parts.append(f"arcs +{len(change.arcs_added)} -{len(change.arcs_removed)}")
            at = f"switches at {change.switch.describe()}; " if change.switch else ""
            out.append(f"  {drone}: {at}{', '.join(parts)}")
            for kind, nodes in (("+", change.added), ("-", change.removed), ("~", change.changed)):
                out.extend(f"      {kind} {n.describe()}" for n in nodes)
        kept = [d for d, c in self.changes.items() if not c.changes]
        if not self.touched:
            out.append("  the amendment changes no drone's program")
        elif kept:
            out.append(f"  not touched (not interrupted): {', '.join(kept)}")
        if self.check is not None:
            out.extend(f"  {line}" for line in self.check.lines(file))
        for refusal in self.refusals:
            out.append(f"refused: {refusal.reason}")
        if self.accepted:
            forced = " (forced past the check's errors)" if self.forced else ""
            out.append(f"accepted{forced}")
        return out

    def to_json(self) -> dict[str, Any]:
        """The report as plain data (``eamos amend --json``)."""
        return {
            "mission": self.mission,
            "mission_id": self.mission_id,
            "snapshot": {"why": self.snapshot_why, "t": self.snapshot_at},
            "accepted": self.accepted,
            "forced": self.forced,
            "touched": self.touched,
            "changes": {d: c.to_json() for d, c in self.changes.items()},
            "refusals": [r.to_json() for r in self.refusals],
            "check": None if self.check is None else self.check.to_json(),
        }


def _states(snapshot: Mapping[str, Any]) -> dict[str, str]:
    """Each node a drone reported, with the last state it reported for it."""
    states: dict[str, str] = {}
    for part in (snapshot.get("participants") or {}).values():
        for key, entry in ((part or {}).get("nodes") or {}).items():
            if isinstance(entry, dict):
                states[str(key)] = str(entry.get("state", ""))
    return states


def _named(key: str, *programs: DroneProgram | None) -> NodeRef:
    for program in programs:
        if program is None:
            continue
        for node in program.nodes:
            if node.key == key:
                return NodeRef(node.key, node.drone, node.label or node.kind, node.line)
    return NodeRef(key, "", "", 0)


def begun_refusals(
    running: Mapping[str, DroneProgram],
    changes: Mapping[str, DroneChange],
    snapshot: Mapping[str, Any],
) -> list[Refusal]:
    """Rule 2 of the module docstring, each node named once: a touched node that has
    begun, a redirected node (what follows it changes) that has ended."""
    states = _states(snapshot)
    progress = node_progress(running, states)
    refusals: list[Refusal] = []
    named: set[str] = set()
    for drone, change in changes.items():
        judged = [(k, True) for k in change.touched] + [(k, False) for k in change.redirected]
        for key, touched in judged:
            got = progress.get(key)
            if got is None or key in named or (not touched and got != "ended"):
                continue
            named.add(key)
            node = _named(key, running.get(drone), *running.values())
            state = states.get(key)
            if state in ("running", "waiting"):
                how = f"is {state}"
            elif state is not None:
                how = f"has ended ({state})"
            else:
                how = "is behind the drones already (a node after it has begun)"
            what = "changes it" if touched else "changes what follows it"
            refusals.append(
                Refusal(
                    f"{node.drone or drone}: {node.describe()} {how}, and the amendment "
                    f"{what}; an amendment may change only what has not started",
                    node,
                )
            )
    return refusals


def check_amendment(
    running: Mapping[str, DroneProgram],
    amended: CompiledMission,
    snapshot: Mapping[str, Any],
    fleet: FleetConfig | None = None,
    *,
    force: bool = False,
    where: str = "snapshot",
) -> AmendmentReport:
    """Judge ``amended`` against the ``running`` programs and the run's ``snapshot``
    (a ``snapshot.json`` document); see the module docstring.

    Raises :class:`~eamos.virtual.SnapshotError` for a snapshot that is not one, or is
    of another mission than the running programs'.
    """
    past = continuation(snapshot, where)
    running_id = next(iter(running.values())).mission_id if running else ""
    if past.mission_id != running_id:
        raise SnapshotError(
            f"{where}: the snapshot is of mission {past.mission_id}, the run's programs are of "
            f"mission {running_id}"
        )
    rekeyed = rekey(running, amended)
    changes = compare(running, rekeyed.programs)
    refusals: list[Refusal] = []
    added = sorted(set(amended.programs) - set(running))
    dropped = sorted(set(running) - set(amended.programs))
    if added or dropped:
        what = "; ".join(
            f"{verb} {', '.join(names)}"
            for verb, names in (("adds", added), ("drops", dropped))
            if names
        )
        refusals.append(Refusal(f"the amendment {what}: an amendment keeps the mission's fleet"))
    else:
        refusals.extend(begun_refusals(running, changes, snapshot))
    report = None
    if not refusals and any(c.changes for c in changes.values()):
        report = check_mission(rekeyed, fleet, continuation=past)
        if not report.ok and not force:
            refusals.append(
                Refusal(
                    f"the check of the rest of the mission under the amended programs finds "
                    f"{len(report.errors)} error(s) (--force accepts it anyway)"
                )
            )
    return AmendmentReport(
        amended.mission.name,
        rekeyed.mission_id,
        changes,
        tuple(refusals),
        report,
        force and report is not None and not report.ok,
        rekeyed,
        past.why,
        past.taken_at,
    )


__all__ = ["AmendmentReport", "Refusal", "begun_refusals", "check_amendment"]


class FlyingMission:
    """The mission a run folder's drones fly now: as compiled, then each amendment applied
    to them, in order (``amendments/N/`` with ``applied.json``): its text (``mission.go``)
    renumbered against what flew before it, as ``eamos amend`` renumbered it.  The live
    look-ahead forecasts what flies (:func:`eamos.cli.run.forecast`).
    """

    def __init__(self, compiled: CompiledMission, run_dir: Path) -> None:
        self.compiled = compiled
        self.run_dir = Path(run_dir)
        self.applied = 0  # the last amendment taken in

    def now(self) -> CompiledMission:
        """The mission as it flies now (read again only when an amendment was applied)."""
        from ..compiler import MissionError, compile_mission

        root = self.run_dir / "amendments"
        done = sorted(
            int(p.parent.name) for p in root.glob("*/applied.json") if p.parent.name.isdigit()
        )
        for number in (n for n in done if n > self.applied):
            text_file = root / str(number) / "mission.go"
            try:
                text = text_file.read_text(encoding="utf-8")
                amended = compile_mission(text, str(text_file))
            except (OSError, UnicodeDecodeError, MissionError):
                continue  # not ours to judge again: it was checked when staged
            self.compiled = rekey(self.compiled.programs, amended)
            self.applied = number
        return self.compiled
