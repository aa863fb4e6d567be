"""Groups of drones, loops and group conditions: the same graphs as the mission written out.

A group ``var D [N]Quadcopter`` and ``for`` loops expand at compile time into the
mission tree, execution graph, dependency graphs and programs of the mission written
out by hand (the relay mission ``scripts/bench_scale.py`` generates, compared node by
node with every attribute but where each node was written).
"""

from __future__ import annotations

import importlib.util
import re
from dataclasses import dataclass
from types import ModuleType

import pytest

from eamos.compiler import MissionError, compile_mission
from eamos.program.conditions import evaluate

from .compiler_helpers import REPO, program_semantics, semantics

#: scripts/bench_scale.py's relay, written with a group: D[0] is the script's D1.
RELAY = """\
package relay

var D [{n}]Quadcopter

func SEQ_Relay() {{
	SEQ_Up()
	PAR_Squares()
	SEQ_Down()
}}

func SEQ_Up() {{
	for _, d := range D {{
		d.Arm()
		d.Takeoff(1.5)
	}}
}}

func PAR_Squares() {{
	for _, d := range D {{
		d.FlyByX(1)
		d.FlyByY(1)
		d.FlyByX(-1)
		d.FlyByY(-1)
	}}
}}

func SEQ_Down() {{
	for i := len(D) - 1; i >= 0; i-- {{
		D[i].Land()
		D[i].Disarm()
	}}
}}
"""


