"""Applying a staged amendment to the flying drones, from the ground station.

``eamos amend RUN_DIR NEW.go --apply`` and the monitor's Apply stage an accepted
amendment in ``RUN_DIR/amendments/N/`` (:mod:`eamos.cli.amend`), then ask the ground
station, through the operator's desk (:mod:`.operator`), to apply it.
:class:`AmendmentApplier` does, in two phases over the reliable links
(:class:`~eamos.net.wire.Amend`; the drone's side is :mod:`eamos.actors.reprogram`):

1. ``prepare`` to every drone whose program changes, with its new program.  Each
   holds the nodes the amendment changes and answers ``prepared``, or ``refused``
   with the node that has begun since the snapshot the amendment was judged against.
2. All prepared: ``commit`` to each (each switches to its new part; the triggers of
   the new arcs can only fly once every one of them was prepared, so every peer takes
   them).  One refused, or silent past the timeout: ``cancel`` to the prepared ones,
   and nothing changed.

Drones the amendment does not touch are told nothing.  Applied, the amended programs
become the run folder's ``programs/`` (the replaced ones are kept in
``amendments/N/replaced/``) and ``amendments/N/applied.json`` records when, for whom
and from whom: the next amendment is judged against what flies now.
:func:`apply_refusal` (pure) refuses first what the drones cannot take: a change to the
ground station's own part, or one needing a link the roll-out did not make.
"""

from __future__ import annotations

import json
import shutil
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from eamos.actors.reprogram import change_refusal
from eamos.actors.wiring import connected_peers
from eamos.net import wire
from eamos.program.format import DroneProgram, ProgramError, load_program
from eamos.program.uniform import GROUND_STATION

if TYPE_CHECKING:
    from .station import GroundStation

__all__ = [
    "APPLIED_FILE",
    "APPLY_TIMEOUT_S",
    "JUDGED_AGAINST",
    "AmendmentApplier",
    "apply_refusal",
    "changed_drones",
    "judged_against",
    "read_applied",
    "read_programs",
]

#: What an applied amendment's folder records.
APPLIED_FILE = "applied.json"
#: The key of ``amendment.json`` naming the programs (by checksum) it was checked against.
JUDGED_AGAINST = "judged_against"
#: How long each phase waits for every drone's answer.
PHASE_TIMEOUT_S = 30.0
#: How long a client waits for the desk's answer to ``amend``: three phases, each bounded.
APPLY_TIMEOUT_S = 3 * PHASE_TIMEOUT_S + 10.0


def read_programs(folder: Path) -> dict[str, DroneProgram]:
    """Every ``*.program.json`` in ``folder``, by participant (ProgramError if damaged)."""
    files = sorted(folder.glob("*.program.json")) if folder.is_dir() else []
    return {p.drone: p for p in map(load_program, files)}


def judged_against(running: Mapping[str, DroneProgram]) -> dict[str, str]:
    """What ``amendment.json`` records of the programs an amendment was checked against:
    applied later, it may replace only those (another amendment applied in between would
    otherwise be undone)."""
    return {name: program.checksum for name, program in running.items()}


def read_applied(run_dir: Path, number: str) -> list[str]:
    """The drones amendment ``number`` was applied to ([] if it was not, or unreadable)."""
    try:
        doc = json.loads((Path(run_dir) / "amendments" / number / APPLIED_FILE).read_text())
    except (OSError, ValueError):
        return []
    drones = doc.get("drones") if isinstance(doc, dict) else None
    return [str(d) for d in drones] if isinstance(drones, list) else []


def changed_drones(
    running: Mapping[str, DroneProgram], amended: Mapping[str, DroneProgram]
) -> list[str]:
    """The participants whose program the amendment changes, in the running order: by
    what they run (nodes, arcs, the telemetry they read), not by the file's name."""
    return [
        name
        for name, program in running.items()
        if name in amended and _runs(amended[name]) != _runs(program)
    ]


def _runs(program: DroneProgram) -> tuple[object, ...]:
    nodes = [n.executed() for n in program.nodes]
    return (nodes, program.arcs, program.telemetry_from, program.drone_type)


def apply_refusal(running: Mapping[str, DroneProgram], amended: Mapping[str, DroneProgram]) -> str:
    """Why the amended programs cannot be applied to the flying drones ("" when they can).

    Pure.  The ground station's own part (the start, a bare pause) does not change while it
    runs; a drone may not need a link the roll-out did not make.
    """
    if set(amended) != set(running):
        return "the amendment has other participants than the running mission"
    changed = changed_drones(running, amended)
    if GROUND_STATION in changed:
        return (
            "the amendment changes the ground station's own part (the start, a bare pause): "
            "it cannot be applied in flight; roll out again"
        )
    for name in changed:
        why = change_refusal(running[name], amended[name])
        if why:
            return f"{name}: {why}"
    before, after = connected_peers(dict(running)), connected_peers(dict(amended))
    for name, peers in after.items():
        more = sorted(set(peers) - set(before.get(name, ())))
        if more:
            return f"{name} would need a link to {', '.join(more)}, which the roll-out did not make"
    return ""


