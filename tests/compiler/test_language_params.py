"""Parameterised blocks and declared drone types: compile-time checks and graph shapes.

Each bad mission is refused with a located error (line:col in its file), a
message and a hint; good ones expand each call into the mission tree, so the
graphs are those of the same mission written out by hand.
"""

from __future__ import annotations

from dataclasses import dataclass

import networkx as nx
import pytest

from eamos.compiler import MissionError, compile_mission
from eamos.compiler.limits import MAX_TREE_NODES

from .compiler_helpers import node_by_label


@dataclass(frozen=True)
class Bad:
    name: str
    source: str
    where: str  # "line:col" of the first error
    message: str  # substring of its message
    hint: str = ""  # substring of its hint


HOP = "func SEQ_Hop(d Quadcopter, dist_m float64) {\n\td.FlyByX(dist_m)\n\td.FlyByX(-dist_m)\n}\n"
BLOCK_H = "func SEQ_H(d Quadcopter, h float64) {\n"
INSPECTOR = "type Inspector interface {\n\tQuadcopter\n\tTakePhoto()\n}\nvar D1 Inspector\n"

CASES = [
    Bad(
        "argument count",
        "func SEQ_A() {\n\tSEQ_Hop(D1)\n}\n" + HOP,
        "2:2",
        "SEQ_Hop takes 2 arguments, got 1",
        "SEQ_Hop(d Quadcopter, dist_m float64)",
    ),
    Bad(
        "drone type does not satisfy the parameter's",
        "var D1 DroneType1\nfunc SEQ_A() {\n\tSEQ_Cam(D1)\n}\n"
        "func SEQ_Cam(d DroneType2) {\n\td.TurnOnCamera()\n}\n",
        "3:10",
        "D1 (DroneType1) is not a DroneType2: it has no AdjustCamera, TurnOnCamera",
        "needs a drone of type DroneType2",
    ),
    Bad(
        "number for a drone",
        "func SEQ_A() {\n\tSEQ_Hop(5, 1)\n}\n" + HOP,
        "2:10",
        "SEQ_Hop's parameter 'd' is a drone (Quadcopter)",
        "pass a drone by its name",
    ),
    Bad(
        "drone for a number",
        "func SEQ_A() {\n\tSEQ_Hop(D1, D1)\n}\n" + HOP,
        "2:14",
        "'D1' is a drone (Quadcopter), not a number",
    ),
    Bad(
        "misspelt parameter",
        "func SEQ_A() {\n\tSEQ_H(D1, 2)\n}\n"
        "func SEQ_H(d Quadcopter, dist_m float64) {\n\td.FlyByX(dist)\n}\n",
        "5:11",
        "unknown name 'dist'",
        "did you mean dist_m?",
    ),
    Bad(
        "division by zero once folded",
        "func SEQ_A() {\n\tSEQ_H(D1, 0)\n}\n" + BLOCK_H + "\td.FlyByX(1 / h)\n}\n",
        "5:13",
        "division by zero",
        "in SEQ_H(D1, 0)",
    ),
    Bad(
        "non-finite constant",
        "func SEQ_A() {\n\tD1.FlyByX(1e308 * 10)\n}\n",
        "2:12",
        "not a finite number",
    ),
    Bad(
        "folded argument out of range",
        "func SEQ_A() {\n\tSEQ_H(D1, 2)\n}\n" + BLOCK_H + "\td.Takeoff(-h)\n}\n",
        "5:12",
        "Takeoff's height_m must be positive, got -2",
        "in SEQ_H(D1, 2)",
    ),
    Bad(
        "unknown parameter type",
        "func SEQ_A() {\n\tSEQ_H(D1)\n}\nfunc SEQ_H(d Quadcoptr) {\n\td.Land()\n}\n",
        "4:14",
        "unknown parameter type 'Quadcoptr'",
        "did you mean Quadcopter?",
    ),
    Bad(
        "block with parameters named as a body",
        "func SEQ_A() {\n\tRepeatFor(2, SEQ_Hop)\n}\n" + HOP,
        "2:15",
        "SEQ_Hop takes parameters: name it with its arguments",
        "e.g. RepeatFor(..., SEQ_Hop(d Quadcopter, dist_m float64))",
    ),
    Bad(
        "action on a number",
        "func SEQ_A() {\n\tSEQ_H(D1, 2)\n}\n" + BLOCK_H + "\th.Land()\n}\n",
        "5:2",
        "'h' is a number, not a drone",
    ),
    Bad(
        "entry block with parameters",
        "func SEQ_A(h float64) {\n\tD1.Land()\n}\n",
        "1:12",
        "block 'SEQ_A' takes no parameters",
        "where the mission starts",
    ),
    Bad(
        "parameter named like a drone",
        "var D1 Quadcopter\nfunc SEQ_A() {\n\tSEQ_H(D1, 1)\n}\n"
        "func SEQ_H(D1 Quadcopter, h float64) {\n\tD1.FlyByZ(h)\n}\n",
        "5:12",
        "parameter 'D1' has the name of a drone",
    ),
    Bad(
        "string argument of a block",
        'func SEQ_A() {\n\tSEQ_Hop(D1, "far")\n}\n' + HOP,
        "2:14",
        "literal numbers, not a string",
    ),
    Bad(
        "declared action no adapter implements",
        # Sample is neither uniform nor provided by an installed plugin (TakePhoto is: the
        # camera plugins, docs/plugins.md).
        "type Sampler interface {\n\tQuadcopter\n\tSample()\n}\nvar D1 Sampler\n"
        "func SEQ_A() {\n\tD1.Sample()\n}\n",
        "7:5",
        "no adapter implements action 'Sample' yet",
        "declared by a drone type",
    ),
    Bad(
        "misspelt declared action",
        INSPECTOR + "func SEQ_A() {\n\tD1.TakePhot()\n}\n",
        "7:5",
        "unknown action 'TakePhot'",
        "did you mean TakePhoto?",
    ),
    Bad(
        "action the declared type lacks",
        "type Cam interface {\n\tTakePhoto()\n}\nvar D1 Cam\nfunc SEQ_A() {\n\tD1.Takeoff(1)\n}\n",
        "6:5",
        "D1 (Cam) has no action 'Takeoff'",
        "Cam offers: TakePhoto",
    ),
    Bad(
        "declared action's argument count",
        "type Cam interface {\n\tQuadcopter\n\tGimbal(pitch_deg float64)\n}\nvar D1 Cam\n"
        "func SEQ_A() {\n\tD1.Gimbal()\n}\n",
        "7:2",
        "Gimbal takes 1 argument, got 0",
        "Gimbal(pitch_deg)",
    ),
    Bad(
        "uniform action redeclared differently",
        "type Cam interface {\n\tTakeoff()\n}\nfunc SEQ_A() {\n\tD1.Land()\n}\n",
        "2:2",
        "action 'Takeoff' is declared by the uniform API with 1 parameter",
        "Takeoff(height_m float64)",
    ),
    Bad(
        "unknown embedded type",
        "type Cam interface {\n\tQuadcoptr\n}\nvar D1 Cam\nfunc SEQ_A() {\n\tD1.Land()\n}\n",
        "2:2",
        "unknown drone type 'Quadcoptr'",
        "did you mean Quadcopter?",
    ),
    Bad(
        "types embedding each other",
        "type A interface {\n\tB\n}\ntype B interface {\n\tA\n}\nvar D1 A\n"
        "func SEQ_A() {\n\tD1.Land()\n}\n",
        "5:2",
        "drone types embed each other in a cycle",
    ),
    Bad(
        "action parameter that is not a number",
        "type A interface {\n\tGimbal(p Quadcopter)\n}\nfunc SEQ_A() {\n\tD1.Land()\n}\n",
        "2:11",
        "an action's parameters are numbers",
        "pitch_deg float64",
    ),
    Bad(
        "a type that is not an interface",
        "type A struct{}\nfunc SEQ_A() {\n\tD1.Land()\n}\n",
        "1:8",
        "a drone type is an interface of actions",
    ),
    Bad(
        "unknown declared type of a drone",
        "type Inspector interface {\n\tQuadcopter\n}\nvar D1 Inspectr\n"
        "func SEQ_A() {\n\tD1.Land()\n}\n",
        "4:8",
        "unknown drone type 'Inspectr'",
        "did you mean Inspector?",
    ),
    Bad(
        "built-in type redeclared",
        "type Quadcopter interface {\n\tLand()\n}\nfunc SEQ_A() {\n\tD1.Land()\n}\n",
        "1:6",
        "'Quadcopter' is a built-in type",
    ),
]


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_error_location_message_and_hint(case: Bad) -> None:
    with pytest.raises(MissionError) as info:
        compile_mission(case.source, "m.go")
    errors = [d for d in info.value.diagnostics if d.severity == "error"]
    first = errors[0]
    text = info.value.render("m.go", case.source)
    assert f"{first.loc}" == case.where, text
    assert case.message in first.message, text
    assert case.hint in first.hint, text
    assert f"m.go:{case.where}: error: {first.message}" in text.splitlines()
    assert "Traceback" not in text


