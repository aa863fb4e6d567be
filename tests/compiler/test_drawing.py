"""Pictures and exports: GraphML, DOT in the paper's visual language, SVG, artifacts."""

from __future__ import annotations

import json
import os
import re
import shutil
import stat
import time
from pathlib import Path

import networkx as nx
import pytest

from eamos.compiler import (
    CompiledMission,
    compile_file,
    render_svg,
    to_dot,
    to_graphml,
    write_artifacts,
)
from eamos.compiler.drawing import builtin_svg, drone_colours, parse_dot
from eamos.program.format import load_program

from .compiler_helpers import MISSIONS, mission_files


@pytest.fixture(scope="module")
def demo() -> CompiledMission:
    return compile_file(MISSIONS / "listing01_demo.go")


@pytest.fixture(scope="module")
def exp_d() -> CompiledMission:
    return compile_file(MISSIONS / "experiment_d.go")


def _node_line(dot: str, key: str) -> str:
    (line,) = [ln for ln in dot.splitlines() if ln.strip().startswith(f'"{key}" [')]
    return line


def _edge_line(dot: str, a: str, b: str) -> str:
    (line,) = [ln for ln in dot.splitlines() if ln.strip().startswith(f'"{a}" -> "{b}"')]
    return line


# -- colours and shapes -------------------------------------------------------------------


def test_palette_follows_the_paper() -> None:
    colours = drone_colours(["Drone3", "Drone1", "GCS", "Drone2", "Drone10"])
    assert colours["GCS"] == "#c8c8c8"  # grey
    assert colours["Drone1"] == "#ffe066"  # yellow
    assert colours["Drone2"] == "#8ce99a"  # green
    assert colours["Drone3"] == "#ff8c69"  # orange-red
    assert colours[""] == "#ffffff"  # not assigned to a drone
    # natural order: Drone10 comes after Drone3
    assert colours["Drone10"] not in {colours["Drone1"], colours["Drone2"], colours["Drone3"]}
    many = drone_colours(f"D{i}" for i in range(1, 31))
    assert len(set(many.values())) == len(many)  # 30 drones, 30 distinct colours


def test_amt_shapes_labels_and_order(demo: CompiledMission) -> None:
    dot = to_dot(demo.amt, "amt")
    assert _node_line(dot, "n0").count("shape=triangle") and "#c8c8c8" in _node_line(dot, "n0")
    assert 'label="n0 INIT\\nGCS"' in _node_line(dot, "n0")
    start = _node_line(dot, "n2")  # SEQ_Start
    assert "shape=box" in start and '"#ffffff"' in start and "SEQ_Start" in start
    assert "shape=diamond" in _node_line(dot, "n3")  # PAR_TurnOn
    turn_on = _node_line(dot, "n4")
    assert "shape=ellipse" in turn_on and 'label="n4 TurnOn()\\nDrone1"' in turn_on
    assert '"#ffe066"' in turn_on
    assert 'label="1"' in _edge_line(dot, "n2", "n3")  # seq order labels
    assert 'label="3"' in _edge_line(dot, "n2", "n14")
    assert "label" not in _edge_line(dot, "n3", "n4")  # no order under a fork


def test_meg_loops_controls_and_ends(exp_d: CompiledMission) -> None:
    dot = to_dot(exp_d.meg, "meg")
    meg = exp_d.meg
    loop = next(n for n, a in meg.nodes(data=True) if a["kind"] == "repeat_while")
    end = meg.nodes[loop]["end"]
    assert "shape=cds" in _node_line(dot, f"n{loop}")
    assert "shape=larrow" in _node_line(dot, f"n{end}")
    back = next((a, b) for a, b, d in meg.edges(data=True) if d["kind"] == "loop")
    line = _edge_line(dot, f"n{back[0]}", f"n{back[1]}")
    assert 'style="dotted"' in line and 'label="loop"' in line
    body = next((a, b) for a, b, d in meg.edges(data=True) if d["kind"] == "body")
    assert 'label="body"' in _edge_line(dot, f"n{body[0]}", f"n{body[1]}")
    exits = [(a, b) for a, b, d in meg.edges(data=True) if d["kind"] == "exit"]
    assert all('label="exit"' in _edge_line(dot, f"n{a}", f"n{b}") for a, b in exits)
    assert "dashed" not in dot  # a MEG has no external arcs