class AmendmentApplier:
    """The ground station's side of applying an amendment (module docstring).

    :meth:`answer` takes the drones' answers (on the link's thread); :meth:`apply` runs
    on the operator desk's thread and returns why the amendment was not applied ("").
    """

    def __init__(
        self,
        station: GroundStation,
        run_dir: Path,
        timeout_s: float = PHASE_TIMEOUT_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.station = station
        self.run_dir = Path(run_dir)
        self.timeout_s = timeout_s
        self.clock = clock
        self._cond = threading.Condition()
        self._answers: dict[tuple[int, str], wire.Amend] = {}  # (number, drone) -> answer
        station.amendment_answers = self.answer

    def answer(self, msg: wire.Amend) -> None:
        """A drone's answer to a phase."""
        with self._cond:
            self._answers[(msg.number, msg.sender)] = msg
            self._cond.notify_all()

    def apply(self, number_text: str, origin: str) -> str:
        """Apply ``amendments/<number_text>/`` to the drones it changes ("" when applied)."""
        runtime = self.station.runtime
        if runtime is None or not self.station.started or self.station.over:
            return "the mission is not flying: nothing to apply to"
        if not number_text.isdigit():
            return f"{number_text!r} is not an amendment number"
        number = int(number_text)
        folder = self.run_dir / "amendments" / str(number)
        try:
            doc = json.loads((folder / "amendment.json").read_text(encoding="utf-8"))
            running = read_programs(self.run_dir / "programs")
            amended = read_programs(folder / "programs")
        except (OSError, ValueError, ProgramError) as exc:
            return f"amendment {number} cannot be read ({exc})"
        if not isinstance(doc, dict) or doc.get("accepted") is not True:
            return f"amendment {number} was refused by its check: nothing to apply"
        if (folder / APPLIED_FILE).exists():
            return f"amendment {number} was applied already"
        if doc.get(JUDGED_AGAINST) != judged_against(running):
            return (
                f"amendment {number} was checked against other programs than those flying now "
                "(another amendment applied since?): check it again"
            )
        why = apply_refusal(running, amended)
        drones = changed_drones(running, amended)
        if why or not drones:
            return why or f"amendment {number} changes no drone's program any more"
        runtime.log.warning("mission.amendment", number=number, drones=drones, origin=origin)
        for drone in drones:
            self._send(number, drone, "prepare", amended[drone].to_json().encode())
        answers = self._wait(number, drones, ("prepared", "refused"))
        refused = [
            f"{d}: {answers[d].reason}" if d in answers else f"{d}: no answer"
            for d in drones
            if d not in answers or answers[d].phase != "prepared"
        ]
        if refused:
            prepared = [d for d in drones if d in answers and answers[d].phase == "prepared"]
            for drone in prepared:
                self._send(number, drone, "cancel")
            self._wait(number, prepared, ("cancelled", "refused"))
            runtime.log.warning("mission.amendment.refused", number=number, why=refused)
            return "not applied, nothing changed: " + "; ".join(refused)
        for drone in drones:
            # A node of this drone that restarts from now on runs the amended program:
            # its Ready names that one (the ground station refuses any other).
            self.station.checksums[drone] = amended[drone].checksum
            self._send(number, drone, "commit")
        answers = self._wait(number, drones, ("committed", "refused"))
        silent = [d for d in drones if d not in answers or answers[d].phase != "committed"]
        self._record(folder, amended, drones, origin)
        if silent:
            runtime.log.error("mission.amendment.unconfirmed", number=number, drones=silent)
            return (
                f"amendment {number} was committed, but {', '.join(silent)} did not confirm "
                "the switch: watch them"
            )
        runtime.log.warning("mission.amendment.applied", number=number, drones=drones)
        return ""

    def _send(self, number: int, drone: str, phase: str, program: bytes = b"") -> None:
        assert self.station.runtime is not None
        with self._cond:
            self._answers.pop((number, drone), None)
        self.station.runtime.send(
            wire.Amend(
                mission=self.station.mission_id,
                sender=GROUND_STATION,
                dest=drone,
                number=number,
                phase=phase,  # type: ignore[arg-type]  # one of the ground station's
                program=program,
            )
        )

    def _wait(
        self, number: int, drones: list[str], phases: tuple[str, ...]
    ) -> dict[str, wire.Amend]:
        """The answers in ``phases`` of ``drones``, once all came or the timeout passed."""
        deadline = self.clock() + self.timeout_s

        def got() -> dict[str, wire.Amend]:
            out = {d: self._answers.get((number, d)) for d in drones}
            return {d: a for d, a in out.items() if a is not None and a.phase in phases}

        with self._cond:
            while len(got()) < len(drones):
                left = deadline - self.clock()
                if left <= 0:
                    break
                self._cond.wait(left)
            return got()

    def _record(
        self,
        folder: Path,
        amended: Mapping[str, DroneProgram],
        drones: list[str],
        origin: str,
    ) -> None:
        """The amended programs and their pictures become the run folder's (the replaced
        ones kept in ``replaced/``)."""
        replaced = folder / "replaced"
        replaced.mkdir(exist_ok=True)
        programs = self.run_dir / "programs"
        for drone in drones:
            name = f"{drone}.program.json"
            shutil.copyfile(programs / name, replaced / name)
            amended[drone].save(programs / name)
            for suffix in (".dot", ".svg"):
                picture = f"mdg_{drone}{suffix}"
                if (self.run_dir / "graphs" / picture).is_file():
                    shutil.copyfile(self.run_dir / "graphs" / picture, replaced / picture)
                if (folder / "graphs" / picture).is_file():
                    shutil.copyfile(folder / "graphs" / picture, self.run_dir / "graphs" / picture)
        record = {"applied_at": time.time(), "drones": drones, "origin": origin}
        (folder / APPLIED_FILE).write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