def _actions(amt: nx.DiGraph) -> list[tuple[str, str, tuple[float, ...]]]:
    """(drone, action, args) of the tree's action nodes, in creation order."""
    return [
        (a["drone"], a["action"], tuple(a["args"]))
        for _, a in sorted(amt.nodes(data=True))
        if a["kind"] == "action"
    ]


def test_each_call_is_expanded_with_its_values_folded() -> None:
    source = (
        "var D1 Quadcopter\nvar D2 Quadcopter\n"
        "func SEQ_Main() {\n\tSEQ_Hop(D1, 2)\n\tSEQ_Hop(D2, 2 * 3)\n\tSEQ_Hop(D1, 2)\n}\n" + HOP
    )
    compiled = compile_mission(source, "m.go")
    amt = compiled.amt
    seqs = [a["label"] for _, a in amt.nodes(data=True) if a["kind"] == "seq"]
    # A block called three times appears three times; equal calls share one copy's name.
    assert seqs == ["SEQ_Main", "SEQ_Hop(D1, 2)", "SEQ_Hop(D2, 6)", "SEQ_Hop(D1, 2)"]
    assert _actions(amt) == [
        ("D1", "FlyByX", (2.0,)),
        ("D1", "FlyByX", (-2.0,)),
        ("D2", "FlyByX", (6.0,)),
        ("D2", "FlyByX", (-6.0,)),
        ("D1", "FlyByX", (2.0,)),
        ("D1", "FlyByX", (-2.0,)),
    ]
    # The action nodes keep their place in the block's text (where an error would point).
    hop = node_by_label(amt, "FlyByX(6)", "D2")
    assert (amt.nodes[hop]["line"], amt.nodes[hop]["col"]) == (9, 2)
    assert set(compiled.programs) == {"GCS", "D1", "D2"}
    assert "d" not in compiled.programs  # a drone parameter is not a drone