def test_mdg_proxies_and_external_arcs_are_dashed(demo: CompiledMission) -> None:
    mdg = demo.mdgs["Drone2"]
    dot = to_dot(mdg, "mdg", fleet=list(demo.programs))
    for key, a in mdg.nodes(data=True):
        line = _node_line(dot, key)
        assert ("dashed" in line) == (not a["native"])
        if a["kind"] == "fork":
            assert "shape=diamond" in line and drone_colours(demo.programs)[a["drone"]] in line
    for a, b, d in mdg.edges(data=True):
        assert ('style="dashed"' in _edge_line(dot, a, b)) == d["external"]
    assert "Mission Dependency Graph of Drone2" in dot


def test_the_if_branches_are_labelled() -> None:
    c = compile_file(MISSIONS / "inspection_if.go")
    dot = to_dot(c.meg, "meg")
    assert 'label="then"' in dot and 'label="else"' in dot


def test_dot_is_deterministic_and_independent_of_insertion_order(exp_d: CompiledMission) -> None:
    first = to_dot(exp_d.meg, "meg")
    assert to_dot(exp_d.meg, "meg") == first
    shuffled = nx.DiGraph(**exp_d.meg.graph)
    shuffled.add_nodes_from(reversed(list(exp_d.meg.nodes(data=True))))
    shuffled.add_edges_from(reversed(list(exp_d.meg.edges(data=True))))
    assert to_dot(shuffled, "meg") == first
    assert compile_file(MISSIONS / "experiment_d.go").meg is not exp_d.meg
    assert to_dot(compile_file(MISSIONS / "experiment_d.go").meg, "meg") == first


def test_dot_escapes_quotes_and_backslashes() -> None:
    g = nx.DiGraph()
    g.add_node(1, kind="action", drone="D1", label='say "hi" \\ bye')
    dot = to_dot(g, "meg")
    assert 'label="n1 say \\"hi\\" \\\\ bye\\nD1"' in dot
    assert parse_dot(dot).nodes["n1"]["label"] == 'n1 say "hi" \\ bye\nD1'


def test_to_dot_rejects_an_unknown_graph_kind(demo: CompiledMission) -> None:
    with pytest.raises(ValueError, match="which"):
        to_dot(demo.meg, "tree")  # type: ignore[arg-type]


# -- GraphML ------------------------------------------------------------------------------------


@pytest.mark.parametrize("path", mission_files(), ids=lambda p: p.name)
def test_every_graph_exports_to_graphml(path: Path, tmp_path: Path) -> None:
    c = compile_file(path)
    graphs = {"amt": c.amt, "meg": c.meg, **{f"mdg_{d}": g for d, g in c.mdgs.items()}}
    for name, graph in graphs.items():
        out = to_graphml(graph, tmp_path / f"{name}.graphml")
        back = nx.read_graphml(out)
        assert set(back.nodes) == {str(n) for n in graph.nodes}  # ids and keys kept
        assert back.number_of_edges() == graph.number_of_edges()
    meg = nx.read_graphml(tmp_path / "meg.graphml")
    for n, a in c.meg.nodes(data=True):
        if "args" in a:
            assert json.loads(meg.nodes[str(n)]["args"]) == list(a["args"])
        if "cond" in a:
            assert json.loads(meg.nodes[str(n)]["cond"]) == a["cond"]


def test_graphml_handles_none_and_mixed_types(tmp_path: Path) -> None:
    g = nx.DiGraph(note=None, ids=(1, 2))
    g.add_node("a", v=1, w=None, t=("x",))
    g.add_node("b", v=2.5, w="text", t=[1, 2])
    g.add_node("c", v="three")
    g.add_edge("a", "b", k=None, lst=[1])
    back = nx.read_graphml(to_graphml(g, tmp_path / "g.graphml"))
    assert back.nodes["a"]["t"] == '["x"]' and "w" not in back.nodes["a"]
    assert back.nodes["c"]["v"] == "three"
    assert back.graph["ids"] == "[1, 2]"


