"""What the monitor page needs before anything flies: the mission's participants and graphs.

:class:`MissionSetup` is read once from a run folder (``programs/`` and
``graphs/``, as ``eamos run`` and ``eamos compile`` write them): every
participant's colour (the graph pictures' palette), home on the map, its MDG
nodes (native ones: the nodes it executes) and the compiler's SVG picture of
its MDG.  In that SVG every node is a ``<g class="node">`` whose ``<title>``
is the node's program key (``n5``, ``n7@Drone1``), so the page colours nodes
by key.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from eamos.ground.links import LinkGraph
from eamos.program.format import DroneProgram, ProgramError, load_program
from eamos.program.uniform import GROUND_STATION


class MonitorError(ValueError):
    """A run folder the monitor cannot show (no programs, unreadable logs, a bad port)."""


@dataclass(frozen=True)
class NodeInfo:
    """One node of a participant's MDG, as the page shows it."""

    key: str  # the program key: the SVG node's <title>, Progress.node
    kind: str  # init, fork, end, action, if, wait, repeat, ...
    label: str
    owner: str  # the participant executing it
    action: str = ""  # the uniform action, for action nodes
    loops: int = 0  # how many loops enclose it (its iteration has this many counters)

    def to_json(self) -> dict[str, Any]:
        return {
            "key": self.key,
            "kind": self.kind,
            "label": self.label,
            "owner": self.owner,
            "action": self.action,
            "loops": self.loops,
        }


@dataclass(frozen=True)
class ParticipantSetup:
    """One participant (a drone or the ground station): colour, home, graph."""

    name: str
    colour: str
    home: tuple[float, float]  # x, y (m) of its local frame's origin in the mission frame
    nodes: tuple[NodeInfo, ...]  # its native nodes (those it executes)
    svg: str  # the compiler's picture of its MDG ("" when there is none)
    external_out: int = 0  # the MDG's outgoing external arcs (triggers it should send)
    external_in: int = 0

    def to_json(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "colour": self.colour,
            "home": list(self.home),
            "nodes": [n.to_json() for n in self.nodes],
            "external_out": self.external_out,
            "external_in": self.external_in,
        }


@dataclass(frozen=True)
class MissionSetup:
    """Everything static the page shows: the mission and its participants."""

    mission: str
    mission_id: str
    participants: tuple[ParticipantSetup, ...]  # drones first (natural order), the GCS last
    #: Each node's predecessors in the MDGs (loop arcs aside): what had to finish before it.
    preds: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    #: The whole MDG's arcs for the live trigger counts per link (None: not counted).
    links: LinkGraph | None = None

    @property
    def drones(self) -> list[str]:
        """The drones (not the ground station)."""
        return [p.name for p in self.participants if p.name != GROUND_STATION]

    def participant(self, name: str) -> ParticipantSetup | None:
        """The participant called ``name`` (None: not in the mission)."""
        return next((p for p in self.participants if p.name == name), None)

    def to_json(self) -> dict[str, Any]:
        """The setup as the page receives it (SVGs are fetched separately)."""
        return {
            "mission": self.mission,
            "mission_id": self.mission_id,
            "participants": [p.to_json() for p in self.participants],
            "drones": self.drones,
            "links": [
                {"src": s, "dst": d, "arcs": n}
                for (s, d), n in (self.links.links() if self.links is not None else {}).items()
            ],
        }


def _nodes(program: DroneProgram) -> tuple[NodeInfo, ...]:
    return tuple(
        NodeInfo(n.key, n.kind, n.label or n.kind, n.drone, n.action or "", len(n.loops))
        for n in program.nodes
        if n.native
    )


def build_setup(
    programs: Mapping[str, DroneProgram],
    svgs: Mapping[str, str],
    homes: Mapping[str, tuple[float, float]] | None = None,
) -> MissionSetup:
    """The setup of a mission from its programs, MDG pictures and (optional) homes."""
    from eamos.compiler.drawing import drone_colours  # the pictures' palette

    if not programs:
        raise MonitorError("no programs: nothing to show")
    first = next(iter(programs.values()))
    colours = drone_colours(programs)
    order = sorted(
        programs, key=lambda n: (n == GROUND_STATION, list(colours).index(n) if n in colours else 0)
    )
    homes = homes or {}
    parts = []
    for name in order:
        program = programs[name]
        stats = program.stats()
        parts.append(
            ParticipantSetup(
                name=name,
                colour=colours.get(name, "#ffffff"),
                home=homes.get(name, (0.0, 0.0)),
                nodes=_nodes(program),
                svg=svgs.get(name, ""),
                external_out=int(stats.get("external_out", 0)),
                external_in=int(stats.get("external_in", 0)),
            )
        )
    preds: dict[str, list[str]] = {}
    for program in programs.values():
        native = {n.key for n in program.nodes if n.native}
        for arc in program.arcs:
            if arc.dst in native and arc.kind != "loop":
                preds.setdefault(arc.dst, []).append(arc.src)
    unique_preds = {k: tuple(dict.fromkeys(v)) for k, v in preds.items()}
    links = LinkGraph.from_programs(programs.values())
    return MissionSetup(first.mission, first.mission_id, tuple(parts), unique_preds, links)


def _svg_of(graphs: Path, name: str) -> str:
    """The MDG picture of ``name``: the SVG file, else drawn from its DOT file, else ""."""
    svg = graphs / f"mdg_{name}.svg"
    if svg.is_file():
        return svg.read_text(encoding="utf-8", errors="replace")
    dot = graphs / f"mdg_{name}.dot"
    if dot.is_file():
        from eamos.compiler.svg_layout import builtin_svg

        return builtin_svg(dot.read_text(encoding="utf-8", errors="replace"))
    return ""


def load_setup(
    run_dir: Path, homes: Mapping[str, tuple[float, float]] | None = None
) -> MissionSetup:
    """The setup of the mission in ``run_dir`` (its ``programs/`` and ``graphs/``)."""
    folder = run_dir / "programs"
    paths = sorted(folder.glob("*.program.json")) if folder.is_dir() else []
    if not paths:
        raise MonitorError(f"{run_dir}: no programs/*.program.json (not a run folder)")
    programs: dict[str, DroneProgram] = {}
    for path in paths:
        try:
            program = load_program(path)
        except ProgramError as exc:
            raise MonitorError(str(exc)) from exc
        programs[program.drone] = program
    svgs = {name: _svg_of(run_dir / "graphs", name) for name in programs}
    return build_setup(programs, svgs, homes)