def _shape(graph: nx.DiGraph) -> set[tuple[str, str]]:
    """The graph's arcs between nodes named by what they do (not by block names)."""

    def name(n: object) -> str:
        a = graph.nodes[n]
        if a["kind"] == "action":
            return f"{a['action']}{tuple(a['args'])}@{a['drone']}"
        return f"{a['kind']}@{a.get('drone', '')}"

    return {(name(a), name(b)) for a, b in graph.edges}


def test_the_graphs_are_those_of_the_mission_written_out_by_hand() -> None:
    generic = (
        "var D1 Quadcopter\nvar D2 Quadcopter\n"
        "func SEQ_Main() {\n\tPAR_Up()\n\tPAR_Fly()\n}\n"
        "func PAR_Up() {\n\tSEQ_Up(D1, 2)\n\tSEQ_Up(D2, 3)\n}\n"
        "func SEQ_Up(d Quadcopter, h float64) {\n\td.Arm()\n\td.Takeoff(h)\n}\n"
        "func PAR_Fly() {\n\tSEQ_Leg(D1, 4)\n\tSEQ_Leg(D2, 4)\n}\n"
        "func SEQ_Leg(d Quadcopter, x float64) {\n"
        "\tWaitUntil(d.Z() > 1, SEQ_Go)\n\td.FlyToXYZ(x, -x / 2, 2)\n}\n"
        "func SEQ_Go() {\n\tPauseFor(1)\n}\n"
    )
    by_hand = (
        "var D1 Quadcopter\nvar D2 Quadcopter\n"
        "func SEQ_Main() {\n\tPAR_Up()\n\tPAR_Fly()\n}\n"
        "func PAR_Up() {\n\tSEQ_Up1()\n\tSEQ_Up2()\n}\n"
        "func SEQ_Up1() {\n\tD1.Arm()\n\tD1.Takeoff(2)\n}\n"
        "func SEQ_Up2() {\n\tD2.Arm()\n\tD2.Takeoff(3)\n}\n"
        "func PAR_Fly() {\n\tSEQ_Leg1()\n\tSEQ_Leg2()\n}\n"
        "func SEQ_Leg1() {\n\tWaitUntil(D1.Z() > 1, SEQ_Go)\n\tD1.FlyToXYZ(4, -2, 2)\n}\n"
        "func SEQ_Leg2() {\n\tWaitUntil(D2.Z() > 1, SEQ_Go)\n\tD2.FlyToXYZ(4, -2, 2)\n}\n"
        "func SEQ_Go() {\n\tPauseFor(1)\n}\n"
    )
    a, b = compile_mission(generic, "g.go"), compile_mission(by_hand, "h.go")
    assert _shape(a.amt) == _shape(b.amt)
    assert _shape(a.meg) == _shape(b.meg)
    assert a.stats() == b.stats()
    for drone in ("D1", "D2", "GCS"):
        assert _shape(a.mdgs[drone]) == _shape(b.mdgs[drone])


