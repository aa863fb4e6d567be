"""A node restarted mid-mission: it resumes from what it reported, or refuses to rejoin.

A drone's node killed and started again with the same config would otherwise run
its program from the start while its peers (and the ground station) resend every
trigger and the Start at once (:mod:`eamos.net.incarnation`), so a ``Takeoff`` could
fire before the ``Arm`` it follows.

The node's record, in its log folder (:class:`NodeJournal`): ``node-state.json``, the
deployment and program it runs and how far it got (``ready``: started, no trigger
has reached a node yet; ``running``: written before the first trigger reaches a
node; ``ended``: its report was sent), and ``node-progress.jsonl``, every progress
event it reported to the ground station, each as it happened (a running action with
where its vehicle was when it began), and the triggers its peers acknowledged
(``{"acknowledged": [[src, dst, iteration], ...]}`` lines: a resumed node does not
send them again).  :func:`rejoin_decision` is the one decision point, pure: a node
restarted from ``ready`` rejoins; from ``running`` it resumes from its progress
(:class:`~.continuation.Replay`: what had ended is not done again, what its peers
acknowledged is not sent again) when it can, and otherwise refuses with a clear line.
"""

from __future__ import annotations

import json
import os
import sys
import threading
import time
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, TextIO

__all__ = [
    "PROGRESS_FILE",
    "RECORD_FILE",
    "NodeJournal",
    "NodeRecord",
    "RejoinDecision",
    "TriggerKey",
    "acknowledged_entry",
    "acknowledged_in",
    "read_progress",
    "read_record",
    "rejoin_decision",
]

#: The node's record, in its log folder.
RECORD_FILE = "node-state.json"
#: What the node reported, one JSON line per progress event, in its log folder.
PROGRESS_FILE = "node-progress.jsonl"
#: How far a node got: started (nothing ran), a trigger reached a node, the report was sent.
PHASES = ("ready", "running", "ended")
#: One trigger: (source node, destination node, iteration).
TriggerKey = tuple[str, str, tuple[int, ...]]


def acknowledged_entry(triggers: Iterable[TriggerKey]) -> dict[str, Any]:
    """The journal line of triggers a peer acknowledged."""
    return {"acknowledged": [[src, dst, list(iteration)] for src, dst, iteration in triggers]}


def acknowledged_in(lines: Iterable[dict[str, Any]]) -> frozenset[TriggerKey]:
    """Every trigger the journal's lines say was acknowledged (malformed entries skipped)."""
    out: set[TriggerKey] = set()
    for line in lines:
        entries = line.get("acknowledged")
        for entry in entries if isinstance(entries, list) else ():
            try:
                src, dst, iteration = entry
                key = (str(src), str(dst), tuple(int(i) for i in iteration))
            except (TypeError, ValueError):
                continue
            out.add(key)
    return frozenset(out)


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
    resume: bool = False  # it had run: it replays what it reported, then goes on


def read_record(path: Path) -> NodeRecord | None:
    """The record at ``path`` (None: none, or unreadable)."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return NodeRecord.from_json(data)


def rejoin_decision(
    previous: NodeRecord | None,
    drone: str,
    mission_id: str,
    program: str,
    deployment: str,
    cannot_resume: str = "nothing records what it did",
) -> RejoinDecision:
    """Whether a node starting now runs its mission, given the record an earlier one left.

    A record of another deployment, mission or program is another run's: a
    fresh start.  Of the same one: ``ready`` (no trigger had reached a node)
    may rejoin; ``running`` resumes from what it reported, unless
    ``cannot_resume`` says why it cannot ("": it can), then it is refused;
    ``ended`` is refused (a deployment runs once).  Without a deployment (a
    config written by hand) a new run cannot be told from a restart: an
    ``ended`` record is taken for the run before, a fresh start.
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
    which = f"deployment {deployment}" if deployment else "this mission"
    if previous.phase == "running" and not cannot_resume:
        return RejoinDecision(
            True,
            True,
            f"its node before (pid {previous.pid}) was running {which} since {when}; it "
            f"resumes from what it reported ({PROGRESS_FILE}): what had ended is not done again",
            resume=True,
        )
    if previous.phase == "ended":
        why = f"deployment {deployment} already ended on this drone (at {when}): roll out again"
    else:
        why = (
            f"its node before (pid {previous.pid}) was running {which} since {when} and it "
            f"cannot resume: {cannot_resume}"
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
        self.progress_path = log_dir / PROGRESS_FILE
        self._progress: TextIO | None = None
        self._past: list[dict[str, Any]] = []  # read by decide(): progress events
        self._acknowledged: frozenset[TriggerKey] = frozenset()  # read by decide()
        self._lock = threading.Lock()
        self._told = False

    def decide(self, cannot_resume: str = "") -> RejoinDecision:
        """:func:`rejoin_decision` for this node and the record an earlier one left
        (``cannot_resume``: why this node could not resume, "" if it could)."""
        running = self.previous is not None and self.previous.phase == "running"
        lines = read_progress(self.progress_path) if running else []
        self._past = [line for line in lines if "node" in line]
        self._acknowledged = acknowledged_in(lines)
        if not cannot_resume and not self._past:
            cannot_resume = f"nothing records what it did ({PROGRESS_FILE} is missing or empty)"
        return rejoin_decision(
            self.previous,
            self.drone,
            self.mission_id,
            self.program,
            self.deployment,
            cannot_resume,
        )

    def past(self) -> list[dict[str, Any]]:
        """What the node before reported (:data:`PROGRESS_FILE`'s events, oldest first),
        as :meth:`decide` read it (empty unless its record said ``running``)."""
        return self._past

    def acknowledged(self) -> frozenset[TriggerKey]:
        """The triggers the node before had sent and its peers acknowledged (as
        :meth:`decide` read them)."""
        return self._acknowledged

    def begin(self, resume: bool) -> None:
        """Open the progress journal: appended to when resuming, emptied otherwise."""
        with self._lock:
            try:
                self.progress_path.parent.mkdir(parents=True, exist_ok=True)
                self._progress = self.progress_path.open("a" if resume else "w", encoding="utf-8")
            except OSError as exc:
                self._cannot_write(self.progress_path, exc)

    def reported(self, events: list[dict[str, Any]]) -> None:
        """Append what the node just reported (one write; on disk before a kill -9)."""
        text = "".join(json.dumps(e, separators=(",", ":")) + "\n" for e in events)
        with self._lock:
            if self._progress is None:
                return
            try:
                self._progress.write(text)
                self._progress.flush()
            except (OSError, ValueError) as exc:
                self._cannot_write(self.progress_path, exc)

    def close(self) -> None:
        """Close the progress journal (what was reported stays)."""
        with self._lock:
            if self._progress is not None:
                try:
                    self._progress.close()
                except OSError:
                    pass
                self._progress = None

    def _cannot_write(self, path: Path, exc: Exception) -> None:
        if not self._told:
            self._told = True
            say(
                self.drone,
                f"cannot write {path} ({getattr(exc, 'strerror', None) or exc}): a restart "
                "of this node could not tell what it did",
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
                self._cannot_write(self.path, exc)


def read_progress(path: Path) -> list[dict[str, Any]]:
    """The events in a progress journal (empty: none); a line cut short by a kill is left out."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return []
    events = []
    for line in text.splitlines():
        try:
            event = json.loads(line)
        except ValueError:
            continue
        if isinstance(event, dict):
            events.append(event)
    return events


def say(drone: str, text: str) -> None:
    """One line on stderr (``node.out``); never raises (a full disk loses the line only)."""
    try:
        print(f"eamos-node {drone}: {text}", file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass
