"""Shared helpers for the language-server tests: missions, and positions of text in them."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
MISSIONS = REPO / "missions"

#: A mission with exactly three errors (and the compiler's messages for them).
THREE_ERRORS = """\
var Drone1 DroneType1

func SEQ_Main() {
\tDrone1.Arm()
\tDrone1.Takof(1.5)
\tSEQ_Fyl()
\tDrone1.Takeoff(-2)
\tSEQ_Fly()
}

func SEQ_Fly() { Drone1.FlyByX(2); Drone1.Land() }
"""


def position_of(text: str, needle: str, nth: int = 0, offset: int = 0) -> tuple[int, int]:
    """1-based (line, column) of the ``nth`` occurrence of ``needle`` (plus ``offset`` chars)."""
    at = -1
    for _ in range(nth + 1):
        at = text.index(needle, at + 1)
    at += offset
    line = text.count("\n", 0, at) + 1
    col = at - (text.rfind("\n", 0, at) + 1) + 1
    return line, col


def too_many_sync_arcs(drones: int = 350) -> str:
    """A mission only the graph phases refuse: two PAR blocks of many drones in a row."""
    first = "".join(f"\tD{i}.Arm()\n" for i in range(drones))
    second = "".join(f"\tD{i}.Takeoff(1)\n" for i in range(drones))
    return (
        "func SEQ_Main() {\n\tPAR_A()\n\tPAR_B()\n}\n"
        f"func PAR_A() {{\n{first}}}\nfunc PAR_B() {{\n{second}}}\n"
    )
