"""The mission compiler: mission text -> mission tree -> execution graph -> dependency graphs
-> programs, each phase a pure function (:mod:`.phases`).

What others may use: :func:`compile_mission` / :func:`compile_file` (a
:class:`CompiledMission`: the graphs and one program per participant),
:func:`check_source` (the checks only, for the language server), the errors
(:class:`MissionError` with its located diagnostics, :class:`Diagnostic` at a
:class:`SourceLocation`, :func:`render_diagnostics`; :class:`CompilerBug`), the
pictures and files (:func:`to_dot`, :func:`to_graphml`, :func:`render_svg`,
:func:`write_artifacts`) and the mission libraries (:data:`STANDARD_LIBRARY`,
:func:`search_path`).  Everything else in this package is private.
"""

from .artifacts import write_artifacts
from .drawing import render_svg, to_dot, to_graphml
from .errors import CompilerBug, Diagnostic, MissionError, SourceLocation, render_diagnostics
from .libraries import STANDARD_LIBRARY, search_path
from .phases import CompiledMission, check_source, compile_file, compile_mission

__all__ = [
    "STANDARD_LIBRARY",
    "CompiledMission",
    "CompilerBug",
    "Diagnostic",
    "MissionError",
    "SourceLocation",
    "check_source",
    "compile_file",
    "compile_mission",
    "render_diagnostics",
    "render_svg",
    "search_path",
    "to_dot",
    "to_graphml",
    "write_artifacts",
]
