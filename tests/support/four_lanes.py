"""The four-lane mission of the amendment tests (issue 31) and its edits.

``tests/operator/four_lanes.go``: four drones fly a lane each, north and back, at once.
Shared by ``tests/check/test_amendment.py`` (a snapshot from a virtual run) and
``tests/operator/test_amend.py`` (a real paused run).
"""

from __future__ import annotations

from tests.support.runs import REPO

LANES = REPO / "tests" / "operator" / "four_lanes.go"
TEXT = LANES.read_text()


def amended(*edits: tuple[str, str]) -> str:
    """The mission's text with each (old, new) edit made once (each must apply)."""
    text = TEXT
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new, 1)
    return text


#: Drone3 splits its way back in two; Drone4 climbs a metre before its way back.
LATER_PARTS = (
    ("\tDrone3.FlyByX(-12)\n", "\tDrone3.FlyByX(-6)\n\tDrone3.FlyByX(-6)\n"),
    ("\tDrone4.FlyByX(-12)\n", "\tDrone4.FlyByZ(1)\n\tDrone4.FlyByX(-12)\n"),
)
#: Drone1 and Drone2 fly at each other across the 5 m between their lanes.
HEAD_ON = (
    ("\tDrone1.FlyByX(-12)\n", "\tDrone1.FlyByY(5)\n\tDrone1.FlyByX(-12)\n"),
    ("\tDrone2.FlyByX(-12)\n", "\tDrone2.FlyByY(-5)\n\tDrone2.FlyByX(-12)\n"),
)
#: Drone1's first leg, which is flying when the snapshot is taken.
RUNNING_LEG = (("\tDrone1.FlyByX(12)\n", "\tDrone1.FlyByX(14)\n"),)


def line_of(text: str, statement: str, nth: int = 1) -> int:
    """The line number of the ``nth`` line of ``text`` that is ``statement``."""
    found = [i for i, line in enumerate(text.splitlines(), 1) if line.strip() == statement]
    return found[nth - 1]
