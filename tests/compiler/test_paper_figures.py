"""The compiler against the paper: Figures 6, 7 and 8, Listing 4 and Table 7."""

from __future__ import annotations

from typing import Any

import networkx as nx
import pytest

from eamos.compiler import CompiledMission, compile_file, compile_mission

from .compiler_helpers import MISSIONS, named_edges, node_by_label

# -- Figure 6: the Abstract Mission Tree of Listing 1 ----------------------------------


def _shape(amt: nx.DiGraph, node: int) -> tuple[Any, ...]:
    """(kind, label, drone, [children in order]) all the way down."""
    a = amt.nodes[node]
    kids = sorted(amt.out_edges(node, data=True), key=lambda e: e[2].get("order", 0))
    return (a["kind"], a["label"], a["drone"], [_shape(amt, c) for _, c, _ in kids])


def _leaf(label: str, drone: str) -> tuple[Any, ...]:
    return ("action", label, drone, [])


@pytest.fixture(scope="module")
def listing1() -> CompiledMission:
    return compile_file(MISSIONS / "listing01_demo.go")


def test_figure6_amt_of_listing1_node_by_node(listing1: CompiledMission) -> None:
    amt = listing1.amt
    assert amt.graph["root"] == 0
    expected = (
        "init",
        "INIT",
        "GCS",
        [
            (
                "seq",
                "INIT",
                "",
                [
                    (
                        "seq",
                        "SEQ_Start",
                        "",
                        [
                            (
                                "par",
                                "PAR_TurnOn",
                                "",
                                [
                                    _leaf("TurnOn()", "Drone1"),
                                    _leaf("TurnOn()", "Drone2"),
                                    _leaf("TurnOn()", "Drone3"),
                                ],
                            ),
                            (
                                "par",
                                "PAR_PreFlightChecks",
                                "",
                                [
                                    (
                                        "seq",
                                        "SEQ_PreFlight1",
                                        "",
                                        [
                                            _leaf("PreFlightCheck()", "Drone1"),
                                            _leaf("Calibrate()", "Drone1"),
                                        ],
                                    ),
                                    (
                                        "seq",
                                        "SEQ_PreFlight2",
                                        "",
                                        [
                                            _leaf("PreFlightCheck()", "Drone2"),
                                            _leaf("Calibrate()", "Drone2"),
                                        ],
                                    ),
                                ],
                            ),
                            (
                                "seq",
                                "SEQ_ActivateCamera",
                                "",
                                [
                                    _leaf("TurnOnCamera()", "Drone2"),
                                    _leaf("AdjustCamera()", "Drone2"),
                                ],
                            ),
                        ],
                    ),
                ],
            ),
        ],
    )
    assert _shape(amt, 0) == expected
    assert nx.is_tree(amt.to_undirected()) and amt.number_of_nodes() == 17


def test_figure6_seq_children_are_numbered_par_children_are_not(listing1: CompiledMission) -> None:
    amt = listing1.amt
    start = node_by_label(amt, "SEQ_Start")
    orders = sorted(d["order"] for _, _, d in amt.out_edges(start, data=True))
    assert orders == [1, 2, 3]
    turn_on = node_by_label(amt, "PAR_TurnOn")
    assert all("order" not in d for _, _, d in amt.out_edges(turn_on, data=True))


# -- Figure 7: the Mission Execution Graph of Listing 1 -----------------------------------


def test_figure7_meg_of_listing1(listing1: CompiledMission) -> None:
    meg = listing1.meg
    assert {a["kind"] for _, a in meg.nodes(data=True)} == {"init", "fork", "action"}
    assert named_edges(meg) == {
        ("INIT@GCS", "PAR_TurnOn"),
        ("PAR_TurnOn", "TurnOn()@Drone1"),
        ("PAR_TurnOn", "TurnOn()@Drone2"),
        ("PAR_TurnOn", "TurnOn()@Drone3"),
        ("TurnOn()@Drone1", "PAR_PreFlightChecks"),
        ("TurnOn()@Drone2", "PAR_PreFlightChecks"),
        ("TurnOn()@Drone3", "PAR_PreFlightChecks"),
        ("PAR_PreFlightChecks", "PreFlightCheck()@Drone1"),
        ("PAR_PreFlightChecks", "PreFlightCheck()@Drone2"),
        ("PreFlightCheck()@Drone1", "Calibrate()@Drone1"),
        ("PreFlightCheck()@Drone2", "Calibrate()@Drone2"),
        ("Calibrate()@Drone1", "TurnOnCamera()@Drone2"),
        ("Calibrate()@Drone2", "TurnOnCamera()@Drone2"),
        ("TurnOnCamera()@Drone2", "AdjustCamera()@Drone2"),
    }
    assert meg.number_of_nodes() == 12 and meg.number_of_edges() == 14
    dangling = [n for n in meg if meg.out_degree(n) == 0]
    assert dangling == [node_by_label(meg, "AdjustCamera()")]
    # Node ids are the AMT's, so both figures number nodes alike.
    for n, a in meg.nodes(data=True):
        assert listing1.amt.nodes[n]["label"] == a["label"]