def test_conditions_read_the_drone_and_the_numbers_passed() -> None:
    source = (
        "var D1 Quadcopter\nfunc SEQ_Main() {\n\tSEQ_Climb(D1, 4)\n}\n"
        "func SEQ_Climb(d Quadcopter, h float64) {\n\td.Arm()\n\td.Takeoff(h)\n"
        "\tWaitUntil(d.Z() > h - 0.5, SEQ_Done)\n}\n"
        "func SEQ_Done() {\n\tD1.Land()\n}\n"
    )
    amt = compile_mission(source, "m.go").amt
    wait = next(n for n, a in amt.nodes(data=True) if a["kind"] == "wait_until")
    assert amt.nodes[wait]["cond"] == [">", ["prop", "D1", "Z"], ["-", ["num", 4.0], ["num", 0.5]]]
    assert amt.nodes[wait]["drone"] == "D1"


def test_a_declared_type_checks_its_drones_and_is_recorded_in_the_program() -> None:
    source = (
        "type Flyer interface {\n\tArm()\n\tTakeoff(height_m float64)\n\tLand()\n}\n"
        "type Scout interface {\n\tFlyer\n\tFlyByX(distance_m float64)\n}\n"
        "var D1 Scout\nfunc SEQ_Main() {\n\tSEQ_Go(D1)\n}\n"
        "func SEQ_Go(d Flyer) {\n\td.Arm()\n\td.Takeoff(2)\n\td.Land()\n}\n"
    )
    compiled = compile_mission(source, "m.go")
    assert compiled.programs["D1"].drone_type == "Scout"
    with pytest.raises(MissionError) as info:
        compile_mission(source.replace("\td.Land()\n", "\td.FlyByX(1)\n"), "m.go")
    assert "d (Flyer) has no action 'FlyByX'" in str(info.value)


