"""One source of truth: the vocabulary tables of docs/mission-language.md are generated from
eamos/program/uniform.py (``python -m eamos.lsp.vocabulary`` prints them), and so are the
editor's help (hover, completion) and the VS Code snippets; this test keeps them equal."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from eamos.compiler.parse_statements import _CONTROL_SIGNATURES
from eamos.compiler.syntax import CONTROL_KINDS
from eamos.lsp.vocabulary import control_snippet, reference_tables
from eamos.program.uniform import CONTROL_STRUCTURES, PARAM_RANGES, PROPERTIES, param_unit

REPO = Path(__file__).resolve().parents[1]
REFERENCE = REPO / "docs" / "mission-language.md"
MARKER = "<!-- generated from eamos/program/uniform.py ({name}): python -m eamos.lsp.vocabulary -->"


def table_in_reference(name: str) -> str:
    """The table after the reference's marker for ``name`` (up to the next blank line)."""
    text = REFERENCE.read_text(encoding="utf-8")
    marker = MARKER.format(name=name)
    assert text.count(marker) == 1, f"docs/mission-language.md needs one marker: {marker}"
    start = text.index(marker) + len(marker) + 1
    end = text.find("\n\n", start)
    return text[start : end if end != -1 else len(text)]


@pytest.mark.parametrize("name", sorted(reference_tables()))
def test_reference_table_equals_the_vocabulary(name: str) -> None:
    want = reference_tables()[name]
    assert table_in_reference(name) == want, (
        f"regenerate the {name} table of docs/mission-language.md with "
        f"`python -m eamos.lsp.vocabulary`:\n{want}"
    )


def test_the_check_sees_a_table_out_of_step() -> None:
    # The comparison can fail: a row changed in the vocabulary shows as a difference.
    doctored = table_in_reference("actions").replace("Arm the motors", "Arm motors")
    assert doctored != reference_tables()["actions"]


def test_control_structures_are_those_the_parser_knows() -> None:
    assert set(CONTROL_STRUCTURES) == set(CONTROL_KINDS)
    assert {k: c.signature for k, c in CONTROL_STRUCTURES.items()} == _CONTROL_SIGNATURES


def test_every_parameter_has_a_unit_and_a_range_and_every_property_a_meaning() -> None:
    from eamos.program.uniform import ACTIONS, UNIT_NAMES

    for spec in ACTIONS.values():
        for param in spec.params:
            assert param_unit(param) in UNIT_NAMES, param
            assert param in PARAM_RANGES, param
    assert all(p.doc for p in PROPERTIES.values())


def test_vscode_snippets_are_one_per_control_structure_from_the_vocabulary() -> None:
    snippets = json.loads((REPO / "editors" / "vscode" / "snippets" / "eamos.json").read_text())
    by_prefix = {s["prefix"]: s for s in snippets.values()}
    assert set(by_prefix) == set(CONTROL_STRUCTURES)
    for name, spec in CONTROL_STRUCTURES.items():
        body = by_prefix[name]["body"]
        assert (body if isinstance(body, str) else "\n".join(body)) == control_snippet(spec)
        assert by_prefix[name]["description"] == re.sub(r"`", "", spec.doc)


def _bounds(text: str) -> tuple[float, float]:
    numbers = [float(n.replace(" ", "")) for n in re.findall(r"-?\d(?:[\d ]*\d)?", text)]
    return numbers[0], numbers[-1]


@pytest.mark.parametrize("param", sorted(PARAM_RANGES))
def test_the_stated_ranges_are_what_the_compiler_checks(param: str) -> None:
    from eamos.compiler import MissionError, compile_mission
    from eamos.program.uniform import ACTIONS

    spec = next(s for s in ACTIONS.values() if param in s.params)
    low, high = _bounds(PARAM_RANGES[param])
    exclusive_low = "<" in PARAM_RANGES[param].split(param)[0]

    def accepted(value: float) -> bool:
        args = ", ".join(repr(value) if p == param else "1" for p in spec.params)
        try:
            compile_mission(f"func SEQ_A() {{ D1.Arm(); D1.{spec.name}({args}) }}", "r.go")
        except MissionError:
            return False
        return True

    assert accepted(high) and not accepted(high + 1)
    assert accepted(low) != exclusive_low and not accepted(low - 1)
