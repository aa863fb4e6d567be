"""Try(Body, OnFailure): compile-time checks (table-driven) and the graphs, node by node."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from eamos.compiler import MissionError, compile_file, compile_mission
from eamos.program.format import program_from_dict

from .compiler_helpers import MISSIONS, named_edges, node_by_label

HEAD = "package m\n\nvar D1 Quadcopter\nvar D2 Quadcopter\n\n"
BLOCKS = "\n\nfunc SEQ_B() {\n\tD1.Land()\n}\n\nfunc SEQ_F() {\n\tD1.Land()\n}\n"


@dataclass(frozen=True)
class Bad:
    name: str
    statement: str  # the statement in SEQ_A, after D1.Arm()
    where: str  # line:col of the first error
    message: str
    hint: str = ""


# SEQ_A's statement is on line 8 (HEAD is 5 lines, then "func SEQ_A() {", "\tD1.Arm()").
CASES = [
    Bad(
        "one block only",
        "Try(SEQ_B)",
        "8:2",
        "Try takes 2 arguments, got 1",
        "Try(Body, OnFailure)",
    ),
    Bad("three blocks", "Try(SEQ_B, SEQ_F, SEQ_F)", "8:2", "Try takes 2 arguments, got 3"),
    Bad("no arguments", "Try()", "8:2", "Try takes 2 arguments, got 0"),
    Bad("a condition", "Try(D1.Z() > 1, SEQ_F)", "8:6", "Try expects a block name here"),
    Bad("a number", "Try(3, SEQ_F)", "8:6", "Try expects a block name here"),
    Bad(
        "a called block",
        "Try(SEQ_B(), SEQ_F)",
        "8:6",
        "name the block without calling it: SEQ_B, not SEQ_B()",
        "write Try(Body, OnFailure)",
    ),
    Bad(
        "missing Body",
        "Try(SEQ_Bx, SEQ_F)",
        "8:6",
        "undefined block 'SEQ_Bx'",
        "did you mean SEQ_B?",
    ),
    Bad(
        "missing OnFailure",
        "Try(SEQ_B, SEQ_Fx)",
        "8:13",
        "undefined block 'SEQ_Fx'",
        "did you mean SEQ_F?",
    ),
    Bad(
        "on a drone",
        "D1.Try(SEQ_B, SEQ_F)",
        "8:5",
        "Try is a control structure, not an action of D1",
        "write Try(Body, OnFailure)",
    ),
    Bad("misspelt", "Tyr(SEQ_B, SEQ_F)", "8:2", "undefined block 'Tyr'", "did you mean Try?"),
    Bad(
        "Body calls itself", "Try(SEQ_A, SEQ_F)", "8:6", "recursion between blocks: SEQ_A -> SEQ_A"
    ),
]


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_try_errors_are_located_with_a_hint(case: Bad) -> None:
    source = HEAD + "func SEQ_A() {\n\tD1.Arm()\n\t" + case.statement + "\n}" + BLOCKS
    with pytest.raises(MissionError) as info:
        compile_mission(source, "m.go")
    errors = [d for d in info.value.diagnostics if d.severity == "error"]
    text = info.value.render("m.go", source)
    assert f"{errors[0].loc}" == case.where, text
    assert case.message in errors[0].message, text
    assert case.hint in errors[0].hint, text
    assert "Traceback" not in text


SOURCE = (
    HEAD
    + """func SEQ_A() {
	D1.Arm()
	Try(PAR_Body, SEQ_Fail)
	D1.Land()
}

func PAR_Body() {
	D1.FlyByX(5)
	D2.FlyByY(5)
}