def test_a_mission_without_parameters_compiles_as_before() -> None:
    source = "func SEQ_A() {\n\tD1.Arm()\n\tD1.Takeoff(1 + 0.5)\n\tD1.FlyByX(-(2 * 3) / 4)\n}\n"
    compiled = compile_mission(source, "m.go")
    assert _actions(compiled.amt) == [
        ("D1", "Arm", ()),
        ("D1", "Takeoff", (1.5,)),
        ("D1", "FlyByX", (-1.5,)),
    ]
    assert compiled.programs["D1"].libraries == ()
    assert '"libraries"' not in compiled.programs["D1"].to_json()


def test_expansion_stays_within_the_tree_cap() -> None:
    # Five levels of ten calls with different values: 10^5 copies of the leaf.
    levels = []
    for i in range(5):
        calls = "".join(f"\tSEQ_L{i + 1}(d, x + {k})\n" for k in range(10))
        levels.append(f"func SEQ_L{i}(d Quadcopter, x float64) {{\n{calls}}}\n")
    source = (
        "func SEQ_Main() {\n\tSEQ_L0(D1, 0)\n}\n"
        + "".join(levels)
        + "func SEQ_L5(d Quadcopter, x float64) {\n\td.FlyByX(x)\n}\n"
    )
    with pytest.raises(MissionError) as info:
        compile_mission(source, "m.go")
    assert f"more than the limit of {MAX_TREE_NODES:,}".replace(",", " ") in str(info.value)


def test_the_examples_in_the_language_reference_compile() -> None:
    import re

    from .compiler_helpers import REPO

    text = (REPO / "docs" / "mission-language.md").read_text(encoding="utf-8")
    start = text.index("## Blocks with parameters")
    end = text.index("## Lines, columns and limits")
    examples = re.findall(r"```go\n(.*?)```", text[start:end], re.S)
    assert len(examples) == 3
    hop, patrol, inspector = examples
    compile_mission(hop, "hop.go")
    compile_mission(patrol, "patrol.go")
    compiled = compile_mission(inspector + "func SEQ_A() {\n\tD1.Land()\n}\n", "i.go")
    assert compiled.programs["D1"].drone_type == "Inspector"
    # TakePhoto and Gimbal are the camera plugins' actions (installed with the project).
    compile_mission(inspector + "func SEQ_A() {\n\tD1.Gimbal(-30)\n\tD1.TakePhoto()\n}\n")
    with pytest.raises(MissionError, match="no adapter implements action 'Sample' yet"):
        compile_mission(
            inspector.replace("TakePhoto()", "Sample()") + "func SEQ_A() {\n\tD1.Sample()\n}\n"
        )


def test_controls_in_a_block_with_parameters_run_on_the_drone_passed() -> None:
    from eamos.virtual import run_virtual

    source = (
        "var D1 Quadcopter\nvar D2 Quadcopter\n"
        "func SEQ_Main() {\n\tPAR_Both()\n}\n"
        "func PAR_Both() {\n\tSEQ_Climb(D1, 2)\n\tSEQ_Climb(D2, 4)\n}\n"
        "func SEQ_Climb(d Quadcopter, h float64) {\n\td.Arm()\n\td.Takeoff(h)\n"
        "\td.PauseUntil(d.Z() > h - 0.2)\n"
        "\tIf(d.Z() > 3, SEQ_High, SEQ_Low)\n\td.Land()\n}\n"
        "func SEQ_High() {\n\tD2.FlyByX(3)\n}\n"
        "func SEQ_Low() {\n\tD1.FlyByX(1)\n}\n"
    )
    compiled = compile_mission(source, "m.go")
    pauses = [
        (a["drone"], a["cond"])
        for _, a in compiled.amt.nodes(data=True)
        if a["kind"] == "pause_until"
    ]
    assert pauses == [
        ("D1", [">", ["prop", "D1", "Z"], ["-", ["num", 2.0], ["num", 0.2]]]),
        ("D2", [">", ["prop", "D2", "Z"], ["-", ["num", 4.0], ["num", 0.2]]]),
    ]
    run = run_virtual(compiled.programs, time_limit_s=300)
    assert run.ok, run
    assert ("FlyByX", (1.0,), "ok") in run.actions("D1")
    assert ("FlyByX", (3.0,), "ok") in run.actions("D2")
    assert [a for a, _, _ in run.actions("D1")].count("FlyByX") == 1