# -- Figure 8 and Listing 4: slicing into MDGs ------------------------------------------------

FIGURE8 = """\
// Figure 8 of the paper as a mission: n1 (Drone2) precedes Fork 2, which
// forks into Fork 3 (n5, n6 on Drone1; n7 on Drone2) and Fork 4 (n8, n9 on
// Drone2; n10 on Drone3).
var Drone1 Quadcopter
var Drone2 Quadcopter
var Drone3 Quadcopter

func SEQ_Main() {
	Drone2.Calibrate()
	PAR_Fork2()
}

func PAR_Fork2() {
	PAR_Fork3()
	PAR_Fork4()
}

func PAR_Fork3() {
	Drone1.TurnOn()
	Drone1.Calibrate()
	Drone2.PreFlightCheck()
}

func PAR_Fork4() {
	Drone2.TurnOnCamera()
	Drone2.AdjustCamera()
	Drone3.PreFlightCheck()
}
"""


Figure8 = tuple[CompiledMission, dict[str, str]]
MdgView = tuple[dict[str, tuple[str, bool]], dict[tuple[str, str], bool]]


@pytest.fixture(scope="module")
def figure8() -> Figure8:
    """The compiled mission and the paper's node names -> our MDG keys (mapped by label)."""
    c = compile_mission(FIGURE8, "figure8.go")
    meg = c.meg
    ids = {
        "n0": node_by_label(meg, "INIT"),
        "n1": node_by_label(meg, "Calibrate()", "Drone2"),
        "fork2": node_by_label(meg, "PAR_Fork2"),
        "fork3": node_by_label(meg, "PAR_Fork3"),
        "fork4": node_by_label(meg, "PAR_Fork4"),
        "n5": node_by_label(meg, "TurnOn()", "Drone1"),
        "n6": node_by_label(meg, "Calibrate()", "Drone1"),
        "n7": node_by_label(meg, "PreFlightCheck()", "Drone2"),
        "n8": node_by_label(meg, "TurnOnCamera()", "Drone2"),
        "n9": node_by_label(meg, "AdjustCamera()", "Drone2"),
        "n10": node_by_label(meg, "PreFlightCheck()", "Drone3"),
    }
    keys = {name: f"n{i}" for name, i in ids.items()}
    return c, keys


def test_figure8a_meg(figure8: Figure8) -> None:
    c, k = figure8
    meg_edges = {(f"n{a}", f"n{b}") for a, b in c.meg.edges}
    assert meg_edges == {
        (k["n0"], k["n1"]),
        (k["n1"], k["fork2"]),
        (k["fork2"], k["fork3"]),
        (k["fork2"], k["fork4"]),
        (k["fork3"], k["n5"]),
        (k["fork3"], k["n6"]),
        (k["fork3"], k["n7"]),
        (k["fork4"], k["n8"]),
        (k["fork4"], k["n9"]),
        (k["fork4"], k["n10"]),
    }
    assert list(c.mdgs) == ["GCS", "Drone1", "Drone2", "Drone3"]


def _mdg(c: CompiledMission, drone: str) -> MdgView:
    g = c.mdgs[drone]
    nodes = {n: (a["drone"], a["native"]) for n, a in g.nodes(data=True)}
    arcs = {(a, b): d["external"] for a, b, d in g.edges(data=True)}
    return nodes, arcs


