"""The run summary (``summary.json``): how the mission ended, and every drone's report.

One typed :class:`RunSummary` for every ground station (``eamos run``,
``eamos start``, ``eamos-node`` in the ground role) and for the reader
(:mod:`eamos.report`).  Its JSON keys (documented in ``docs/logs.md``)::

    ok, mission, mission_id, outcome, duration_s, started, run_dir,
    failures, links, drones, ground_station[, rollout]

``drones.<name>`` is the drone's own report (:class:`DroneReport`, as in its
``report.json``) plus what the ground station knows besides: ``exit_code``
(a local process), ``host`` (over SSH); a drone that sent no report has
``{"ok": false, "error": "no report", "link": ..., "last_seen": ...}`` instead,
``last_seen`` (:class:`LastSeen`) being where its last telemetry placed it.  A
MAVLink drone's report carries ``vehicle``: its autopilot, whether its link was ``signed``, and
``taken_over`` (the pilot's mode and where, m) when a pilot took it: such a drone is
not ok, and the run's detail says ``Drone2: taken over by the pilot in LOITER at
(x, y, z)``.
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from eamos.actors.report import ActionEntry, DroneReport, FinalState
from eamos.hal.api import TakenOver
from eamos.logs import report_write_error
from eamos.program.uniform import GROUND_STATION

from .last_seen import LastSeen

__all__ = [
    "ActionEntry",
    "DroneReport",
    "DroneResult",
    "FinalState",
    "LastSeen",
    "RunSummary",
    "summarize",
]

if TYPE_CHECKING:
    from .station import DroneView

NO_REPORT = "no report"


@dataclass(frozen=True)
class DroneResult:
    """One drone's entry in the summary: its report, or why there is none."""

    report: DroneReport | None  # None: the ground station never received it
    exit_code: int | None = None  # the node's exit code when it ran here (eamos run)
    host: str | None = None  # where it ran, when over SSH (eamos start)
    last_seen: LastSeen | None = None  # without a report: where its last telemetry placed it

    @property
    def ok(self) -> bool:
        """The drone finished its part (a report that says so), was left disarmed, and no
        pilot took it."""
        return (
            self.report is not None
            and self.report.ok
            and not self.left_armed
            and self.taken_over is None
        )

    @property
    def taken_over(self) -> TakenOver | None:
        """The pilot's takeover the drone's adapter saw (None: none, or no report)."""
        if self.report is None:
            return None
        return TakenOver.from_json(self.report.vehicle.get("taken_over"))

    @property
    def signed(self) -> bool | None:
        """Whether the drone's MAVLink link was signed (None: not a MAVLink drone, no report)."""
        if self.report is None:
            return None
        value = self.report.vehicle.get("signed")
        return value if isinstance(value, bool) else None

    @property
    def left_armed(self) -> str:
        """Where the drone was left armed, in words ("" when it was not, or is unknown).

        A drone whose part is over must stand disarmed on the ground: autopilots (and
        the simulated drone) disarm by themselves a moment after landing, and the drone
        waits for that before it reports.  One left hovering, or armed on the ground
        (armed, never flown, never disarmed), did not finish.
        """
        final = self.report.final if self.report is not None else None
        if final is None or not final.armed or self.taken_over is not None:
            return ""  # a pilot's vehicle is the pilot's: the takeover says where it was
        where = f"at ({final.x:.2f}, {final.y:.2f}, {final.z:.2f}) m from its home"
        if final.landed is True:
            return f"armed on the ground {where}"
        if final.landed is False:
            return f"in the air, armed, {where}"
        return f"armed {where}"

    def to_json(self, link: str | None = None) -> dict[str, Any]:
        """The ``drones.<name>`` object; ``link`` is written where no report explains the end."""
        if self.report is not None:
            out: dict[str, Any] = self.report.to_json()
        else:
            out = {"ok": False, "error": NO_REPORT}
            if link is not None:
                out["link"] = link
            if self.last_seen is not None:
                out["last_seen"] = self.last_seen.to_json()
        if self.exit_code is not None:
            out["exit_code"] = self.exit_code
        if self.host is not None:
            out["host"] = self.host
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> DroneResult:
        """Read a ``drones.<name>`` object (the inverse of :meth:`to_json`).

        Raises :class:`~eamos.actors.report.DroneReportError` (a ``ValueError``) for a
        report with missing or mistyped keys.
        """
        exit_code = data.get("exit_code")
        host = data.get("host")
        if data.get("error") == NO_REPORT and "actions" not in data:
            return cls(None, exit_code, host, LastSeen.from_json(data.get("last_seen")))
        return cls(DroneReport.from_json(data), exit_code, host)


