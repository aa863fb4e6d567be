"""Mission libraries: ``import "name"`` resolution, located errors, recorded checksums."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import pytest

from eamos.compiler import MissionError, compile_file
from eamos.program.format import load_program, program_from_dict

LIB = (
    "package lib\n\n"
    "func SEQ_Hop(d Quadcopter, dist_m float64) {\n\td.FlyByX(dist_m)\n\td.FlyByX(-dist_m)\n}\n"
)
MAIN = 'package m\n\nimport "lib"\n\nfunc SEQ_Main() {\n\tD1.Arm()\n\tlib.SEQ_Hop(D1, 5)\n}\n'


def _tree(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")


def test_an_imported_block_is_expanded_and_its_file_recorded(tmp_path: Path) -> None:
    _tree(tmp_path, {"m.go": MAIN, "lib/lib.go": LIB})
    compiled = compile_file(tmp_path / "m.go")
    args = [a["args"] for _, a in compiled.amt.nodes(data=True) if a.get("action") == "FlyByX"]
    assert args == [(5.0,), (-5.0,)]
    blocks = {a["block"] for _, a in compiled.amt.nodes(data=True) if a["kind"] == "action"}
    assert blocks == {"SEQ_Main", "lib.SEQ_Hop(D1, 5)"}
    digest = hashlib.sha256((tmp_path / "lib/lib.go").read_bytes()).hexdigest()
    program = compiled.programs["D1"]
    assert program.libraries == ((str(tmp_path / "lib/lib.go"), digest),)
    # Saved and loaded back: the field survives and the checksum still verifies.
    saved = program.save(tmp_path / "D1.program.json")
    assert load_program(saved) == program
    assert json.loads(saved.read_text())["libraries"] == [
        {"path": str(tmp_path / "lib/lib.go"), "sha256": digest}
    ]


def test_a_library_change_changes_the_mission_identity(tmp_path: Path) -> None:
    _tree(tmp_path, {"m.go": MAIN, "lib/lib.go": LIB})
    before = compile_file(tmp_path / "m.go").mission_id
    (tmp_path / "lib/lib.go").write_text(LIB + "\n// a comment\n", encoding="utf-8")
    assert compile_file(tmp_path / "m.go").mission_id != before


def test_a_program_without_the_field_still_loads(tmp_path: Path) -> None:
    _tree(tmp_path, {"m.go": "func SEQ_A() {\n\tD1.Arm()\n}\n"})
    program = compile_file(tmp_path / "m.go").programs["D1"]
    doc = json.loads(program.to_json())
    assert "libraries" not in doc  # a mission without libraries writes what it always did
    assert program_from_dict(doc).libraries == ()


def test_the_mission_folder_comes_before_eamos_path_and_the_standard_library(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    mine = LIB.replace("package lib", "package shapes").replace("SEQ_Hop", "SEQ_Square")
    _tree(
        tmp_path,
        {
            "mission/m.go": MAIN.replace('"lib"', '"shapes"').replace(
                "lib.SEQ_Hop", "shapes.SEQ_Square"
            ),
            "mission/shapes/shapes.go": mine,
            "path1/lib/lib.go": LIB.replace("dist_m)\n\td", "dist_m * 2)\n\td"),
            "path2/lib/lib.go": LIB,
        },
    )
    compiled = compile_file(tmp_path / "mission/m.go")
    assert [p for p, _ in compiled.programs["D1"].libraries] == [
        str(tmp_path / "mission/shapes/shapes.go")
    ]
    monkeypatch.setenv("EAMOS_PATH", f"{tmp_path / 'path1'}:{tmp_path / 'path2'}")
    _tree(tmp_path, {"mission/m2.go": MAIN})
    compiled = compile_file(tmp_path / "mission/m2.go")
    args = [a["args"] for _, a in compiled.amt.nodes(data=True) if a.get("action") == "FlyByX"]
    assert args == [(10.0,), (-5.0,)]  # path1's copy, the first on EAMOS_PATH


@dataclass(frozen=True)
class BadLibrary:
    name: str
    files: dict[str, str]
    file: str  # the file the first error is in
    where: str  # its line:col
    message: str
    hint: str = ""


BAD = [
    BadLibrary(
        "missing library",
        {"m.go": MAIN.replace('"lib"', '"nolib"').replace("lib.SEQ", "nolib.SEQ")},
        "m.go",
        "3:8",
        "no library 'nolib'",
        "looked for the folder in",
    ),
    BadLibrary(
        "import cycle",
        {
            "m.go": MAIN,
            "lib/lib.go": LIB.replace("package lib\n", 'package lib\n\nimport "other"\n'),
            "other/other.go": 'package other\n\nimport "lib"\n\nfunc SEQ_X(d Quadcopter) {\n'
            "\td.Land()\n}\n",
        },
        "other/other.go",
        "3:8",
        "import cycle: lib -> other -> lib",
    ),
    BadLibrary(
        "two libraries with one name",
        {
            "m.go": MAIN.replace('import "lib"', 'import (\n\t"a/lib"\n\t"b/lib"\n)'),
            "a/lib/lib.go": LIB,
            "b/lib/lib.go": LIB,
        },
        "m.go",
        "5:2",
        "two libraries are named 'lib'",
        "rename one of the folders",
    ),
    BadLibrary(
        "library named like a drone",
        {"m.go": "var lib Quadcopter\n" + MAIN.replace("package m\n", ""), "lib/lib.go": LIB},
        "m.go",
        "3:8",
        "library 'lib' has the name of drone lib",
    ),
    BadLibrary(
        "wrong package clause",
        {"m.go": MAIN, "lib/lib.go": LIB.replace("package lib", "package other")},
        "lib/lib.go",
        "1:1",
        "declares package 'other', but its folder is 'lib'",
        "write: package lib",
    ),
    BadLibrary(
        "error inside a library block",
        {"m.go": MAIN, "lib/lib.go": LIB.replace("d.FlyByX(-dist_m)", "d.FlyBX(-dist_m)")},
        "lib/lib.go",
        "5:4",
        "unknown action 'FlyBX'",
        "did you mean FlyByX?",
    ),
    BadLibrary(
        "a library declaring drones",
        {"m.go": MAIN, "lib/lib.go": LIB + "var D9 Quadcopter\n"},
        "lib/lib.go",
        "7:5",
        "a library declares no drones",
    ),
    BadLibrary(
        "a block defined in two files of a library",
        {"m.go": MAIN, "lib/lib.go": LIB, "lib/more.go": LIB},
        "lib/more.go",
        "3:6",
        "block 'lib.SEQ_Hop' is defined twice",
        "lib.go:3",
    ),
    BadLibrary(
        "an undefined library block",
        {"m.go": MAIN.replace("lib.SEQ_Hop", "lib.SEQ_Hopp"), "lib/lib.go": LIB},
        "m.go",
        "7:2",
        "undefined block 'lib.SEQ_Hopp'",
        "did you mean lib.SEQ_Hop?",
    ),
    BadLibrary(
        "a package not imported",
        {"m.go": "func SEQ_Main() {\n\tlib.SEQ_Hop(D1, 5)\n}\n"},
        "m.go",
        "2:6",
        "unknown action 'SEQ_Hop'",
    ),
    BadLibrary(
        "an import path that is no folder name",
        {"m.go": MAIN.replace('"lib"', '"../lib"')},
        "m.go",
        "3:8",
        "'../lib' is not a library name",
    ),
    BadLibrary(
        "a library growing the tree past the cap",
        {
            "m.go": MAIN.replace("lib.SEQ_Hop(D1, 5)", "lib.SEQ_Big(D1)"),
            "lib/lib.go": "package lib\n\n"
            + "".join(
                f"func SEQ_L{i}(d Quadcopter) {{\n" + f"\tSEQ_L{i + 1}(d)\n" * 10 + "}\n"
                for i in range(5)
            )
            + "func SEQ_L5(d Quadcopter) {\n\td.Land()\n}\n"
            + "func SEQ_Big(d Quadcopter) {\n\tSEQ_L0(d)\n}\n",
        },
        "lib/lib.go",
        "3:6",
        "expands to",
        "every call copies",
    ),
]


def test_unreadable_library_files_are_located_errors(tmp_path: Path) -> None:
    _tree(tmp_path, {"m.go": MAIN, "lib/lib.go": LIB})
    (tmp_path / "lib/bad.go").write_bytes(b"package lib\n\xff\xfe\n")
    (tmp_path / "lib/nul.go").write_bytes(b"package lib\x00\n")
    (tmp_path / "lib/dir.go").mkdir()
    with pytest.raises(MissionError) as info:
        compile_file(tmp_path / "m.go")
    found = {
        (d.loc.file, str(d.loc), d.message.split(":")[0].split(" bytes)")[0])
        for d in info.value.diagnostics
    }
    assert found == {
        ("", "3:8", f"cannot read library file {tmp_path / 'lib/bad.go'}"),
        ("", "3:8", f"cannot read library file {tmp_path / 'lib/dir.go'}"),
        (
            str(tmp_path / "lib/nul.go"),
            "1:1",
            "the library file is not text (it contains NUL",
        ),
    }
    text = info.value.render("m.go", MAIN)
    assert "Traceback" not in text


@pytest.mark.parametrize("case", BAD, ids=[c.name for c in BAD])
def test_library_errors_are_located_in_their_file(tmp_path: Path, case: BadLibrary) -> None:
    _tree(tmp_path, case.files)
    with pytest.raises(MissionError) as info:
        compile_file(tmp_path / "m.go")
    main = (tmp_path / "m.go").read_text()
    text = info.value.render(str(tmp_path / "m.go"), main)
    errors = [d for d in info.value.diagnostics if d.severity == "error"]
    first = errors[0]
    assert (first.loc.file or str(tmp_path / "m.go")) == str(tmp_path / case.file), text
    assert f"{first.loc}" == case.where, text
    assert case.message in first.message, text
    assert case.hint in first.hint, text
    # Rendered with the library file's own path, line and caret.
    lines = text.splitlines()
    head = f"{tmp_path / case.file}:{case.where}: error: {first.message}"
    assert head in lines, text
    source_lines = (tmp_path / case.file).read_text().splitlines()
    line = int(case.where.split(":")[0])
    assert lines[lines.index(head) + 1].strip() == source_lines[line - 1].strip(), text
    assert "Traceback" not in text


def test_the_language_server_finds_libraries_next_to_the_mission(tmp_path: Path) -> None:
    from eamos.lsp.document import checked_findings, findings
    from eamos.lsp.server import mission_path

    _tree(tmp_path, {"m.go": MAIN, "lib/lib.go": LIB})
    path = mission_path((tmp_path / "m.go").as_uri())
    assert path == str(tmp_path / "m.go")
    assert [f for f in findings(MAIN, path) if f.severity == "error"] == []
    (tmp_path / "lib/lib.go").write_text(LIB.replace("FlyByX(-", "FlyBX(-"), encoding="utf-8")
    found = checked_findings(MAIN, path)
    # A mistake in the library is shown at the top of the mission, naming its place.
    assert [(f.span.line, f.message) for f in found] == [
        (1, f"{tmp_path / 'lib/lib.go'}:5:4: unknown action 'FlyBX'")
    ]


def test_a_library_change_redeploys_only_the_drones_that_use_it(tmp_path: Path) -> None:
    from eamos.ops.identity import execution_digest

    main = (
        'import (\n\t"lib"\n\t"other"\n)\n\n'
        "func SEQ_Main() {\n\tlib.SEQ_Hop(D1, 5)\n\tother.SEQ_Up(D2)\n}\n"
    )
    other = "package other\n\nfunc SEQ_Up(d Quadcopter) {\n\td.Arm()\n}\n"
    _tree(tmp_path, {"m.go": main, "lib/lib.go": LIB, "other/other.go": other})
    before = compile_file(tmp_path / "m.go").programs
    assert [p for p, _ in before["D1"].libraries] == [str(tmp_path / "lib/lib.go")]
    assert [p for p, _ in before["D2"].libraries] == [str(tmp_path / "other/other.go")]
    (tmp_path / "other/other.go").write_text(other + "// changed\n", encoding="utf-8")
    after = compile_file(tmp_path / "m.go").programs
    assert execution_digest(after["D1"]) == execution_digest(before["D1"])
    assert execution_digest(after["D2"]) != execution_digest(before["D2"])


def test_the_library_count_is_capped(tmp_path: Path) -> None:
    from eamos.compiler.limits import MAX_LIBRARIES

    files = {"m.go": 'import "l0"\n\nfunc SEQ_Main() {\n\tD1.Arm()\n}\n'}
    for i in range(MAX_LIBRARIES + 1):
        files[f"l{i}/l{i}.go"] = (
            f'package l{i}\n\nimport "l{i + 1}"\n\nfunc SEQ_X(d Quadcopter) {{\n\td.Arm()\n}}\n'
        )
    files[f"l{MAX_LIBRARIES + 1}/l{MAX_LIBRARIES + 1}.go"] = (
        f"package l{MAX_LIBRARIES + 1}\n\nfunc SEQ_X(d Quadcopter) {{\n\td.Arm()\n}}\n"
    )
    _tree(tmp_path, files)
    with pytest.raises(MissionError) as info:
        compile_file(tmp_path / "m.go")
    first = info.value.diagnostics[0]
    assert first.message == f"more than {MAX_LIBRARIES} libraries are imported"
    assert first.loc.file == str(tmp_path / f"l{MAX_LIBRARIES - 1}/l{MAX_LIBRARIES - 1}.go")
