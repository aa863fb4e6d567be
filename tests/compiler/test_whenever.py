"""Whenever(cond, Handler) and Abandon(): compile-time checks (table-driven) and the graphs."""

from __future__ import annotations

import json
from dataclasses import dataclass

import pytest

from eamos.compiler import MissionError, compile_file, compile_mission
from eamos.program.format import program_from_dict

from .compiler_helpers import MISSIONS, named_edges, node_by_label

HEAD = "package m\n\nvar D1 Quadcopter\nvar D2 Quadcopter\n\n"
HANDLER = "\n\nfunc SEQ_H() {\n\tD1.Land()\n}\n"


@dataclass(frozen=True)
class Bad:
    name: str
    statements: str  # SEQ_A's statements after D1.Arm() (which is on line 7)
    where: str
    message: str
    hint: str = ""
    extra: str = ""  # more blocks


CASES = [
    Bad(
        "no handler",
        "Whenever(D1.Z() > 1)\n\tD1.Land()",
        "8:2",
        "Whenever takes 2 arguments, got 1",
        "write Whenever(cond, Handler)",
    ),
    Bad("no condition", "Whenever(SEQ_H)\n\tD1.Land()", "8:2", "Whenever takes 2 arguments, got 1"),
    Bad(
        "a number for a condition",
        "Whenever(D1.Z(), SEQ_H)\n\tD1.Land()",
        "8:11",
        "the condition of Whenever is a number, not true/false",
    ),
    Bad(
        "a called handler",
        "Whenever(D1.Z() > 1, SEQ_H())\n\tD1.Land()",
        "8:23",
        "name the block without calling it",
    ),
    Bad(
        "missing handler",
        "Whenever(D1.Z() > 1, SEQ_Hx)\n\tD1.Land()",
        "8:23",
        "undefined block 'SEQ_Hx'",
        "did you mean SEQ_H?",
    ),
    Bad(
        "guards nothing",
        "D1.Land()\n\tWhenever(D1.Z() > 1, SEQ_H)",
        "9:2",
        "Whenever is the last statement of SEQ_A: it guards nothing",
        "put it before them",
    ),
    Bad(
        "in a PAR block",
        "PAR_P()",
        "17:2",
        "Whenever in a PAR_ block",
        "call a SEQ_ block from PAR_P that starts with the Whenever",
        "\nfunc PAR_P() {\n\tD1.Land()\n\tWhenever(D1.Z() > 1, SEQ_H)\n}\n",
    ),
    Bad(
        "on a drone",
        "D1.Whenever(D1.Z() > 1, SEQ_H)\n\tD1.Land()",
        "8:5",
        "Whenever is a control structure, not an action of D1",
        "write Whenever(cond, Handler)",
    ),
    Bad(
        "Abandon outside a handler",
        "Abandon()",
        "8:2",
        "Abandon() outside a Whenever handler (SEQ_A runs outside one)",
        "goes in the Handler block",
    ),
    Bad(
        "Abandon in a block also run outside a handler",
        "Whenever(D1.Z() > 1, SEQ_G)\n\tSEQ_G()",
        "18:2",
        "Abandon() outside a Whenever handler (SEQ_G runs outside one)",
        "",
        "\nfunc SEQ_G() {\n\tD1.Land()\n\tAbandon()\n}\n",
    ),
    Bad("Abandon with an argument", "Abandon(1)", "8:2", "Abandon takes 0 arguments, got 1"),
]


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_whenever_and_abandon_errors_are_located_with_a_hint(case: Bad) -> None:
    source = (
        HEAD + "func SEQ_A() {\n\tD1.Arm()\n\t" + case.statements + "\n}" + HANDLER + case.extra
    )
    with pytest.raises(MissionError) as info:
        compile_mission(source, "m.go")
    errors = [d for d in info.value.diagnostics if d.severity == "error"]
    text = info.value.render("m.go", source)
    assert f"{errors[0].loc}" == case.where, text
    assert case.message in errors[0].message, text
    assert case.hint in errors[0].hint, text
    assert "Traceback" not in text


def test_abandon_in_a_block_only_a_handler_runs_compiles() -> None:
    source = (
        HEAD
        + "func SEQ_A() {\n\tD1.Arm()\n\tWhenever(D1.Z() > 1, SEQ_H)\n\tD1.Land()\n}\n"
        + "\nfunc SEQ_H() {\n\tSEQ_G()\n}\n\nfunc SEQ_G() {\n\tD1.Land()\n\tAbandon()\n}\n"
    )
    compile_mission(source, "m.go")


