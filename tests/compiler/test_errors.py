"""Mission errors: exact location, message and hint, all errors of a file at once."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

from eamos.compiler import MissionError, compile_file, compile_mission


@dataclass(frozen=True)
class Bad:
    name: str
    source: str
    where: str  # "line:col" of the first error
    message: str  # substring of its message
    hint: str = ""  # substring of its hint


TWO_BLOCKS = "\n\nfunc SEQ_B() {\n\tDrone1.Land()\n}\n"

CASES = [
    Bad(
        "syntax error",
        "func SEQ_A() {\n\tDrone1.Arm(\n}\n",
        "2:2",
        "syntax error near 'Drone1.Arm('",
        "brackets",
    ),
    Bad(
        "stray parenthesis",
        "func SEQ_A() {\n\tDrone1.Arm()\n\tDrone1.Land())\n}\n",
        "3:15",
        "syntax error",
        "parentheses",
    ),
    Bad(
        "undefined block",
        "func SEQ_A() {\n\tSEQ_Fyl()\n}\n\nfunc SEQ_Fly() {\n\tDrone1.Arm()\n}\n",
        "2:2",
        "undefined block 'SEQ_Fyl'",
        "did you mean SEQ_Fly?",
    ),
    Bad(
        "unknown action",
        "func SEQ_A() {\n\tDrone1.Takof(1)\n}\n",
        "2:9",
        "unknown action 'Takof'",
        "did you mean Takeoff?",
    ),
    Bad(
        "action the drone type lacks",
        "var Drone1 DroneType1\n\nfunc SEQ_A() {\n\tDrone1.TurnOnCamera()\n}\n",
        "4:9",
        "Drone1 (DroneType1) has no action 'TurnOnCamera'",
        "DroneType1 offers: Arm",
    ),
    Bad(
        "wrong argument count",
        "func SEQ_A() {\n\tDrone1.Takeoff()\n}\n",
        "2:2",
        "Takeoff takes 1 argument, got 0",
        "Takeoff(height_m)",
    ),
    Bad(
        "string argument",
        'func SEQ_A() {\n\tDrone1.Takeoff("high")\n}\n',
        "2:17",
        "action arguments are literal numbers, not a string",
        "Drone1.Takeoff(1.5)",
    ),
    Bad(
        "negative height",
        "func SEQ_A() {\n\tDrone1.Takeoff(-1)\n}\n",
        "2:17",
        "height_m must be positive",
    ),
    Bad(
        "recursion",
        "func SEQ_A() {\n\tSEQ_B()\n}\n\nfunc SEQ_B() {\n\tDrone1.Arm()\n\tSEQ_A()\n}\n",
        "7:2",
        "recursion between blocks: SEQ_A -> SEQ_B -> SEQ_A",
        "RepeatWhile/RepeatFor",
    ),
    Bad(
        "Go for while a condition holds",
        "func SEQ_A() {\n\tfor Drone1.X() < 3 {\n\t\tDrone1.Arm()\n\t}\n}\n",
        "2:2",
        "a for loop in a mission repeats a known number of times",
        "RepeatWhile(cond, Body)",
    ),
    Bad(
        "Go if",
        "func SEQ_A() {\n\tif Drone1.X() > 1 {\n\t\tDrone1.Arm()\n\t}\n}\n",
        "2:2",
        "a Go 'if' statement is not supported",
        "If(cond, Then, Else)",
    ),
    Bad(
        "Go go",
        "func SEQ_A() {\n\tgo SEQ_B()\n}" + TWO_BLOCKS,
        "2:2",
        "a 'go' statement is not supported",
        "PAR_ block",
    ),
    Bad(
        "assignment",
        "func SEQ_A() {\n\theight = 2\n\tDrone1.Takeoff(2)\n}\n",
        "2:2",
        "an assignment is not supported",
        "no variables",
    ),
    Bad(
        "short variable declaration",
        "func SEQ_A() {\n\th := 2\n\tDrone1.Takeoff(2)\n}\n",
        "2:2",
        "a variable declaration is not supported",
        "no variables",
    ),
    Bad(
        "unknown property",
        "func SEQ_A() {\n\tWaitUntil(Drone1.Hieght() > 1, SEQ_B)\n}" + TWO_BLOCKS,
        "2:12",
        "Drone1 has no property 'Hieght'",
        "valid names: Alt",
    ),
    Bad(
        "misspelt property",
        "func SEQ_A() {\n\tWaitUntil(Drone1.Batery() > 1, SEQ_B)\n}" + TWO_BLOCKS,
        "2:12",
        "Drone1 has no property 'Batery'",
        "did you mean Battery?",
    ),
    Bad(
        "number as condition",
        "func SEQ_A() {\n\tIf(Drone1.X(), SEQ_B)\n}" + TWO_BLOCKS,
        "2:5",
        "the condition of If is a number, not true/false",
        "compare it",
    ),
    Bad(
        "&& on numbers",
        "func SEQ_A() {\n\tWaitUntil(Drone1.X() && true, SEQ_B)\n}" + TWO_BLOCKS,
        "2:23",
        "'&&' joins conditions, not numbers",
    ),
    Bad(
        "bare property",
        "func SEQ_A() {\n\tWaitUntil(X > 1, SEQ_B)\n}" + TWO_BLOCKS,
        "2:12",
        "'X' is a bare name",
        "Drone1.X()",
    ),
    Bad(
        "unknown drone in a condition",
        "var Drone1 Quadcopter\nfunc SEQ_A() {\n\tWaitUntil(Drone2.X() > 1, SEQ_B)\n}" + TWO_BLOCKS,
        "3:12",
        "unknown drone 'Drone2'",
        "did you mean Drone1?",
    ),
    Bad(
        "control with too few arguments",
        "func SEQ_A() {\n\tWaitUntil(Drone1.X() > 1)\n}\n",
        "2:2",
        "WaitUntil takes 2 arguments, got 1",
        "WaitUntil(cond, Body)",
    ),
    Bad(
        "block called in a control",
        "func SEQ_A() {\n\tWaitUntil(Drone1.X() > 1, SEQ_B())\n}" + TWO_BLOCKS,
        "2:28",
        "name the block without calling it: SEQ_B, not SEQ_B()",
    ),
    Bad(
        "RepeatFor with a fraction",
        "func SEQ_A() {\n\tRepeatFor(1.5, SEQ_B)\n}" + TWO_BLOCKS,
        "2:12",
        "whole number of times",
    ),
    Bad(
        "action without drone",
        "func SEQ_A() {\n\tTakeoff(1)\n}\n",
        "2:2",
        "'Takeoff' is an action and needs a drone",
        "Drone1.Takeoff(...)",
    ),
    Bad(
        "ground station flies",
        "func SEQ_A() {\n\tGCS.Takeoff(1)\n}\n",
        "2:2",
        "the ground station 'GCS' does not fly",
        "bare PauseFor",
    ),
    Bad(
        "unknown drone type",
        "var Drone1 Quadcoptr\nfunc SEQ_A() {\n\tDrone1.Land()\n}\n",
        "1:12",
        "unknown drone type 'Quadcoptr'",
        "did you mean Quadcopter?",
    ),
    Bad(
        "missing library",
        'package m\nimport "fmt"\nfunc SEQ_A() {\n\tDrone1.Land()\n}\n',
        "2:8",
        "no library 'fmt'",
        "looked for the folder in",
    ),
    Bad(
        "entry block parameters",
        "func SEQ_A(h float64) {\n\tDrone1.Land()\n}\n",
        "1:12",
        "block 'SEQ_A' takes no parameters",
        "where the mission starts",
    ),
    Bad("empty file", "", "1:1", "the mission file is empty", "func SEQ_Main()"),
    Bad("blank file", "  \n\n\t\n", "1:1", "the mission file is empty"),
    Bad("NUL bytes", "func SEQ_A() {\x00\n}\n", "1:1", "not text (it contains NUL bytes)"),
    Bad(
        "empty block",
        "func SEQ_A() {\n\tSEQ_B()\n}\n\nfunc SEQ_B() {\n}\n",
        "5:6",
        "block 'SEQ_B' is empty",
        "at least one statement",
    ),
    Bad(
        "duplicate block",
        "func SEQ_A() {\n\tDrone1.Arm()\n}\n\nfunc SEQ_A() {\n\tDrone1.Land()\n}\n",
        "5:6",
        "block 'SEQ_A' is defined twice",
        "first defined at line 1",
    ),
    Bad("no blocks", "package m\n\nvar Drone1 Quadcopter\n", "1:1", "the mission has no blocks"),
]


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_error_location_message_and_hint(case: Bad) -> None:
    with pytest.raises(MissionError) as info:
        compile_mission(case.source, "m.go")
    errors = [d for d in info.value.diagnostics if d.severity == "error"]
    first = errors[0]
    assert f"{first.loc}" == case.where, info.value.render("m.go", case.source)
    assert case.message in first.message
    assert case.hint in first.hint
    text = info.value.render("m.go", case.source)
    assert text.startswith(f"m.go:{case.where}: error: ")
    assert "Traceback" not in text


def test_rendering_shows_the_line_caret_and_hint() -> None:
    source = 'func SEQ_A() {\n\tDrone1.Takeoff("high")\n}\n'
    with pytest.raises(MissionError) as info:
        compile_mission(source, "m.go")
    lines = info.value.render("m.go", source).splitlines()
    assert lines[0] == "m.go:2:17: error: action arguments are literal numbers, not a string"
    assert lines[1] == '        Drone1.Takeoff("high")'  # the tab expanded to 4 columns
    assert lines[2] == "                       ^~~~~~"  # under "high" with its quotes
    assert lines[3].startswith("    hint: ")
    assert lines[-1] == "1 error in m.go"


def test_all_errors_of_a_file_are_reported_at_once() -> None:
    source = "func SEQ_A() {\n\tDrone1.Takof(1)\n\tSEQ_Nope()\n\tDrone1.Land(3)\n}\n"
    with pytest.raises(MissionError) as info:
        compile_mission(source, "m.go")
    errors = [d for d in info.value.diagnostics if d.severity == "error"]
    assert [str(d.loc) for d in errors] == ["2:9", "3:2", "4:2"]
    assert "(and 2 more)" in str(info.value)
    assert info.value.render("m.go", source).endswith("3 errors in m.go")


def test_all_unsupported_go_constructs_are_reported_at_once() -> None:
    source = "func SEQ_A() {\n\tfor {\n\t}\n\tx := 1\n\tgo SEQ_A()\n}\n"
    with pytest.raises(MissionError) as info:
        compile_mission(source, "m.go")
    assert [str(d.loc) for d in info.value.diagnostics] == ["2:2", "4:2", "5:2"]


def test_block_never_reached_is_a_warning() -> None:
    source = "func SEQ_A() {\n\tDrone1.Arm()\n}\n\nfunc SEQ_B() {\n\tDrone1.Land()\n}\n"
    compiled = compile_mission(source, "m.go")
    (warning,) = compiled.warnings
    assert warning.severity == "warning" and str(warning.loc) == "5:6"
    assert "block 'SEQ_B' is never reached from SEQ_A" in warning.message


def test_unprefixed_block_and_unused_drone_are_warnings() -> None:
    source = "var Drone1 Quadcopter\nvar Drone2 Quadcopter\n\nfunc Main() {\n\tDrone1.Arm()\n}\n"
    compiled = compile_mission(source, "m.go")
    messages = sorted(w.message for w in compiled.warnings)
    assert any("no SEQ_ or PAR_ prefix" in m for m in messages)
    assert any("drone 'Drone2' is declared but never used" in m for m in messages)


def test_unreadable_files_are_mission_errors(tmp_path: Path) -> None:
    folder = tmp_path
    with pytest.raises(MissionError, match="no such mission file"):
        compile_file(folder / "missing.go")
    with pytest.raises(MissionError, match="is a folder"):
        compile_file(folder)
    binary = folder / "bin.go"
    binary.write_bytes(b"\xff\xfe\x00\x01garbage")
    with pytest.raises(MissionError, match="not UTF-8 text"):
        compile_file(binary)


def test_unsupported_go_and_check_errors_are_reported_together():
    source = (
        "var Drone1 DroneTyp1\n"
        "func SEQ_Main() {\n"
        "    Drone1.Takeof(1.5)\n"
        "    for i := 0; i < 3; i++ {}\n"
        "}\n"
    )
    with pytest.raises(MissionError) as info:
        compile_mission(source, "m.go")
    messages = [(d.loc.line, d.message) for d in info.value.diagnostics if d.severity == "error"]
    assert [line for line, _ in messages] == [1, 3, 4]
    assert "DroneTyp1" in messages[0][1] and "Takeof" in messages[1][1] and "for" in messages[2][1]


def test_a_block_emptied_by_a_rejected_statement_is_not_also_reported_empty():
    source = "func SEQ_Main() {\n    go SEQ_Main()\n}\n"
    with pytest.raises(MissionError) as info:
        compile_mission(source, "m.go")
    assert [d.message for d in info.value.diagnostics if d.severity == "error"] == [
        "a 'go' statement is not supported in missions"
    ]
