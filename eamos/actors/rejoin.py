"""A node restarted mid-mission: rejoin only when nothing had run (issue 28).

A drone's node killed and started again with the same config remembers
nothing: its nodes would run its program from the start while its peers (and
the ground station) resend every trigger and the Start at once
(:mod:`eamos.net.incarnation`), so a ``Takeoff`` could fire before the
``Arm`` it follows.  Until a restarted node can resume from what it did
(the operator-in-the-loop work: its own state restored, the predecessors
already done not run again), it rejoins only when it can prove nothing ran,
and otherwise refuses with a clear line.

The proof is the node's record, ``node-state.json`` in its log folder
(:class:`NodeJournal`): the deployment and program it runs and how far it got,
``ready`` (started, no trigger has reached a node yet), ``running`` (written
before the first trigger reaches a node: something may have run) or ``ended``
(its report was sent).  :func:`rejoin_decision` is the one decision point, pure;
resuming will replace its refusal.
"""

from __future__ import annotations

import json
import os
import sys
import threading
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

__all__ = [
    "RECORD_FILE",
    "NodeJournal",
    "NodeRecord",
    "RejoinDecision",
    "read_record",
    "rejoin_decision",
]

#: The node's record, in its log folder.
RECORD_FILE = "node-state.json"
#: How far a node got: started (nothing ran), a trigger reached a node, the report was sent.
PHASES = ("ready", "running", "ended")


@dataclass(frozen=True)
class NodeRecord:
    """What a node wrote about itself: which mission of which deployment, and how far."""

    drone: str
    mission_id: str
    program: str  # its program's checksum
    deployment: str
    phase: str  # one of PHASES
    pid: int
    at: float  # wall-clock time of the phase

    @classmethod
    def from_json(cls, data: Any) -> NodeRecord | None:
        """The record in ``data`` (None when it is not one)."""
        if not isinstance(data, dict):
            return None
        try:
            record = cls(
                drone=str(data["drone"]),
                mission_id=str(data["mission_id"]),
                program=str(data["program"]),
                deployment=str(data["deployment"]),
                phase=str(data["phase"]),
                pid=int(data["pid"]),
                at=float(data["at"]),
            )
        except (KeyError, TypeError, ValueError):
            return None
        return record if record.phase in PHASES else None


@dataclass(frozen=True)
class RejoinDecision:
    """Whether this node runs the mission (``join``), and what it found (``reason``)."""

    join: bool
    restarted: bool  # an earlier node of the same deployment ran here
    reason: str


def read_record(path: Path) -> NodeRecord | None:
    """The record at ``path`` (None: none, or unreadable)."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return NodeRecord.from_json(data)


def rejoin_decision(
    previous: NodeRecord | None, drone: str, mission_id: str, program: str, deployment: str
) -> RejoinDecision:
    """Whether a node starting now runs its mission, given the record an earlier one left.

    A record of another deployment, mission or program is another run's: a
    fresh start.  Of the same one: ``ready`` (no trigger had reached a node)
    may rejoin; ``running`` may not (refused; the operator-in-the-loop work will
    resume here instead), nor ``ended`` (a deployment runs once).  Without a
    deployment (a config written by hand) a new run cannot be told from a
    restart: an ``ended`` record is taken for the run before, a fresh start.
    """
    same = previous is not None and (
        previous.drone,
        previous.mission_id,
        previous.program,
        previous.deployment,
    ) == (drone, mission_id, program, deployment)
    if previous is None or not same or (previous.phase == "ended" and not deployment):
        return RejoinDecision(True, False, "a fresh start")
    when = time.strftime("%H:%M:%S", time.localtime(previous.at))
    if previous.phase == "ready":
        return RejoinDecision(
            True,
            True,
            f"its node before (pid {previous.pid}) had started at {when}, and no trigger had "
            "reached its nodes: nothing had run; it rejoins the mission",
        )
    if previous.phase == "ended":
        why = f"deployment {deployment} already ended on this drone (at {when}): roll out again"
    else:
        which = f"deployment {deployment}" if deployment else "this mission"
        why = (
            f"its node before (pid {previous.pid}) was running {which} since {when}; what it "
            "did is lost, and its peers would resend their triggers at once (an action before "
            "the one it follows)"
        )
        if not deployment:
            why += f"; to start this config afresh, remove {RECORD_FILE} from its log folder"
    return RejoinDecision(False, True, why)


class NodeJournal:
    """This node's record, kept as it goes (:data:`RECORD_FILE` in ``log_dir``).

    Writes are atomic (a temporary file, then a rename) and never raise: a
    record that cannot be written is said once on stderr (``node.out``), and
    the mission goes on.
    """

    def __init__(
        self, log_dir: Path, drone: str, mission_id: str, program: str, deployment: str
    ) -> None:
        self.path = log_dir / RECORD_FILE
        self.drone = drone
        self.mission_id = mission_id
        self.program = program
        self.deployment = deployment
        self.previous = read_record(self.path)
        self._lock = threading.Lock()
        self._told = False

    def decide(self) -> RejoinDecision:
        """:func:`rejoin_decision` for this node and the record an earlier one left."""
        return rejoin_decision(
            self.previous, self.drone, self.mission_id, self.program, self.deployment
        )

    def mark(self, phase: str) -> None:
        """Record that this node reached ``phase`` (one of :data:`PHASES`)."""
        record = NodeRecord(
            self.drone,
            self.mission_id,
            self.program,
            self.deployment,
            phase,
            os.getpid(),
            time.time(),
        )
        tmp = self.path.with_name(f".{RECORD_FILE}.{os.getpid()}")
        with self._lock:
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                tmp.write_text(json.dumps(asdict(record)) + "\n", encoding="utf-8")
                os.replace(tmp, self.path)
            except OSError as exc:
                if not self._told:
                    self._told = True
                    say(
                        self.drone,
                        f"cannot write {self.path} ({exc.strerror}): a restart of this node "
                        "could not tell whether anything ran",
                    )


def say(drone: str, text: str) -> None:
    """One line on stderr (``node.out``); never raises (a full disk loses the line only)."""
    try:
        print(f"eamos-node {drone}: {text}", file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass
