"""What the pre-flight check found: located findings, per-run summaries, the report.

Everything here is a small frozen dataclass; :meth:`CheckReport.to_json` is the
machine-readable form (``eamos check --json``) and :meth:`CheckReport.lines` the
human one (``file:line:col: error|warning: ...`` and one summary line per run).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

Severity = Literal["error", "warning"]
#: A point in the fleet frame: north, east, up (metres).
Point = tuple[float, float, float]


@dataclass(frozen=True)
class Place:
    """Where in the mission text: a node's action (or condition) and its line and column.

    ``file`` is the library file the line is in ("" for the mission file itself: a
    block of a library, ``import "shapes"``, is written in ``shapes/shapes.go``).
    """

    drone: str
    node: str
    label: str
    line: int
    col: int
    file: str = ""

    def to_json(self, mission_file: str = "") -> dict[str, Any]:
        """A JSON-ready dict; ``file`` is the library's, else ``mission_file``."""
        return {
            "drone": self.drone,
            "node": self.node,
            "label": self.label,
            "file": self.file or mission_file,
            "line": self.line,
            "col": self.col,
        }


@dataclass(frozen=True)
class Finding:
    """One thing the check found, as an error (the mission would fail) or a warning.

    ``check`` names the rule (``separation``, ``termination``, ``deadlock``,
    ``action``, ...); ``places`` are the actions or nodes involved, the first one
    being where the finding is reported; ``time_s`` is virtual seconds from the
    start; ``positions`` maps drones to fleet-frame points (north, east, up).
    """

    severity: Severity
    check: str
    message: str
    places: tuple[Place, ...] = ()
    time_s: float | None = None
    positions: tuple[tuple[str, Point], ...] = ()
    branch: str = ""

    @property
    def line(self) -> int:
        """The line the finding is reported on (1 when no action is involved)."""
        return self.places[0].line if self.places and self.places[0].line else 1

    @property
    def col(self) -> int:
        """The column the finding is reported on."""
        return self.places[0].col if self.places and self.places[0].col else 1

    @property
    def file(self) -> str:
        """The library file the finding is reported in ("" for the mission file)."""
        return self.places[0].file if self.places else ""

    def render(self, path: str) -> str:
        """``file:line:col: severity: message [branch]``; ``path`` is the mission file's name,
        used unless the line is in a library file."""
        where = f" [{self.branch}]" if self.branch else ""
        return f"{self.file or path}:{self.line}:{self.col}: {self.severity}: {self.message}{where}"

    def to_json(self, mission_file: str = "") -> dict[str, Any]:
        """A JSON-ready dict; ``file`` is where ``line`` is (a library's, else ``mission_file``)."""
        return {
            "severity": self.severity,
            "check": self.check,
            "message": self.message,
            "file": self.file or mission_file,
            "line": self.line,
            "col": self.col,
            "places": [p.to_json(mission_file) for p in self.places],
            "time_s": None if self.time_s is None else round(self.time_s, 3),
            "positions": {d: [round(c, 3) for c in p] for d, p in self.positions},
            "branch": self.branch,
        }


@dataclass(frozen=True)
class RunSummary:
    """One explored run: its branch label, how long it took, what was checked."""

    branch: str
    duration_s: float
    timed_out: bool
    checked: tuple[str, ...]
    errors: int
    warnings: int

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict."""
        return {
            "branch": self.branch,
            "duration_s": round(self.duration_s, 3),
            "timed_out": self.timed_out,
            "checked": list(self.checked),
            "errors": self.errors,
            "warnings": self.warnings,
        }


@dataclass(frozen=True)
class CheckReport:
    """The outcome of :func:`eamos.check.check_mission`."""

    mission: str
    source_file: str
    runs: tuple[RunSummary, ...]
    findings: tuple[Finding, ...]
    max_runs: int
    unexplored: int = 0  # runs left out because of ``max_runs``
    settings: dict[str, Any] = field(default_factory=dict, hash=False)
    #: (branch, tracks by drone) of the first run and of every run with a finding, for pictures.
    tracks: tuple[tuple[str, Mapping[str, Any]], ...] = field(default=(), hash=False, repr=False)

    @property
    def errors(self) -> tuple[Finding, ...]:
        """The error findings (the mission would fail)."""
        return tuple(f for f in self.findings if f.severity == "error")

    @property
    def warnings(self) -> tuple[Finding, ...]:
        """The warning findings."""
        return tuple(f for f in self.findings if f.severity == "warning")

    @property
    def ok(self) -> bool:
        """True when no finding is an error."""
        return not self.errors

    def lines(self, path: str | None = None) -> list[str]:
        """The human report: one line per finding, then one per run, then a total."""
        where = path or self.source_file or "<mission>"
        out = [f.render(where) for f in self.findings]
        for i, run in enumerate(self.runs, 1):
            state = "FAILED" if run.errors else "ok"
            timed = ", did not end (time limit)" if run.timed_out else ""
            out.append(
                f"run {i}/{len(self.runs)} [{run.branch}]: {state}, {run.duration_s:.1f} s{timed}, "
                f"{run.errors} error(s), {run.warnings} warning(s); "
                f"checked {', '.join(run.checked)}"
            )
        if self.runs:
            times = [r.duration_s for r in self.runs]
            out.append(f"duration: min {min(times):.1f} s, max {max(times):.1f} s")
        more = f" ({self.unexplored} more not explored: --max-runs)" if self.unexplored else ""
        out.append(
            f"{len(self.runs)} run(s) explored (at most {self.max_runs}){more}: "
            f"{len(self.errors)} error(s), {len(self.warnings)} warning(s)"
        )
        return out

    def to_json(self) -> dict[str, Any]:
        """The whole report as a JSON-ready dict (``eamos check --json``)."""
        times = [r.duration_s for r in self.runs]
        return {
            "mission": self.mission,
            "file": self.source_file,
            "ok": self.ok,
            "errors": len(self.errors),
            "warnings": len(self.warnings),
            "max_runs": self.max_runs,
            "explored_runs": len(self.runs),
            "unexplored_runs": self.unexplored,
            "duration_s": {
                "min": round(min(times), 3) if times else None,
                "max": round(max(times), 3) if times else None,
            },
            "settings": self.settings,
            "runs": [r.to_json() for r in self.runs],
            "findings": [f.to_json(self.source_file) for f in self.findings],
        }


__all__ = ["CheckReport", "Finding", "Place", "Point", "RunSummary", "Severity"]