SOURCE = (
    HEAD
    + """func SEQ_A() {
	D1.Arm()
	Whenever(D1.Battery() < 25, SEQ_H)
	D1.FlyByX(5)
	D2.FlyByY(5)
}

func SEQ_H() {
	D1.FlyToXYZ(0, 0, 2)
	Abandon()
}
"""
)


def test_whenever_amt_meg_and_mdg_node_by_node() -> None:
    compiled = compile_mission(SOURCE, "m.go")
    amt, meg = compiled.amt, compiled.meg
    w = node_by_label(amt, "Whenever D1.Battery() < 25")
    assert (amt.nodes[w]["kind"], amt.nodes[w]["drone"], amt.nodes[w]["line"]) == (
        "whenever",
        "D1",
        8,
    )
    roles = {amt.nodes[c]["label"]: d["role"] for _, c, d in amt.out_edges(w, data=True)}
    assert roles == {"SEQ_A after Whenever": "body", "SEQ_H": "handler"}
    # The statements after the Whenever hang from it; the block's seq keeps Arm and W only.
    seq_a = node_by_label(amt, "SEQ_A")
    assert [amt.nodes[c]["label"] for c in amt.successors(seq_a)] == [
        "Arm()",
        "Whenever D1.Battery() < 25",
    ]
    abandon = node_by_label(amt, "Abandon()")
    assert (amt.nodes[abandon]["kind"], amt.nodes[abandon]["begin"]) == ("abandon", w)
    # MEG: W -body-> R -> E, W -begin-> E, W -handler-> H -loop-> W.
    end = meg.nodes[w]["end"]
    edges = {
        (meg.nodes[a]["label"], meg.nodes[b]["label"]): d["kind"]
        for a, b, d in meg.edges(data=True)
    }
    label = "Whenever D1.Battery() < 25"
    assert edges == {
        ("INIT", "Arm()"): "seq",
        ("Arm()", label): "seq",
        (label, "FlyByX(5)"): "body",
        ("FlyByX(5)", "FlyByY(5)"): "seq",
        ("FlyByY(5)", "end Whenever"): "seq",
        (label, "end Whenever"): "begin",
        (label, "FlyToXYZ(0, 0, 2)"): "handler",
        ("FlyToXYZ(0, 0, 2)", "Abandon()"): "seq",
        ("Abandon()", label): "loop",
    }
    assert meg.nodes[end]["drone"] == "D1"
    attrs = meg.nodes[w]
    assert (attrs["interrupt_drones"], attrs["suspend_drones"]) == (("D1", "D2"), ("D1",))
    fly_x = meg.nodes[node_by_label(meg, "FlyByX(5)")]
    fly_y = meg.nodes[node_by_label(meg, "FlyByY(5)")]
    home = meg.nodes[node_by_label(meg, "FlyToXYZ(0, 0, 2)")]
    assert (fly_x["scopes"], fly_x["loops"], fly_x.get("suspendable")) == ((w,), (), True)
    assert (fly_y["scopes"], fly_y.get("suspendable")) == ((w,), None)  # D2: not in the Handler
    assert (home["loops"], home["scopes"], home.get("in_handler")) == ((w,), (), True)
    ab = meg.nodes[node_by_label(meg, "Abandon()")]
    assert (ab["begin"], ab["interrupt_drones"], ab["interrupt_mode"]) == (w, ("D1", "D2"), "all")
    # D2's MDG: its guarded leg with the arcs it exchanges with D1; the programs keep the fields.
    assert ("FlyByX(5)@D1", "FlyByY(5)@D2") in named_edges(compiled.mdgs["D2"])
    program = compiled.programs["D1"]
    again = program_from_dict(json.loads(program.to_json()))
    assert again == program
    assert again.node(f"n{w}").suspend_drones == ("D1",)
    assert {a.kind for a in program.arcs} >= {"handler", "loop", "begin", "body"}


def test_the_example_missions_compile() -> None:
    for name in ("whenever_battery.go", "whenever_abandon.go"):
        meg = compile_file(MISSIONS / name).meg
        assert [a["kind"] for _, a in meg.nodes(data=True)].count("whenever") == 1
