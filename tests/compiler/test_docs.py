"""The compiler docs quote real output: keep them in step with the compiler."""

from __future__ import annotations

import re

import pytest

from eamos.compiler import MissionError, compile_file, compile_mission

from .compiler_helpers import MISSIONS, REPO

DOCS = REPO / "docs"


Figures = tuple[int, int, int, int]


def _stats_rows() -> tuple[dict[str, tuple[int, int]], dict[str, dict[str, Figures]]]:
    """From docs/graphs.md: MEG sizes and ``{mission: {participant: (nodes, int, in, out)}}``."""
    megs: dict[str, tuple[int, int]] = {}
    rows: dict[str, dict[str, Figures]] = {}
    current = ""
    for line in (DOCS / "graphs.md").read_text(encoding="utf-8").splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 6 or not re.fullmatch(r"\d+ / \d+", cells[5]):
            continue
        name = re.search(r"`([\w.]+\.go)`", cells[0])
        if name:
            current = name.group(1)
            nodes, arcs = (int(x) for x in cells[1].split(" / "))
            megs[current] = (nodes, arcs)
        ext_in, ext_out = (int(x) for x in cells[5].split(" / "))
        rows.setdefault(current, {})[cells[2]] = (int(cells[3]), int(cells[4]), ext_in, ext_out)
    return megs, rows


def test_graph_size_tables_match_the_compiler() -> None:
    megs, rows = _stats_rows()
    assert len(rows) == 9, sorted(rows)
    for mission, participants in rows.items():
        stats = compile_file(MISSIONS / mission).stats()
        meg: dict[str, int] = stats["meg"]  # type: ignore[assignment]
        drones: dict[str, dict[str, int]] = stats["drones"]  # type: ignore[assignment]
        assert megs[mission] == (meg["nodes"], meg["arcs"]), mission
        got = {
            d: (s["nodes"], s["internal_arcs"], s["external_in"], s["external_out"])
            for d, s in drones.items()
        }
        assert participants == got, mission


def test_error_example_in_the_language_reference_is_real_output() -> None:
    text = (DOCS / "mission-language.md").read_text(encoding="utf-8")
    source = re.search(r"`eamos compile bad.go` on\n\n(?:<!--.*?-->\n)?```go\n(.*?)```", text, re.S)
    output = re.search(r"prints\n\n```text\n(.*?)```", text, re.S)
    assert source and output
    with pytest.raises(MissionError) as info:
        compile_mission(source.group(1), "bad.go")
    assert info.value.render("bad.go", source.group(1)) + "\n" == output.group(1)


def test_reference_lists_every_action_property_and_drone_type() -> None:
    from eamos.program.uniform import ACTIONS, DRONE_TYPES, PROPERTIES

    text = (DOCS / "mission-language.md").read_text(encoding="utf-8")
    for name in ACTIONS:
        assert f"| `{name}(" in text, name
    for name in PROPERTIES:
        assert f"| `{name}()` |" in text, name
    for name in DRONE_TYPES:
        assert f"| `{name}`" in text, name
