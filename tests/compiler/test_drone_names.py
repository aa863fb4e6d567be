"""A drone name one typing mistake from another gets a warning with a hint (issue 29).

Undeclared names are drones (the paper's listings declare none), so ``Dron1.FlyByX(1)``
next to ``Drone1`` was silently a third drone; only the pre-flight check noticed.
"""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from eamos.compiler import compile_mission
from eamos.compiler.drone_names import _neighbours, one_edit_apart

from .compiler_helpers import mission_files


@pytest.mark.parametrize(
    "a,b",
    [
        ("Dron1", "Drone1"),  # a letter left out
        ("Drone1", "Dronee1"),  # one too many
        ("Drome1", "Drone1"),  # a wrong letter
        ("Dorne1", "Drone1"),  # two neighbours swapped
        ("drone1", "Drone1"),  # case
        ("Drone", "Drones"),
    ],
)
def test_one_edit_apart(a: str, b: str) -> None:
    assert one_edit_apart(a, b) and one_edit_apart(b, a)


@pytest.mark.parametrize(
    "a,b",
    [
        ("D1", "D2"),  # a fleet, numbered
        ("Drone1", "Drone12"),
        ("D12", "D21"),
        ("Drone1", "Drone1"),
        ("Dr1", "Drone1"),  # two edits
        ("Alpha", "Bravo"),
    ],
)
def test_not_one_edit_apart(a: str, b: str) -> None:
    assert not one_edit_apart(a, b) and not one_edit_apart(b, a)


def warnings_of(source: str) -> list[str]:
    compiled = compile_mission(source, "t.go")
    return [f"{w.loc.line}:{w.loc.col}: {w.message} [{w.hint}]" for w in compiled.warnings]


def test_a_misspelt_drone_next_to_a_declared_one_is_warned_at_its_first_use() -> None:
    source = (
        "var Drone1 Quadcopter\n\nfunc SEQ_Main() {\n    Drone1.Arm()\n    Drone1.Takeoff(2)\n"
        "    Dron1.FlyByX(1)\n    Dron1.FlyByX(2)\n    Drone1.Land()\n}\n"
    )
    assert warnings_of(source) == [
        "6:5: drone 'Dron1' is not declared and is one letter away from 'Drone1' (declared): "
        "it is a drone of its own [did you mean Drone1?]"
    ]


def test_between_undeclared_drones_the_less_used_is_the_mistake() -> None:
    source = (
        "func SEQ_Main() {\n    Drone1.Arm()\n    Drone1.Takeoff(2)\n"
        "    If(Drone1.Z() > 1, SEQ_A, SEQ_B)\n}\n"
        "func SEQ_A() { Drone1.Land() }\nfunc SEQ_B() { Drnoe1.Land() }\n"
    )
    found = warnings_of(source)
    assert len(found) == 1 and "'Drnoe1'" in found[0] and "'Drone1' (used 4 times)" in found[0]
    assert found[0].startswith("7:16:") and found[0].endswith("[did you mean Drone1?]")


def test_a_misspelt_drone_passed_to_a_block_is_warned_too() -> None:
    source = (
        "var Drone1 Quadcopter\nfunc SEQ_Hop(d Quadcopter) { d.Arm() }\n"
        "func SEQ_Main() {\n    SEQ_Hop(Drone1)\n    SEQ_Hop(Dorne1)\n}\n"
    )
    found = warnings_of(source)
    assert len(found) == 1 and found[0].startswith("5:13: drone 'Dorne1'")


def test_numbered_fleets_and_parameters_are_not_mistakes() -> None:
    source = (
        "func SEQ_Hop(d Quadcopter, e Quadcopter) {\n    d.Arm()\n    e.Arm()\n}\n"
        "func SEQ_Main() {\n    SEQ_Hop(D1, D2)\n    D3.Arm()\n}\n"
    )
    assert warnings_of(source) == []


@pytest.mark.parametrize("path", mission_files(), ids=lambda p: p.name)
def test_no_shipped_mission_is_warned(path) -> None:
    compiled = compile_mission(path.read_text(), str(path))
    assert [w for w in compiled.warnings if "one letter away" in w.message] == []


@settings(max_examples=200, deadline=None)
@given(st.lists(st.text(alphabet="abD12_", min_size=1, max_size=5), max_size=40, unique=True))
def test_the_grouping_finds_every_pair_one_edit_apart(names: list[str]) -> None:
    near = _neighbours(sorted(names))
    for a in names:
        for b in names:
            if a != b and one_edit_apart(a, b):
                assert b in near.get(a, set()), (a, b)
