"""The mission compiler: mission text -> mission tree -> execution graph -> dependency graphs -> programs.

Public surface; everything else in this package is private.
"""

from .errors import CompilerBug, Diagnostic, MissionError, SourceLocation
from .phases import CompiledMission, compile_file, compile_mission

__all__ = [
    "CompiledMission",
    "CompilerBug",
    "Diagnostic",
    "MissionError",
    "SourceLocation",
    "compile_file",
    "compile_mission",
]
