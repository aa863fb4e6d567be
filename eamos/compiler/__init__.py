"""The mission compiler.

Mission text -> mission tree -> execution graph -> dependency graphs -> programs.

Public surface; everything else in this package is private.
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