def test_the_parameter_count_is_capped() -> None:
    from eamos.compiler.limits import MAX_PARAMS

    names = [f"p{i}" for i in range(MAX_PARAMS + 1)]
    source = (
        "func SEQ_Main() {\n\tSEQ_X(" + ", ".join("1" for _ in names) + ")\n}\n"
        "func SEQ_X(" + ", ".join(f"{n} float64" for n in names) + ") {\n\tD1.Arm()\n}\n"
    )
    with pytest.raises(MissionError) as info:
        compile_mission(source, "m.go")
    first = info.value.diagnostics[0]
    assert first.message == f"block 'SEQ_X' has more than {MAX_PARAMS} parameters"
    assert first.loc.line == 4
    compile_mission(source.replace(", 1)", ")").replace(f", p{MAX_PARAMS} float64", ""))


def test_a_drone_whose_type_has_actions_no_adapter_runs_is_warned_of() -> None:
    source = (
        "type Inspector interface {\n\tQuadcopter\n\tWinch(length_m float64)\n\tSample()\n}\n"
        "var D1 Inspector\nfunc SEQ_A() {\n\tD1.Arm()\n}\n"
    )
    compiled = compile_mission(source, "m.go")
    [warning] = [w for w in compiled.warnings if "no adapter" in w.message]
    assert f"{warning.loc}" == "6:8"
    assert warning.message == (
        "D1's type Inspector has actions no adapter implements yet: Sample, Winch"
    )


def test_a_body_with_arguments_and_a_count_from_a_parameter() -> None:
    source = (
        "func SEQ_Main() {\n\tD1.Arm()\n\tSEQ_Laps(D1, 3, 2)\n}\n"
        "func SEQ_Laps(d Quadcopter, laps float64, x float64) {\n"
        "\tRepeatFor(laps, SEQ_Lap(d, x * 2))\n}\n"
        "func SEQ_Lap(d Quadcopter, x float64) {\n\td.FlyByX(x)\n\td.FlyByX(-x)\n}\n"
    )
    amt = compile_mission(source, "m.go").amt
    loop = next(n for n, a in amt.nodes(data=True) if a["kind"] == "repeat_for")
    assert amt.nodes[loop]["count"] == 3
    assert amt.nodes[loop]["drone"] == "D1"
    [body] = list(amt.successors(loop))
    assert amt.nodes[body]["label"] == "SEQ_Lap(D1, 4)"
    assert [amt.nodes[n]["label"] for n in amt.successors(body)] == ["FlyByX(4)", "FlyByX(-4)"]
    with pytest.raises(MissionError) as info:
        compile_mission(source.replace("SEQ_Laps(D1, 3, 2)", "SEQ_Laps(D1, 2.5, 2)"), "m.go")
    [error] = info.value.diagnostics
    assert (f"{error.loc}", error.hint) == ("6:12", "in SEQ_Laps(D1, 2.5, 2)")
    assert "RepeatFor repeats a whole number of times" in error.message
    with pytest.raises(MissionError, match="SEQ_Lap takes 2 arguments, got 1"):
        compile_mission(source.replace("SEQ_Lap(d, x * 2)", "SEQ_Lap(d)"), "m.go")
    with pytest.raises(MissionError, match="unknown name 'lap'"):
        compile_mission(source.replace("RepeatFor(laps,", "RepeatFor(lap,"), "m.go")
