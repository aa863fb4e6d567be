"""The compiler pipeline: one pure function per phase, chained by :func:`compile_mission`.

    text --parse--> Mission --check--> Mission --mission_tree--> AMT
         --execution_graph--> MEG --dependency_graph--> MDGs --synthesis--> programs

Each phase raises :class:`~.errors.MissionError` for the user's mistakes and
:class:`~.errors.CompilerBug` for ours.
"""

from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import networkx as nx

from .. import __version__
from ..program.format import DroneProgram
from ..program.uniform import GROUND_STATION
from .check import collect_diagnostics, drone_types, instance_warnings
from .dependency_graph import fleet, mdg_stats, slice_dependency_graphs
from .errors import Diagnostic, MissionError, SourceLocation, with_source_lines
from .execution_graph import build_execution_graph
from .instantiate import instantiate
from .libraries import load_libraries
from .limits import block_limit_errors
from .mission_tree import build_mission_tree
from .parse import parse_partial
from .syntax import LibraryFile, Mission
from .synthesis import synthesize_program


@dataclass(frozen=True)
class CompiledMission:
    """Everything one compilation produces (graphs are networkx graphs)."""

    mission: Mission
    mission_id: str
    amt: nx.DiGraph = field(repr=False)
    meg: nx.DiGraph = field(repr=False)
    mdgs: dict[str, nx.DiGraph] = field(repr=False)
    programs: dict[str, DroneProgram] = field(repr=False)
    warnings: tuple[Diagnostic, ...] = ()
    source_file: str = ""

    def stats(self) -> dict[str, object]:
        """``{"meg": {"nodes", "arcs"}, "drones": {NAME: {...Table 7 columns}}}``."""
        return {
            "meg": {"nodes": self.meg.number_of_nodes(), "arcs": self.meg.number_of_edges()},
            "drones": {name: mdg_stats(mdg) for name, mdg in self.mdgs.items()},
        }


def mission_identity(source: str, libraries: tuple[LibraryFile, ...] = ()) -> str:
    """A short, stable id of a mission's text (and libraries) and the compiler that compiled it."""
    text = f"eamos {__version__}\n{source}"
    if libraries:  # a library's change changes the mission
        text += "".join(f"\n{f.package} {f.sha256}" for f in libraries)
    digest = hashlib.sha256(text.encode()).hexdigest()
    return digest[:16]


def compile_mission(source: str, source_file: str = "<mission>") -> CompiledMission:
    """Compile mission text through every phase; raise MissionError listing all problems."""
    try:
        compiled = _compile(source, source_file)
    except MissionError as exc:
        # Each diagnostic keeps its line, so printing many of them stays linear.
        exc.diagnostics = with_source_lines(exc.diagnostics, source)
        raise
    warnings = with_source_lines(list(compiled.warnings), source)
    return dataclasses.replace(compiled, warnings=tuple(warnings))


def _mission_dir(source_file: str) -> Path | None:
    return None if source_file in ("", "<mission>") else Path(source_file).parent


def check_source(source: str, source_file: str = "<mission>") -> tuple[Mission, list[Diagnostic]]:
    """The phases that find an author's mistakes: parse and check, no graph built.

    Returns the checked syntax and its warnings; raises :class:`MissionError`
    with every error.  :func:`compile_mission` starts with it, and the language
    server runs it alone on every edit (the graph phases cost most of the time
    of a large mission and find only one rare thing more: too many
    synchronisation arcs).  ``source_file`` locates the libraries it imports.
    """
    return _check(source, source_file)[1:]


def _check(source: str, source_file: str) -> tuple[Mission, Mission, list[Diagnostic]]:
    """The mission as expanded (no parameters left), as written, and its warnings."""
    mission, parsed, fatal = parse_partial(source)
    if fatal:
        raise MissionError(parsed)
    loaded = load_libraries(mission, _mission_dir(source_file))
    if any(d.severity == "error" for d in loaded.diagnostics):
        # Checking calls into a library that did not load would only add noise.
        raise MissionError(with_source_lines(parsed + loaded.diagnostics, source, loaded.texts))
    mission = loaded.mission
    checked = collect_diagnostics(mission)
    found = with_source_lines(parsed + loaded.diagnostics + checked, source, loaded.texts)
    if any(d.severity == "error" for d in found):
        raise MissionError(found)
    if not mission.entry:
        raise MissionError([Diagnostic("error", SourceLocation(1, 1), "the mission has no blocks")])
    expanded, problems = instantiate(mission)
    if expanded is not mission and not problems:
        # Loops and copies are counted again, written out: the limits are the expanded tree's.
        problems = block_limit_errors(expanded)
    if problems:
        raise MissionError(with_source_lines(problems, source, loaded.texts))
    if expanded is not mission:
        found += with_source_lines(instance_warnings(expanded), source, loaded.texts)
    return expanded, mission, found


def _compile(source: str, source_file: str) -> CompiledMission:
    mission, _, warnings = _check(source, source_file)
    if mission.name == "mission" and source_file not in ("", "<mission>"):
        mission = dataclasses.replace(mission, name=Path(source_file).stem)
    amt = build_mission_tree(mission)
    meg = build_execution_graph(amt)
    mdgs = slice_dependency_graphs(meg)
    mission_id = mission_identity(source, mission.libraries)
    participants = fleet(meg)
    types = drone_types(mission)
    programs = {
        name: synthesize_program(
            mdg,
            mission_id=mission_id,
            fleet=participants,
            drone_type=types[name].name if name in types else "",
            source_file=Path(source_file).name,
            libraries=_libraries_used(mission, mdg),
        )
        for name, mdg in mdgs.items()
    }
    return CompiledMission(
        mission=mission,
        mission_id=mission_id,
        amt=amt,
        meg=meg,
        mdgs=mdgs,
        programs=programs,
        warnings=tuple(warnings),
        source_file=source_file,
    )


def _libraries_used(mission: Mission, mdg: nx.DiGraph) -> tuple[tuple[str, str], ...]:
    """(path, sha256) of the library files whose blocks this drone's own nodes come from.

    Per drone, so that a roll-out's partial redeploy counts a library's change as a
    change of exactly the drones that run something of it.
    """
    if not mission.libraries:
        return ()
    files = set()
    for _, attrs in mdg.nodes(data=True):
        block = mission.blocks.get(attrs.get("block", "")) if attrs.get("native") else None
        if block is not None and block.loc.file:
            files.add(block.loc.file)
    return tuple((f.path, f.sha256) for f in mission.libraries if f.path in files)


def compile_file(path: Path) -> CompiledMission:
    """Read and compile a mission file; unreadable or non-text files are MissionErrors."""
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError as exc:
        raise MissionError(
            [Diagnostic("error", SourceLocation(1, 1), f"no such mission file: {path}")]
        ) from exc
    except IsADirectoryError as exc:
        raise MissionError(
            [Diagnostic("error", SourceLocation(1, 1), f"{path} is a folder, not a mission file")]
        ) from exc
    except OSError as exc:
        raise MissionError(
            [Diagnostic("error", SourceLocation(1, 1), f"cannot read {path}: {exc.strerror}")]
        ) from exc
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise MissionError(
            [
                Diagnostic(
                    "error",
                    SourceLocation(1, 1),
                    "the mission file is not UTF-8 text",
                    "give the path of a .go mission file",
                )
            ]
        ) from exc
    return compile_mission(text, str(path))


__all__ = [
    "GROUND_STATION",
    "CompiledMission",
    "check_source",
    "compile_file",
    "compile_mission",
    "mission_identity",
]