def _bench_scale() -> ModuleType:
    path = REPO / "scripts" / "bench_scale.py"
    spec = importlib.util.spec_from_file_location("bench_scale_relay", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _renamed(text: str) -> str:
    """The script's drone names D1 .. DN as the group's members D_0 .. D_(N-1)."""
    return re.sub(r"\bD(\d+)\b", lambda m: f"D_{int(m.group(1)) - 1}", text)


def assert_same_compilation(by_hand: str, grouped: str, rename=_renamed) -> None:  # type: ignore[no-untyped-def]
    """The two missions compile to the same graphs and programs (up to ``rename``)."""
    a = compile_mission(by_hand, "by_hand.go")
    b = compile_mission(grouped, "grouped.go")
    assert semantics(a.amt, rename) == semantics(b.amt)
    assert semantics(a.meg, rename) == semantics(b.meg)
    assert sorted(rename(d) for d in a.mdgs) == sorted(b.mdgs)
    for drone, mdg in a.mdgs.items():
        assert semantics(mdg, rename) == semantics(b.mdgs[rename(drone)]), drone
    for drone, program in a.programs.items():
        assert program_semantics(program, rename) == program_semantics(b.programs[rename(drone)]), (
            drone
        )
    assert [w.message for w in a.warnings] == [w.message for w in b.warnings]


@pytest.mark.parametrize("drones", [3, 12, 100])
def test_the_relay_with_a_group_compiles_to_the_generated_relays_graphs(drones: int) -> None:
    by_hand = _bench_scale().relay_mission(drones)
    assert_same_compilation(by_hand, RELAY.format(n=drones))


def test_members_are_named_group_index_and_the_fleet_is_in_index_order() -> None:
    compiled = compile_mission(RELAY.format(n=12), "relay.go")
    fleet = compiled.programs["D_0"].fleet
    assert fleet == ("GCS", *(f"D_{i}" for i in range(12)))
    assert compiled.programs["D_11"].drone_type == "Quadcopter"


def test_a_different_mission_is_told_apart() -> None:
    # Landing in the declared order instead of the reverse: the comparison must see it.
    forward = RELAY.format(n=4).replace("i := len(D) - 1; i >= 0; i--", "i := 0; i < len(D); i++")
    with pytest.raises(AssertionError):
        assert_same_compilation(_bench_scale().relay_mission(4), forward)


# -- errors, located through the expansion -------------------------------------------------


@dataclass(frozen=True)
class Bad:
    name: str
    source: str
    where: str  # "line:col" of the first error
    message: str  # substring of its message
    hint: str = ""  # substring of its hint


TEAM = "var Team [4]Quadcopter\n"
LAND = "func SEQ_B() {\n\tTeam[0].Land()\n}\n"

CASES = [
    Bad(
        "index out of range in one iteration",
        TEAM + "func SEQ_A() {\n\tfor i := 0; i < 4; i++ {\n\t\tTeam[i+1].Arm()\n\t}\n}\n",
        "4:3",
        "index 4 is outside Team, whose members are Team[0] .. Team[3]",
        "in iteration i=3",
    ),
    Bad(
        "a folded argument out of range, once for all the iterations",
        TEAM + "func SEQ_A() {\n\tfor i, d := range Team {\n\t\td.Takeoff(1 - i)\n\t}\n}\n",
        "4:13",
        "Takeoff's height_m must be positive, got 0",
        "in iteration i=1 (and 2 more times in other iterations)",
    ),
    Bad(
        "nested loops name both iterations",
        TEAM + "func SEQ_A() {\n\tfor r := range 2 {\n\t\tfor c := range 3 {\n"
        "\t\t\tTeam[2*r+c].Arm()\n\t\t}\n\t}\n}\n",
        "5:4",
        "index 4 is outside Team",
        "in iteration r=1, c=2",
    ),
    Bad(
        "an error in a block copy's loop names the copy and the iteration",
        TEAM + "func SEQ_A() {\n\tSEQ_H(Team, 2)\n}\n"
        "func SEQ_H(g []Quadcopter, h float64) {\n\tfor i := range len(g) {\n"
        "\t\tg[i].Takeoff(h - i)\n\t}\n}\n",
        "7:16",
        "Takeoff's height_m must be positive, got 0",
        "in SEQ_H(Team, 2), iteration i=2",
    ),
    Bad(
        "a constant index out of range",
        TEAM + "func SEQ_A() {\n\tTeam[4].Arm()\n}\n",
        "3:7",
        "index 4 is outside Team",
    ),
    Bad(
        "a slice out of range",
        TEAM + 'import "fleet"\nfunc SEQ_A() {\n\tfor k := range 2 {\n'
        "\t\tfleet.PAR_Land(Team[3*k : 3*k+3])\n\t}\n}\n",
        "5:18",
        "Team[3:6] is not a part of Team",
        "in iteration k=1",
    ),
    Bad(
        "a group given an action",
        TEAM + "func SEQ_A() {\n\tTeam.Arm()\n}\n",
        "3:2",
        "'Team' is a group of drones, not one drone",
        "for _, d := range Team",
    ),
    Bad(
        "a member's file name in the mission",
        TEAM + "func SEQ_A() {\n\tTeam[0].Arm()\n\tTeam_3.Arm()\n}\n",
        "4:2",
        "'Team_3' is the file name of Team[3]: in the mission, write Team[3]",
    ),
    Bad(
        "a drone named like a member",
        TEAM + "var Team_2 Quadcopter\nfunc SEQ_A() {\n\tTeam[0].Arm()\n\tTeam_2.Arm()\n}\n",
        "2:5",
        "drone 'Team_2' has the name of Team[2], a member of a group",
    ),
    Bad(
        "a group too large",
        "var Team [1001]Quadcopter\nfunc SEQ_A() {\n\tTeam[0].Arm()\n}\n",
        "1:11",
        "a group has 1 to 1000 drones, not 1001",
    ),
    Bad(
        "groups over the drone limit together",
        "var A [600]Quadcopter\nvar B [600]Quadcopter\nfunc SEQ_A() {\n\tA[0].Arm()\n"
        "\tB[0].Arm()\n}\n",
        "2:5",
        "more than 1 000 drones; group 'B' (600) crosses the limit",
    ),
    Bad(
        "a loop that never ends",
        TEAM + "func SEQ_A() {\n\tfor i := 0; i < 4; i-- {\n\t\tTeam[i].Arm()\n\t}\n}\n",
        "3:18",
        "this loop never ends: its counter moves away from 4 (from 0, step -1)",
    ),
    Bad(
        "loops over the tree's cap",
        TEAM + "func SEQ_A() {\n\tfor i := range 100000 {\n\t\tTeam[i % 4].Arm()\n\t}\n}\n",
        "3:2",
        "the loops run more than 50 000 iterations",
    ),
    Bad(
        "nested loops over the tree's cap, refused before they are written out",
        TEAM + "func SEQ_A() {\n\tfor i := range 40000 {\n\t\tfor j := range 40000 {\n"
        "\t\t\tTeam[(i + j) % 4].Arm()\n\t\t}\n\t}\n}\n",
        "4:3",
        "the loops run more than 50 000 iterations",
    ),
    Bad(
        "the index of a range used as a drone",
        TEAM + "func SEQ_A() {\n\tfor d := range Team {\n\t\td.Arm()\n\t}\n}\n",
        "4:3",
        "'d' is a number, not a drone",
        "for _, d := range ... gives the members",
    ),
    Bad(
        "a group read as one drone in a condition",
        TEAM + "func SEQ_A() {\n\tTeam[0].Arm()\n\tWaitUntil(Team.Z() > 2, SEQ_B)\n}\n" + LAND,
        "4:12",
        "'Team' is a group of drones, not one drone",
        "All(Team.Z() > 2)",
    ),
    Bad(
        "a group condition reading no group",
        TEAM
        + "func SEQ_A() {\n\tTeam[0].Arm()\n\tWaitUntil(All(Team[0].Z() > 2), SEQ_B)\n}\n"
        + LAND,
        "4:12",
        "All(...) reads one group, as if it were a drone",
        "Team.Z() stands for each member's Z()",
    ),
    Bad(
        "a group condition reading two groups",
        TEAM + "var Pair [2]Quadcopter\nfunc SEQ_A() {\n\tTeam[0].Arm()\n\tPair[0].Arm()\n"
        "\tWaitUntil(Any(Team.Z() > Pair.Z()), SEQ_B)\n}\n" + LAND,
        "6:12",
        "this one reads Team, Pair",
    ),
    Bad(
        "a group condition inside another",
        TEAM + "func SEQ_A() {\n\tTeam[0].Arm()\n"
        "\tWaitUntil(All(Team.Z() > 2 && Any(Team.Z() > 3)), SEQ_B)\n}\n" + LAND,
        "4:32",
        "Any(...) inside another group condition",
    ),
    Bad(
        "Count compares a number",
        TEAM
        + "func SEQ_A() {\n\tTeam[0].Arm()\n\tWaitUntil(Count(Team.Z()) > 2, SEQ_B)\n}\n"
        + LAND,
        "4:18",
        "Count(...) takes a condition (true/false), not a number",
    ),
    Bad(
        "% on decimals",
        TEAM + "func SEQ_A() {\n\tfor i := range 4 {\n\t\tTeam[i].Takeoff(2.5 % 2)\n\t}\n}\n",
        "4:19",
        "'%' takes whole numbers, got 2.5 % 2",
        "% gives the remainder of whole numbers",
    ),
    Bad(
        "% on a property",
        TEAM
        + "func SEQ_A() {\n\tTeam[0].Arm()\n\tWaitUntil(Team[0].Z() % 2 > 1, SEQ_B)\n}\n"
        + LAND,
        "4:24",
        "'%' is computed when the mission is compiled",
    ),
    Bad(
        "a loop variable named like a drone",
        TEAM + "var D1 Quadcopter\nfunc SEQ_A() {\n\tD1.Arm()\n\tfor _, D1 := range Team {\n"
        "\t\tD1.Arm()\n\t}\n}\n",
        "5:9",
        "'D1' is the name of a drone of the mission",
    ),
    Bad(
        "a loop variable hiding another",
        TEAM + "func SEQ_A() {\n\tfor i := range 2 {\n\t\tfor i := range 2 {\n"
        "\t\t\tTeam[i].Arm()\n\t\t}\n\t}\n}\n",
        "4:7",
        "'i' is already a parameter or a loop variable here",
    ),
    Bad(
        "Whenever in a loop",
        TEAM + "func SEQ_A() {\n\tfor _, d := range Team {\n\t\tWhenever(d.Z() > 5, SEQ_B)\n"
        "\t\td.Arm()\n\t}\n}\n" + LAND,
        "4:3",
        "Whenever in a for loop",
    ),
    Bad(
        "a for loop that assigns instead of declaring",
        TEAM + "func SEQ_A() {\n\tfor i = 0; i < 4; i++ {\n\t\tTeam[i].Arm()\n\t}\n}\n",
        "3:6",
        "a loop starts by declaring its counter",
        "i := 0",
    ),
    Bad(
        "an empty loop",
        TEAM + "func SEQ_A() {\n\tTeam[0].Arm()\n\tfor range 3 {\n\t}\n}\n",
        "4:2",
        "this for loop is empty",
    ),
    Bad(
        "a drone for a group parameter",
        TEAM + 'import "fleet"\nvar D1 Quadcopter\nfunc SEQ_A() {\n\tfleet.PAR_TakeOff(D1, 2)\n}\n',
        "5:20",
        "fleet.PAR_TakeOff's parameter 'g' is a group ([]fleet.Flyer)",
        "pass a group by its name",
    ),
    Bad(
        "a group for a drone parameter",
        TEAM + 'import "fleet"\nfunc SEQ_A() {\n\tfleet.SEQ_Up(Team, 2)\n}\n',
        "4:15",
        "'Team' is a group; fleet.SEQ_Up's parameter 'd' is one drone",
        "Team[i]",
    ),
    Bad(
        "members whose type does not satisfy the group parameter's",
        "var Cams [2]DroneType1\nfunc SEQ_A() {\n\tPAR_Cam(Cams)\n}\n"
        "func PAR_Cam(g []DroneType2) {\n\tfor _, d := range g {\n\t\td.TurnOnCamera()\n\t}\n}\n",
        "3:10",
        "Cams's members (DroneType1) are not DroneType2: they have no AdjustCamera",
    ),
    Bad(
        "a decimal for an int parameter",
        TEAM + "func SEQ_A() {\n\tSEQ_Row(1.5)\n}\nfunc SEQ_Row(r int) {\n\tTeam[r].Arm()\n}\n",
        "3:10",
        "parameter 'r' (int) is a whole number, got 1.5",
    ),
    Bad(
        "5 000 nested loops: refused at the eleventh, without recursing further",
        TEAM
        + "func SEQ_A() {\n"
        + "for range 1 {\n" * 5000
        + "Team[0].Arm()\n"
        + "}\n" * 5000
        + "}\n",
        "13:1",
        "loops nest more than 10 deep",
    ),
    Bad(
        "a decimal step that would run forever",
        TEAM + "func SEQ_A() {\n\tfor x := 0; x < 10; x += 0.0000001 {\n"
        "\t\tTeam[0].FlyByX(x)\n\t}\n}\n",
        "3:2",
        "the loops run more than 50 000 iterations",
    ),
    Bad(
        "a group of no drone",
        "var Team [0]Quadcopter\nfunc SEQ_A() {\n\tD1.Arm()\n}\n",
        "1:11",
        "a group has 1 to 1000 drones, not 0",
    ),
    Bad(
        "a group's size from a name",
        "var Team [n]Quadcopter\nfunc SEQ_A() {\n\tD1.Arm()\n}\n",
        "1:11",
        "a group's size is a number written in the declaration",
    ),
    Bad(
        "an index of a member",
        TEAM + "func SEQ_A() {\n\tTeam[0][1].Arm()\n}\n",
        "3:2",
        "only a group's name is indexed",
    ),
    Bad(
        "a member as an index",
        TEAM + "func SEQ_A() {\n\tTeam[Team[0]].Arm()\n}\n",
        "3:7",
        "'Team[...]' is a drone, not a number",
        "indices are numbers",
    ),
    Bad(
        "a range over a drone",
        "var D1 Quadcopter\nfunc SEQ_A() {\n\tfor _, d := range D1 {\n\t\td.Arm()\n\t}\n}\n",
        "3:20",
        "'D1' is not a group of drones",
    ),
    Bad(
        "an array parameter instead of a group's",
        "func SEQ_A() {\n\tD1.Arm()\n}\nfunc SEQ_B(g [3]Quadcopter) {\n\tg[0].Arm()\n}\n",
        "4:14",
        "a type is a plain name, or a group's: []Name",
        "[]Quadcopter for a group",
    ),
    Bad(
        "a group loop on an unknown group",
        TEAM + "func SEQ_A() {\n\tfor _, d := range Tam {\n\t\td.Arm()\n\t}\n}\n",
        "3:20",
        "'Tam' is not a group of drones",
        "did you mean Team?",
    ),
]


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_error_location_message_and_hint(case: Bad) -> None:
    with pytest.raises(MissionError) as info:
        compile_mission(case.source, "m.go")
    first = next(d for d in info.value.diagnostics if d.severity == "error")
    assert f"{first.loc.line}:{first.loc.col}" == case.where, first
    assert case.message in first.message, first
    assert case.hint in first.hint, first


# -- what the loops expand to --------------------------------------------------------------


def _children(compiled, label: str) -> list[str]:  # type: ignore[no-untyped-def]
    """The labels (with drones) under the one seq/par node labelled ``label``, in order."""
    amt = compiled.amt
    (node,) = [n for n, a in amt.nodes(data=True) if a["label"] == label]
    kids = sorted(amt.successors(node), key=lambda k: amt.edges[node, k].get("order", 0))
    return [
        f"{amt.nodes[k]['label']}@{amt.nodes[k]['drone']}" if amt.nodes[k]["drone"] else
        amt.nodes[k]["label"]
        for k in kids
    ]  # fmt: skip


def test_a_loop_in_a_par_block_makes_one_branch_per_iteration() -> None:
    source = TEAM.replace("4", "3") + (
        "func SEQ_A() {\n\tPAR_Up()\n\tPAR_Go()\n}\n"
        "func PAR_Up() {\n\tfor _, d := range Team {\n\t\td.Arm()\n\t}\n}\n"
        "func PAR_Go() {\n\tfor i, d := range Team {\n\t\td.Takeoff(2 + i)\n\t\td.Land()\n\t}\n}\n"
    )
    compiled = compile_mission(source, "m.go")
    # One statement per iteration: the statements themselves are the branches.
    assert _children(compiled, "PAR_Up") == ["Arm()@Team_0", "Arm()@Team_1", "Arm()@Team_2"]
    # Several: a SEQ block per iteration, named after the loop's variable.
    assert _children(compiled, "PAR_Go") == ["PAR_Go[i=0]", "PAR_Go[i=1]", "PAR_Go[i=2]"]
    assert _children(compiled, "PAR_Go[i=2]") == ["Takeoff(4)@Team_2", "Land()@Team_2"]
    kinds = {a["label"]: a["kind"] for _, a in compiled.amt.nodes(data=True)}
    assert kinds["PAR_Go"] == "par" and kinds["PAR_Go[i=1]"] == "seq"


def test_a_loop_in_a_seq_block_runs_its_iterations_in_order() -> None:
    source = TEAM.replace("4", "2") + (
        "func SEQ_A() {\n\tTeam[1].Arm()\n\tfor i := range 2 {\n\t\tTeam[i].Takeoff(1 + i)\n"
        "\t\tfor _, d := range Team {\n\t\t\td.FlyByX(i)\n\t\t}\n\t}\n}\n"
    )
    compiled = compile_mission(source, "m.go")
    assert _children(compiled, "SEQ_A") == [
        "Arm()@Team_1",
        "Takeoff(1)@Team_0",
        "FlyByX(0)@Team_0",
        "FlyByX(0)@Team_1",
        "Takeoff(2)@Team_1",
        "FlyByX(1)@Team_0",
        "FlyByX(1)@Team_1",
    ]
    # Each expanded node points at its statement in the loop.
    lines = {(a["label"], a["drone"]): a["line"] for _, a in compiled.amt.nodes(data=True)}
    assert lines["FlyByX(1)", "Team_1"] == 7 and lines["Takeoff(2)", "Team_1"] == 5


@pytest.mark.parametrize(
    ("argument", "values"),
    [
        ("i / 2", [0, 0, 1, 1, 2]),  # whole numbers divide as in Go
        ("i % 3", [0, 1, 2, 0, 1]),
        ("2.5 * i", [0, 2.5, 5, 7.5, 10]),  # a decimal makes it decimal
        ("i / 2.0", [0, 0.5, 1, 1.5, 2]),
        ("(i - 4) / 3", [-1, -1, -0, -0, 0]),  # truncated toward zero
        ("(i - 4) % 3", [-1, -0, -2, -1, 0]),  # the left side's sign
        ("7 / 2 + i", [3.5, 4.5, 5.5, 6.5, 7.5]),  # literals alone: decimal, as before
        ("len(Team) - i", [5, 4, 3, 2, 1]),
        ("len(Team[1:3]) * i", [0, 2, 4, 6, 8]),
    ],
)
def test_arithmetic_on_loop_counters(argument: str, values: list[float]) -> None:
    source = (
        "var Team [5]Quadcopter\nfunc SEQ_A() {\n"
        f"\tfor i, d := range Team {{\n\t\td.FlyByX({argument})\n\t}}\n}}\n"
    )
    compiled = compile_mission(source, "m.go")
    got = [
        a["args"][0]
        for _, a in sorted(compiled.amt.nodes(data=True), key=lambda na: na[1]["drone"])
        if a["kind"] == "action"
    ]
    assert got == values


def test_counting_loops_of_every_form() -> None:
    source = TEAM + (
        "func SEQ_A() {\n"
        "\tfor i := 3; i >= 0; i -= 2 {\n\t\tTeam[i].Arm()\n\t}\n"
        "\tfor i := 0; i != 4; i += 2 {\n\t\tTeam[i].Takeoff(1)\n\t}\n"
        "\tfor i := 0.5; i < 2; i++ {\n\t\tTeam[0].FlyByX(i)\n\t}\n"
        "\tfor range 2 {\n\t\tTeam[1].FlyByY(1)\n\t}\n"
        "\tfor i := range len(Team) - 3 {\n\t\tTeam[i].Land()\n\t}\n}\n"
    )
    compiled = compile_mission(source, "m.go")
    assert _children(compiled, "SEQ_A") == [
        "Arm()@Team_3",
        "Arm()@Team_1",
        "Takeoff(1)@Team_0",
        "Takeoff(1)@Team_2",
        "FlyByX(0.5)@Team_0",
        "FlyByX(1.5)@Team_0",
        "FlyByY(1)@Team_1",
        "FlyByY(1)@Team_1",
        "Land()@Team_0",
    ]


def test_group_conditions_are_one_condition_over_the_members() -> None:
    source = TEAM + (
        "func SEQ_A() {\n\tTeam[0].Arm()\n"
        "\tWaitUntil(All(Team.Z() > 2) && Count(Team[1:4].Battery() < 20) >= 2, SEQ_B)\n"
        "\tTeam[0].PauseUntil(Any(Team[2:4].X() > Team[0].X() + 1))\n}\n" + LAND
    )
    compiled = compile_mission(source, "m.go")
    labels = {a["label"]: a for _, a in compiled.amt.nodes(data=True) if "cond" in a}
    wait = labels["WaitUntil All(Team.Z() > 2) && Count(Team[1:4].Battery() < 20) >= 2"]
    pause = labels["PauseUntil Any(Team[2:4].X() > Team_0.X() + 1)"]
    assert pause["drone"] == "Team_0"

    def holds(cond: list, values: dict[tuple[str, str], float]) -> bool:  # type: ignore[type-arg]
        return bool(evaluate(cond, lambda d, p: values.get((d, p))))

    high = {(f"Team_{i}", "Z"): 3.0 for i in range(4)}
    low = {(f"Team_{i}", "Battery"): 10.0 for i in (1, 2)} | {("Team_3", "Battery"): 90.0}
    assert holds(wait["cond"], high | low)
    assert not holds(wait["cond"], high | low | {("Team_2", "Battery"): 90.0})  # one low
    assert not holds(wait["cond"], high | low | {("Team_3", "Z"): 1.0})
    x = {("Team_0", "X"): 0.0, ("Team_2", "X"): 0.5, ("Team_3", "X"): 1.5}
    assert holds(pause["cond"], x)
    assert not holds(pause["cond"], x | {("Team_3", "X"): 1.0})


def test_a_group_condition_over_many_drones_nests_shallow() -> None:
    source = (
        "var Team [1000]Quadcopter\nfunc SEQ_A() {\n\tTeam[0].Arm()\n"
        "\tWaitUntil(All(Team.Z() > 2), SEQ_B)\n}\n" + LAND
    )
    compiled = compile_mission(source, "m.go")
    (cond,) = [a["cond"] for _, a in compiled.amt.nodes(data=True) if "cond" in a]

    def depth(c: list) -> int:  # type: ignore[type-arg]
        return 0 if c[0] in ("num", "bool", "prop") else 1 + max(depth(x) for x in c[1:])

    assert depth(cond) == 11  # ten levels of && and the comparison
    everyone = {(f"Team_{i}", "Z"): 2.5 for i in range(1000)}
    assert evaluate(cond, lambda d, p: everyone.get((d, p))) is True


def test_the_fleet_helpers_take_a_group_as_the_numbered_ones_took_drones() -> None:
    by_hand = (
        'import "fleet"\nvar D1 Quadcopter\nvar D2 Quadcopter\nvar D3 Quadcopter\n'
        "var D4 Quadcopter\nfunc SEQ_A() {\n\tfleet.PAR_TakeOff4(D1, D2, D3, D4, 2)\n"
        "\tfleet.PAR_Land2(D1, D2)\n\tfleet.PAR_Land2(D3, D4)\n}\n"
    )
    grouped = (
        'import "fleet"\nvar D [4]Quadcopter\nfunc SEQ_A() {\n\tfleet.PAR_TakeOff(D, 2)\n'
        "\tfor half := range 2 {\n\t\tPAR_Down(D[2*half : 2*half+2])\n\t}\n}\n"
        "func PAR_Down(g []Quadcopter) {\n\tfor _, d := range g {\n\t\tfleet.SEQ_Down(d)\n"
        "\t}\n}\n"
    )
    assert_same_compilation(by_hand, grouped)


def test_a_group_parameter_passes_a_part_on_and_keeps_the_members_names() -> None:
    source = TEAM + (
        "func SEQ_A() {\n\tPAR_Half(Team[2:])\n\tPAR_Half(Team[:2])\n}\n"
        "func PAR_Half(g []Quadcopter) {\n\tSEQ_One(g[1:], len(g))\n\tg[0].Arm()\n}\n"
        "func SEQ_One(h []Quadcopter, n int) {\n\th[0].Takeoff(n)\n}\n"
    )
    compiled = compile_mission(source, "m.go")
    assert _children(compiled, "SEQ_A") == ["PAR_Half(Team[2:4])", "PAR_Half(Team[0:2])"]
    assert _children(compiled, "PAR_Half(Team[2:4])") == ["SEQ_One(Team[3:4], 2)", "Arm()@Team_2"]
    assert _children(compiled, "SEQ_One(Team[1:2], 2)") == ["Takeoff(2)@Team_1"]


def test_the_expanded_size_limit_counts_the_written_out_mission() -> None:
    # 1 000 members x 60 actions: each block is small, the tree they write is not.
    source = (
        "var Team [1000]Quadcopter\nfunc SEQ_A() {\n\tfor _, d := range Team {\n\t\tSEQ_Hop(d)\n"
        "\t}\n}\nfunc SEQ_Hop(d Quadcopter) {\n"
        + "".join("\td.FlyByX(1)\n" for _ in range(60))
        + "}\n"
    )
    with pytest.raises(MissionError) as info:
        compile_mission(source, "m.go")
    (error,) = info.value.diagnostics
    assert error.message == "the loops and block copies write out more than 50 000 statements"
    assert 8 <= error.loc.line <= 67 and error.hint.startswith("loop over fewer drones")
    assert "(in SEQ_Hop(Team_" in error.hint


# -- the 100-drone example in missions/ ----------------------------------------------------

FLEET100 = REPO / "missions" / "fleets" / "fleet100.go"


def fleet100_written_out() -> str:
    """missions/fleet100.go written out by hand, as a script would generate it."""
    team = [f"Team_{i}" for i in range(100)]
    out = ['import "fleet"', *(f"var {d} Quadcopter" for d in team)]
    out += ["func SEQ_Mission() {", "\tPAR_Grid()"]
    out += [f"\t{d}.{move}" for d in team for move in ("FlyByZ(1)", "FlyByZ(-1)")]
    out += ["\tPAR_Sweep1()", "\tPAR_Sweep2()", *(f"\tPAR_Row{r}()" for r in range(10)), "}"]
    out += ["func PAR_Grid() {", *(f"\tSEQ_Cell{i}()" for i in range(100)), "}"]
    for i, d in enumerate(team):
        x = 5 * (i % 10)
        out += [f"func SEQ_Cell{i}() {{", f"\tfleet.SEQ_Up({d}, 3)"]
        out += [f"\t{d}.FlyToXYZ({x}, {-x}, 3)", "}"]
    for k, dx in ((1, 20), (2, -20)):
        out += [f"func PAR_Sweep{k}() {{", *(f"\t{d}.FlyByX({dx})" for d in team), "}"]
    for r in range(10):
        row = team[10 * r : 10 * r + 10]
        out += [f"func PAR_Row{r}() {{", *(f"\tfleet.SEQ_Park({d})" for d in row), "}"]
    return "\n".join(out) + "\n"


def test_the_100_drone_example_is_30_lines_and_compiles_cleanly() -> None:
    text = FLEET100.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 30
    compiled = compile_mission(text, str(FLEET100))
    assert compiled.warnings == ()
    assert len(compiled.programs) == 101
    assert {p.drone_type for d, p in compiled.programs.items() if d != "GCS"} == {"Quadcopter"}


def test_the_100_drone_example_compiles_to_the_graphs_of_the_mission_written_out() -> None:
    text = FLEET100.read_text(encoding="utf-8")
    assert_same_compilation(fleet100_written_out(), text, rename=str)


# -- the language reference ----------------------------------------------------------------


def _groups_section() -> str:
    text = (REPO / "docs" / "mission-language.md").read_text(encoding="utf-8")
    start = text.index("## Groups of drones and loops")
    return text[start : text.index("## Blocks with parameters")]


def test_the_examples_of_the_groups_section_are_missions_that_compile() -> None:
    examples = re.findall(r"```go\n(.*?)```", _groups_section(), re.S)
    assert len(examples) == 3
    for i, example in enumerate(examples):
        compiled = compile_mission(example, str(REPO / "missions" / f"doc{i}.go"))
        assert compiled.warnings == ()
    labels = {a["label"] for _, a in compiled.amt.nodes(data=True)}
    assert {"PAR_Forward(Team[3:6], 5)", "PAR_Up(Team, 2)[d=Team_0]"} <= labels


def test_the_error_example_of_the_groups_section_is_real_output() -> None:
    (shown,) = re.findall(r"```text\n(m\.go:.*?)```", _groups_section(), re.S)
    source = TEAM + "func SEQ_A() {\n\tfor i := 0; i < 4; i++ {\n\t\tTeam[i+1].Arm()\n\t}\n}\n"
    with pytest.raises(MissionError) as info:
        compile_mission(source, "m.go")
    printed = info.value.render("m.go", source)
    assert printed.startswith(shown.rstrip("\n")), printed


def test_two_motions_at_once_in_a_loop_are_one_warning_for_all_the_members() -> None:
    source = TEAM + (
        "func PAR_A() {\n\tfor _, d := range Team {\n\t\td.FlyByX(1)\n\t}\n"
        "\tfor _, d := range Team {\n\t\td.FlyByY(1)\n\t}\n}\n"
    )
    (warning,) = compile_mission(source, "m.go").warnings
    assert (warning.loc.line, warning.loc.col) == (7, 3)
    assert "Team_0.FlyByY runs in PAR_A together with Team_0.FlyByX (line 4)" in warning.message
    assert warning.hint.endswith("(the same for 3 more drones here)")