# -- SVG ---------------------------------------------------------------------------------


def _is_svg(text: str) -> bool:
    return text.lstrip().startswith(("<?xml", "<svg")) and "<svg" in text and "</svg>" in text


def test_builtin_renderer_draws_every_mission_graph() -> None:
    for path in mission_files():
        c = compile_file(path)
        for which, graph in (("amt", c.amt), ("meg", c.meg), ("mdg", c.mdgs["GCS"])):
            dot = to_dot(graph, which)  # type: ignore[arg-type]
            svg = render_svg(dot, engine="builtin")
            assert _is_svg(svg)
            parsed = parse_dot(dot)
            assert len(parsed.nodes) == graph.number_of_nodes()
            assert len(parsed.edges) == graph.number_of_edges()
            assert svg.count('<g class="node">') == graph.number_of_nodes()
            assert svg.count('<g class="edge">') == graph.number_of_edges()


def test_builtin_renderer_styles_and_shapes(exp_d: CompiledMission) -> None:
    svg = builtin_svg(to_dot(exp_d.mdgs["D3"], "mdg"))
    assert 'stroke-dasharray="6,4"' in svg  # external arcs / proxies
    assert 'stroke-dasharray="2,3"' in svg  # loop arcs
    assert "<polygon" in svg and "<ellipse" in svg
    assert "&amp;&amp;" in svg  # conditions are XML-escaped
    # Layers go down: the start is drawn above the take-off, the take-off above the landing.
    svg = builtin_svg(to_dot(exp_d.meg, "meg"))
    ys = {
        m.group(2): float(m.group(1))
        for m in re.finditer(
            r'<text x="[\d.]+" y="([\d.]+)" text-anchor="middle" font-size="10">'
            r"(n\d+ [^<]*)</text>",
            svg,
        )
    }
    init = next(y for t, y in ys.items() if "INIT" in t)
    takeoff = next(y for t, y in ys.items() if "Takeoff" in t)
    land = next(y for t, y in ys.items() if "Land" in t)
    assert init < takeoff < land


def test_builtin_renderer_reads_general_dot() -> None:
    svg = builtin_svg("digraph G { a -> b -> c; c -> a [style=dotted]; d; b [shape=box] }")
    assert _is_svg(svg)
    assert svg.count('<g class="node">') == 4 and svg.count('<g class="edge">') == 3


@pytest.mark.skipif(shutil.which("dot") is None, reason="Graphviz (dot) is not installed")
def test_graphviz_is_used_when_installed(demo: CompiledMission) -> None:
    warnings: list[str] = []
    svg = render_svg(to_dot(demo.meg, "meg"), warnings=warnings)
    assert _is_svg(svg) and "Generated by graphviz" in svg and warnings == []