@dataclass(frozen=True)
class RunSummary:
    """A whole run, as ``summary.json`` holds it."""

    mission: str
    mission_id: str
    outcome: str  # "ok", "not ready: ...", "aborted by the operator", "timed out ..."
    started: float  # wall-clock time of the start trigger (time zero of the logs' plots)
    duration_s: float
    run_dir: str  # the folder holding summary.json and (when local) logs/
    drones: Mapping[str, DroneResult]
    ground_station: DroneReport | None  # the ground station's own report
    failures: tuple[str, ...] = ()  # participants that died, never became ready, went silent
    links: Mapping[str, str] = field(default_factory=dict)  # each drone's last link state
    rollout: Mapping[str, Any] | None = None  # roll-out durations (eamos start)
    # The operator's commands, in order: {"t", "command", "drone" ("": all), "origin"}.
    operator_commands: tuple[Mapping[str, Any], ...] = ()

    @property
    def ok(self) -> bool:
        """The mission ended normally and every participant finished its part."""
        return (
            self.outcome == "ok"
            and all(d.ok for d in self.drones.values())
            and self.ground_station is not None
            and self.ground_station.ok
        )

    @property
    def word(self) -> str:
        """The one word for how the run ended: ``finished``, ``failed``, ``aborted``, ``timed out``.

        The same word everywhere: the CLI's last line, ``summary.json``
        (``result``), the report's title and the monitor.
        """
        if self.ok:
            return "finished"
        if self.outcome.startswith("aborted"):
            return "aborted"
        if self.outcome.startswith("timed out"):
            return "timed out"
        return "failed"

    @property
    def detail(self) -> str:
        """Why the run did not finish ("" when it did): the outcome, or the parts not ok."""
        if self.ok:
            return ""
        if self.outcome != "ok":
            return self.outcome
        left = [f"{n} left {d.left_armed}" for n, d in self.drones.items() if d.left_armed]
        taken = [f"{n}: {t.describe()}" for n, d in self.drones.items() if (t := d.taken_over)]
        left += taken
        bad = [
            n
            for n, d in self.drones.items()
            if not d.ok and not d.left_armed and d.taken_over is None
        ]
        if self.ground_station is None or not self.ground_station.ok:
            bad.append(GROUND_STATION)
        parts = (["not ok: " + ", ".join(bad)] if bad else []) + left
        return "; ".join(parts)

    def to_json(self) -> dict[str, Any]:
        """The ``summary.json`` object."""
        out: dict[str, Any] = {
            "ok": self.ok,
            "result": self.word,
            "mission": self.mission,
            "mission_id": self.mission_id,
            "outcome": self.outcome,
            "duration_s": self.duration_s,
            "started": self.started,
            "run_dir": self.run_dir,
            "failures": list(self.failures),
            "links": dict(self.links),
            "drones": {n: d.to_json(self.links.get(n)) for n, d in self.drones.items()},
            "ground_station": {} if self.ground_station is None else self.ground_station.to_json(),
        }
        if self.rollout is not None:
            out["rollout"] = dict(self.rollout)
        out["operator_commands"] = [dict(c) for c in self.operator_commands]
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> RunSummary:
        """Read a ``summary.json`` object (files from before ``failures``/``links`` too)."""
        return cls(
            mission=str(data.get("mission", "")),
            mission_id=str(data.get("mission_id", "")),
            outcome=str(data.get("outcome", "")),
            started=float(data.get("started", 0.0)),
            duration_s=float(data.get("duration_s", 0.0)),
            run_dir=str(data.get("run_dir", "")),
            drones={n: DroneResult.from_json(d) for n, d in data.get("drones", {}).items()},
            ground_station=DroneReport.from_json(data["ground_station"])
            if data.get("ground_station")
            else None,
            failures=tuple(data.get("failures", ())),
            links=dict(data.get("links", {})),
            rollout=data.get("rollout"),
            operator_commands=tuple(
                c for c in data.get("operator_commands", ()) if isinstance(c, dict)
            ),
        )

    def write(self, path: Path) -> bool:
        """Write the summary as JSON to ``path`` (its folder is created); False if it could not.

        A full disk or an unwritable folder must not cost the summary's other
        copies (the run folder's and ``--summary``'s are written one after the
        other): the error is told on stderr, naming the path, and not raised.
        A partial file is removed rather than left looking like a summary.
        """
        text = json.dumps(self.to_json(), indent=1) + "\n"
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
        except OSError as exc:
            with contextlib.suppress(OSError):
                if path.is_file() and path.stat().st_size < len(text.encode()):
                    path.unlink()
            report_write_error(path, exc, "the summary's other copies are still written")
            return False
        return True

    @classmethod
    def read(cls, path: Path) -> RunSummary:
        """Read a ``summary.json`` (OSError, ValueError when it is not one)."""
        return cls.from_json(json.loads(path.read_text(encoding="utf-8")))


def summarize(
    mission: str,
    mission_id: str,
    outcome: str,
    started: float,
    ended: float,
    run_dir: Path,
    views: Mapping[str, DroneView],
    drones: list[str],
    failures: list[str],
    ground_report: DroneReport | None,
    exits: Mapping[str, int] | None = None,
    hosts: Mapping[str, str] | None = None,
) -> RunSummary:
    """The summary of a run from the ground station's views at its end."""
    exits = exits or {}
    hosts = hosts or {}
    return RunSummary(
        mission=mission,
        mission_id=mission_id,
        outcome=outcome,
        started=started,
        duration_s=round(ended - started, 3),
        run_dir=str(run_dir),
        drones={
            n: DroneResult(
                views[n].report,
                exits.get(n),
                hosts.get(n),
                views[n].last_seen() if views[n].report is None else None,
            )
            for n in drones
        },
        ground_station=ground_report,
        failures=tuple(failures),
        links={n: views[n].link for n in drones},
        operator_commands=operator_commands(views),
    )


def operator_commands(views: Mapping[str, DroneView]) -> tuple[dict[str, Any], ...]:
    """The operator's commands the ground station sent (kept in its own view's events)."""
    gcs = views.get(GROUND_STATION)
    events = gcs.events if gcs is not None else []
    return tuple(
        {"t": e["t"], "command": e["operator"], "drone": e["drone"], "origin": e["origin"]}
        for e in events
        if "operator" in e
    )