func SEQ_Fail() {
	D1.FlyToXYZ(0, 0, 3)
}
"""
)


def test_try_amt_meg_and_mdg_node_by_node() -> None:
    compiled = compile_mission(SOURCE, "m.go")
    amt, meg = compiled.amt, compiled.meg
    # AMT: the Try node hosted by Body's first drone, Body on a body edge, OnFailure on exit.
    try_node = next(n for n, a in amt.nodes(data=True) if a["kind"] == "try")
    attrs = amt.nodes[try_node]
    assert (attrs["drone"], attrs["label"], attrs["line"]) == ("D1", "Try PAR_Body", 8)
    roles = {amt.nodes[c]["label"]: d["role"] for _, c, d in amt.out_edges(try_node, data=True)}
    assert roles == {"PAR_Body": "body", "SEQ_Fail": "exit"}
    # MEG: C -body-> fork -> both legs -> E, C -begin-> E, E -exit-> OnFailure -> Land.
    end = meg.nodes[try_node]["end"]
    assert meg.nodes[end]["kind"] == "end" and meg.nodes[end]["begin"] == try_node
    assert named_edges(meg) >= {
        ("Try PAR_Body@D1", "PAR_Body"),
        ("PAR_Body", "FlyByX(5)@D1"),
        ("PAR_Body", "FlyByY(5)@D2"),
        ("FlyByX(5)@D1", "end Try@D1"),
        ("FlyByY(5)@D2", "end Try@D1"),
        ("Try PAR_Body@D1", "end Try@D1"),
        ("end Try@D1", "FlyToXYZ(0, 0, 3)@D1"),
        ("FlyToXYZ(0, 0, 3)@D1", "Land()@D1"),
        ("end Try@D1", "Land()@D1"),
    }
    kinds = {
        (meg.nodes[a]["label"], meg.nodes[b]["label"]): d["kind"]
        for a, b, d in meg.edges(data=True)
    }
    assert kinds[("Try PAR_Body", "PAR_Body")] == "body"
    assert kinds[("Try PAR_Body", "end Try")] == "begin"
    assert kinds[("end Try", "FlyToXYZ(0, 0, 3)")] == "exit"
    assert meg.nodes[try_node]["interrupt_mode"] == "all"
    assert meg.nodes[try_node]["interrupt_drones"] == ("D1", "D2")
    # Every node of Body knows the Try that catches it; OnFailure and the rest do not.
    for label in ("FlyByX(5)", "FlyByY(5)"):
        node = meg.nodes[node_by_label(meg, label)]
        assert node["scopes"] == (try_node,)
        assert (node["catch"], node["catch_loops"], node["catch_drones"]) == (
            try_node,
            0,
            ("D1", "D2"),
        )
        assert node["catch_line"] == 8
    for label in ("FlyToXYZ(0, 0, 3)", "Land()", "end Try", "Try PAR_Body"):
        assert "catch" not in meg.nodes[node_by_label(meg, label)]
    # MDG and program of D2: its leg, with the catch, and the arcs it exchanges with D1.
    mdg = compiled.mdgs["D2"]
    leg = f"n{node_by_label(meg, 'FlyByY(5)')}"
    assert mdg.nodes[leg]["native"] and mdg.nodes[leg]["catch"] == try_node
    assert {(a, b) for a, b, d in mdg.edges(data=True) if d["external"]} == {
        (f"n{try_node}", f"n{node_by_label(meg, 'PAR_Body')}@D2"),
        (leg, f"n{end}"),
    }
    program = compiled.programs["D2"]
    spec = program.node(leg)
    assert (spec.catch, spec.catch_drones, spec.catch_line) == (try_node, ("D1", "D2"), 8)
    # The program format keeps them through JSON (and leaves them out where absent).
    import json

    again = program_from_dict(json.loads(program.to_json()))
    assert again.node(leg) == spec
    assert "catch" not in json.loads(compiled.programs["GCS"].to_json())["nodes"][0]


def test_nested_try_inner_catches_and_loops_give_the_catch_depth() -> None:
    source = (
        HEAD
        + """func SEQ_A() {
	D1.Arm()
	Try(SEQ_Outer, SEQ_F)
}

func SEQ_Outer() {
	RepeatFor(2, SEQ_Loop)
	D2.FlyByY(1)
}

func SEQ_Loop() {
	Try(SEQ_Inner, SEQ_G)
}

func SEQ_Inner() {
	D1.FlyByX(1)
}

func SEQ_F() {
	D1.Land()
}

func SEQ_G() {
	D2.Land()
}
"""
    )
    meg = compile_mission(source, "m.go").meg
    outer = node_by_label(meg, "Try SEQ_Outer")
    inner = node_by_label(meg, "Try SEQ_Inner")
    loop = node_by_label(meg, "RepeatFor 2")
    fly = meg.nodes[node_by_label(meg, "FlyByX(1)")]
    assert fly["scopes"] == (outer, loop, inner)
    assert (fly["catch"], fly["catch_loops"], fly["catch_drones"]) == (inner, 1, ("D1",))
    # OnFailure of the inner Try is inside the outer one's Body (and inside the loop).
    land = meg.nodes[node_by_label(meg, "Land()", "D2")]
    assert (land["catch"], land["catch_loops"]) == (outer, 0)
    assert meg.nodes[outer]["interrupt_drones"] == ("D1", "D2")


def test_the_example_mission_compiles_with_one_try() -> None:
    compiled = compile_file(MISSIONS / "try_rescue.go")
    assert [a["label"] for _, a in compiled.meg.nodes(data=True) if a["kind"] == "try"] == [
        "Try PAR_Survey"
    ]