def test_missing_graphviz_falls_back_to_the_builtin_renderer(
    demo: CompiledMission,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr("eamos.compiler.drawing.shutil.which", lambda name: None)
    warnings: list[str] = []
    svg = render_svg(to_dot(demo.meg, "meg"), warnings=warnings)
    assert _is_svg(svg) and "graphviz" not in svg.lower()
    assert warnings == []  # no Graphviz is normal, not a warning
    render_svg(to_dot(demo.meg, "meg"), engine="dot", warnings=warnings)
    assert warnings and "not installed" in warnings[0]


def test_missing_graphviz_is_said_once_for_all_pictures(
    demo: CompiledMission, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """`eamos compile` and `eamos run` print one line, then draw every picture anyway."""
    monkeypatch.setattr("eamos.compiler.artifacts.shutil.which", lambda name: None)
    monkeypatch.setattr("eamos.compiler.drawing.shutil.which", lambda name: None)
    notes: list[str] = []
    manifest = write_artifacts(demo, tmp_path / "out", warnings=notes)
    assert [n for n in notes if "Graphviz" in n] == [
        "Graphviz 'dot' is not installed: pictures drawn by the built-in renderer "
        "(install graphviz for its layouts)"
    ]
    assert all("svg" in entry for entry in manifest["graphs"].values())


def _fake_dot(folder: Path, script: str, monkeypatch: pytest.MonkeyPatch) -> None:
    exe = folder / "dot"
    exe.write_text("#!/bin/sh\n" + script + "\n")
    exe.chmod(exe.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setenv("PATH", f"{folder}{os.pathsep}{os.environ.get('PATH', '')}")


def test_failing_graphviz_falls_back_with_a_warning(
    demo: CompiledMission,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    _fake_dot(tmp_path, "echo 'Error: something broke' >&2; exit 3", monkeypatch)
    warnings: list[str] = []
    svg = render_svg(to_dot(demo.meg, "meg"), warnings=warnings)
    assert _is_svg(svg)
    assert len(warnings) == 1 and "something broke" in warnings[0]


def test_hanging_graphviz_times_out_and_falls_back(
    demo: CompiledMission,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    _fake_dot(tmp_path, "exec sleep 30", monkeypatch)
    warnings: list[str] = []
    started = time.monotonic()
    svg = render_svg(to_dot(demo.meg, "meg"), timeout=0.5, warnings=warnings)
    assert time.monotonic() - started < 10
    assert _is_svg(svg) and "longer than" in warnings[0]


def test_graphviz_printing_garbage_falls_back(
    demo: CompiledMission,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    _fake_dot(tmp_path, "echo not-an-svg", monkeypatch)
    warnings: list[str] = []
    assert _is_svg(render_svg(to_dot(demo.meg, "meg"), warnings=warnings))
    assert warnings


# -- artifacts ---------------------------------------------------------------------------


def test_write_artifacts_writes_everything(demo: CompiledMission, tmp_path: Path) -> None:
    manifest = write_artifacts(demo, tmp_path)
    participants = ["GCS", "Drone1", "Drone2", "Drone3"]
    assert list(manifest["programs"]) == participants
    for drone in participants:
        path = tmp_path / "programs" / f"{drone}.program.json"
        program = load_program(path)
        assert program.drone == drone
        assert program.checksum == manifest["programs"][drone]["checksum"]
    stems = ["amt", "meg", *(f"mdg_{d}" for d in participants)]
    assert list(manifest["graphs"]) == stems
    for stem in stems:
        for ext in ("graphml", "dot", "svg"):
            path = tmp_path / "graphs" / f"{stem}.{ext}"
            assert manifest["graphs"][stem][ext] == f"graphs/{stem}.{ext}"
            assert path.stat().st_size > 0
        assert _is_svg((tmp_path / "graphs" / f"{stem}.svg").read_text())
        nx.read_graphml(tmp_path / "graphs" / f"{stem}.graphml")
    assert json.loads((tmp_path / "stats.json").read_text()) == demo.stats()
    assert json.loads((tmp_path / "manifest.json").read_text()) == manifest
    import hashlib

    for rel, digest in manifest["files"].items():
        assert digest == "sha256:" + hashlib.sha256((tmp_path / rel).read_bytes()).hexdigest()
    assert not list(tmp_path.rglob("*.tmp"))


def test_write_artifacts_without_svg_and_stale_files(tmp_path: Path) -> None:
    demo = compile_file(MISSIONS / "listing01_demo.go")
    write_artifacts(demo, tmp_path)
    assert (tmp_path / "programs" / "Drone3.program.json").exists()
    # Recompiling another mission into the same folder leaves none of the first behind.
    single = compile_file(MISSIONS / "experiment_a.go")
    manifest = write_artifacts(single, tmp_path, svg=False)
    assert sorted(p.name for p in (tmp_path / "programs").iterdir()) == [
        "Drone1.program.json",
        "GCS.program.json",
    ]
    assert not list((tmp_path / "graphs").glob("*.svg"))
    assert not (tmp_path / "graphs" / "mdg_Drone3.dot").exists()
    assert "svg" not in manifest["graphs"]["meg"]
    assert load_program(tmp_path / "programs" / "Drone1.program.json").mission == "experiment_a"


# -- pictures a person reads (issue 14) -------------------------------------------------


def test_an_mdg_in_parts_is_stacked_by_invisible_arcs_in_mission_order() -> None:
    """Experiment C's Drone3 MDG has seven parts: chained top to bottom, not side by side."""
    compiled = compile_file(MISSIONS / "experiment_c.go")
    mdg = compiled.mdgs["Drone3"]
    dot = to_dot(mdg, "mdg")
    invisible = re.findall(r'^  "(\S+)" -> "(\S+)" \[style="invis"\];$', dot, re.M)
    parts = list(nx.weakly_connected_components(mdg))
    assert len(parts) == 7 and invisible
    # Every part but the last sends invisible arcs to the next one, and only to it.
    part_of = {f"n{n}" if isinstance(n, int) else str(n): i for i, p in enumerate(parts) for n in p}
    order = sorted(range(len(parts)), key=lambda i: min(mdg.nodes[n]["meg"] for n in parts[i]))
    rank = {part: r for r, part in enumerate(order)}
    assert {(rank[part_of[a]], rank[part_of[b]]) for a, b in invisible} == {
        (r, r + 1) for r in range(len(parts) - 1)
    }
    # The built-in renderer lays them out too, but does not draw them.
    svg = builtin_svg(dot)
    assert svg.count('class="edge"') == mdg.number_of_edges()


def test_condition_labels_break_between_comparisons_without_extra_brackets(
    exp_d: CompiledMission,
) -> None:
    dot = to_dot(exp_d.mdgs["D3"], "mdg")
    assert "((" not in dot
    label = re.search(r'label="(n14 RepeatWhile[^"]*)"', dot)
    assert label is not None
    lines = label.group(1).split("\\n")
    assert lines[:3] == ["n14 RepeatWhile", "D3.X() > -30 &&", "D3.X() < 30 &&"]


def test_builtin_shapes_hold_their_text() -> None:
    """Each node's text (10 pt, 6.4 pt a character, 13 pt a line) fits inside its shape."""
    for mission in ("experiment_d.go", "listing01_demo.go"):
        compiled = compile_file(MISSIONS / mission)
        for mdg in compiled.mdgs.values():
            svg = builtin_svg(to_dot(mdg, "mdg"))
            for node in re.findall(r'<g class="node">(.*?)</g>', svg, re.S):
                lines = re.findall(r">([^<]*)</text>", node)
                w = max(len(x) for x in lines) * 6.4
                h = len(lines) * 13.0
                if m := re.search(r'rx="([\d.]+)" ry="([\d.]+)"', node):
                    rx, ry = float(m.group(1)), float(m.group(2))
                    assert (w / 2 / rx) ** 2 + (h / 2 / ry) ** 2 <= 1.0, lines
                elif "<polygon" in node and ("PAR" in lines[0] or "SEQ" in lines[0]):
                    pts = re.search(r'points="([^"]+)"', node).group(1)  # type: ignore[union-attr]
                    xs = [float(p.split(",")[0]) for p in pts.split()]
                    ys = [float(p.split(",")[1]) for p in pts.split()]
                    assert w / (max(xs) - min(xs)) + h / (max(ys) - min(ys)) <= 1.0, lines


@pytest.mark.skipif(shutil.which("dot") is None, reason="Graphviz (dot) is not installed")
@pytest.mark.parametrize("path", mission_files(), ids=lambda p: p.stem)
def test_graphviz_pictures_fit_a_screen_width(path: Path, tmp_path: Path) -> None:
    """No dependency or execution graph of a shipped mission is wider than a screen (1100 pt).

    Abstract mission trees of the deep missions (loops in a PAR in a SEQ...)
    stay wider: drawn on their side they are as wide as their levels; 1500 pt.
    """
    compiled = compile_file(path)
    graphs = [("amt", compiled.amt), ("meg", compiled.meg)]
    graphs += [("mdg", mdg) for mdg in compiled.mdgs.values()]
    for which, graph in graphs:
        svg = render_svg(to_dot(graph, which), engine="dot")  # type: ignore[arg-type]
        width = float(re.search(r'<svg width="(\d+)pt"', svg).group(1))  # type: ignore[union-attr]
        limit = 1500 if which == "amt" else 1100
        assert width <= limit, (path.stem, which, graph.graph.get("drone"), width)