def test_figure8c_mdg_of_drone2_and_listing4(figure8: Figure8) -> None:
    c, k = figure8
    nodes, arcs = _mdg(c, "Drone2")
    f2, f3, f4 = k["fork2"], k["fork3"], k["fork4"]
    assert nodes == {
        k["n0"]: ("GCS", False),  # INITNODE_GCS, a proxy
        k["n1"]: ("Drone2", True),  # n1_Calibrate
        f"{f2}@Drone1": ("Drone1", False),  # n2_FORK_Drone1, a proxy
        f"{f2}@Drone3": ("Drone3", False),  # n2_FORK_Drone3, a proxy
        f"{f2}@Drone2": ("Drone2", True),  # n2_FORK
        f"{f3}@Drone2": ("Drone2", True),  # n3_FORK
        f"{f4}@Drone2": ("Drone2", True),  # n4_FORK
        k["n7"]: ("Drone2", True),
        k["n8"]: ("Drone2", True),
        k["n9"]: ("Drone2", True),
    }
    # Listing 4's predecessor arguments, arc by arc; True marks an external arc.
    assert arcs == {
        (k["n0"], k["n1"]): True,
        (k["n1"], f"{f2}@Drone1"): True,
        (k["n1"], f"{f2}@Drone3"): True,
        (k["n1"], f"{f2}@Drone2"): False,
        (f"{f2}@Drone2", f"{f3}@Drone2"): False,
        (f"{f2}@Drone2", f"{f4}@Drone2"): False,
        (f"{f3}@Drone2", k["n7"]): False,
        (f"{f4}@Drone2", k["n8"]): False,
        (f"{f4}@Drone2", k["n9"]): False,
    }
    # Listing 4 lines 18-19: n1 is attached to both the In- and the Out-Bridge.
    program = c.programs["Drone2"]
    ext_in = {a.dst for a in program.arcs if a.external and program.node(a.dst).native}
    ext_out = {a.src for a in program.arcs if a.external and program.node(a.src).native}
    assert ext_in == {k["n1"]} and ext_out == {k["n1"]}


def test_figure8b_mdg_of_drone1(figure8: Figure8) -> None:
    c, k = figure8
    nodes, arcs = _mdg(c, "Drone1")
    f2, f3 = k["fork2"], k["fork3"]
    assert nodes == {
        k["n1"]: ("Drone2", False),
        f"{f2}@Drone1": ("Drone1", True),
        f"{f3}@Drone1": ("Drone1", True),
        k["n5"]: ("Drone1", True),
        k["n6"]: ("Drone1", True),
    }
    assert arcs == {
        (k["n1"], f"{f2}@Drone1"): True,
        (f"{f2}@Drone1", f"{f3}@Drone1"): False,
        (f"{f3}@Drone1", k["n5"]): False,
        (f"{f3}@Drone1", k["n6"]): False,
    }


def test_figure8d_mdg_of_drone3(figure8: Figure8) -> None:
    c, k = figure8
    nodes, arcs = _mdg(c, "Drone3")
    f2, f4 = k["fork2"], k["fork4"]
    assert nodes == {
        k["n1"]: ("Drone2", False),
        f"{f2}@Drone3": ("Drone3", True),
        f"{f4}@Drone3": ("Drone3", True),
        k["n10"]: ("Drone3", True),
    }
    assert arcs == {
        (k["n1"], f"{f2}@Drone3"): True,
        (f"{f2}@Drone3", f"{f4}@Drone3"): False,
        (f"{f4}@Drone3", k["n10"]): False,
    }


def test_figure8e_mdg_of_the_ground_station(figure8: Figure8) -> None:
    c, k = figure8
    nodes, arcs = _mdg(c, "GCS")
    assert nodes == {k["n0"]: ("GCS", True), k["n1"]: ("Drone2", False)}
    assert arcs == {(k["n0"], k["n1"]): True}


def test_figure8_external_arcs_are_shared_by_sender_and_receiver(figure8: Figure8) -> None:
    c, _ = figure8
    outs: list[tuple[str, str]] = []
    ins: list[tuple[str, str]] = []
    for mdg in c.mdgs.values():
        for a, b, d in mdg.edges(data=True):
            if d["external"]:
                (outs if mdg.nodes[a]["native"] else ins).append((a, b))
    assert sorted(outs) == sorted(ins) and len(outs) == 3


# -- Table 7: external arcs per drone ---------------------------------------------------------


def _table(name: str) -> dict[str, dict[str, int]]:
    return compile_file(MISSIONS / name).stats()["drones"]  # type: ignore[return-value]


def test_table7_experiment_c() -> None:
    drones = _table("experiment_c.go")
    for d in ("Drone1", "Drone2"):
        assert drones[d] == {"nodes": 26, "internal_arcs": 9, "external_in": 8, "external_out": 8}
    assert (drones["Drone3"]["external_in"], drones["Drone3"]["external_out"]) == (15, 12)


def test_table7_experiment_d() -> None:
    drones = _table("experiment_d.go")
    ext = {d: (s["external_in"], s["external_out"]) for d, s in drones.items()}
    assert ext["D1"] == (6, 4)
    assert ext["D2"] == (5, 5)
    assert ext["D3"] == (6, 7)


def test_table7_experiment_a_single_drone() -> None:
    """Experiment A: the only external arc into Drone1 is the ground station's start trigger."""
    drones = _table("experiment_a.go")
    assert (drones["Drone1"]["external_in"], drones["Drone1"]["external_out"]) == (1, 0)
    assert drones["Drone1"]["internal_arcs"] == 7  # 8 actions in a chain
