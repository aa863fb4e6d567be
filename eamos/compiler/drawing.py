"""Pictures and exports of the mission graphs: GraphML, Graphviz DOT and SVG.

* :func:`to_graphml` writes any of the compiler's graphs (AMT, MEG, MDG) as
  GraphML, the format the paper's compiler emitted (Figure 2), after turning
  attribute values GraphML cannot hold (tuples, lists, ``None``) into JSON
  strings or dropping them.
* :func:`to_dot` draws a graph in the paper's visual language (Figures 6-8):
  the shape tells the node kind, the fill colour the drone, dashed lines are
  external arcs and proxy nodes, dotted lines are loop arcs.
* :func:`render_svg` turns DOT text into SVG with Graphviz when it is
  installed, and otherwise (or when Graphviz fails or takes too long) with a
  small built-in layered renderer (:mod:`.svg_layout`), so pictures never
  need Graphviz.

Legend (also in ``docs/graphs.md``):

=================  ============================================================
shape              node kind
=================  ============================================================
triangle           ``init``: the ground station's initial node
box                ``seq``: a sequential block (AMT only)
diamond            ``par``/``fork``: a parallel block
ellipse            ``action``: a drone action
cds (arrow right)  a control structure (If, Wait*, Repeat*, Pause*, Do*) begin
larrow (arrow left) ``end`` node closing a control structure
=================  ============================================================

Fill colours: the ground station is grey, drones take a fixed palette in
natural name order (first yellow, second green, third orange-red, ...), nodes
not yet assigned to a drone (AMT ``seq``/``par``, MEG forks) are white.
"""

from __future__ import annotations

import colorsys
import itertools
import json
import logging
import re
import shutil
import subprocess
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, Literal

import networkx as nx

from ..program.uniform import GROUND_STATION
from .dependency_graph import natural_key

# The built-in renderer lives in .svg_layout; its names stay importable from here.
from .svg_layout import builtin_svg, parse_dot

log = logging.getLogger(__name__)

GraphKind = Literal["amt", "meg", "mdg"]

#: Graphviz shape for each node kind; control structures not listed use :data:`CONTROL_SHAPE`.
KIND_SHAPES: dict[str, str] = {
    "init": "triangle",
    "seq": "box",
    "par": "diamond",
    "fork": "diamond",
    "action": "ellipse",
    "end": "larrow",
    "abandon": "octagon",  # Abandon(): a stop sign
}
CONTROL_SHAPE = "cds"

GROUND_COLOUR = "#c8c8c8"
UNASSIGNED_COLOUR = "#ffffff"
#: Drone colours in order: the paper's yellow, green, orange-red, then more.
PALETTE: tuple[str, ...] = (
    "#ffe066",  # yellow   (Drone1 in the paper)
    "#8ce99a",  # green    (Drone2)
    "#ff8c69",  # orange-red (Drone3)
    "#74c0fc",  # blue
    "#da77f2",  # violet
    "#63e6be",  # teal
    "#ffc078",  # light orange
    "#a9e34b",  # lime
    "#91a7ff",  # indigo
    "#f783ac",  # pink
)

#: Arc kinds (MEG/MDG) and roles (AMT) written next to their arcs.
_LABELLED_ARCS = frozenset({"then", "else", "body", "exit", "loop", "begin", "handler"})

#: Above about this many nodes plus arcs Graphviz may run for minutes; the built-in
#: renderer is used instead.
MAX_DOT_STATEMENTS = 6000
DOT_TIMEOUT_S = 30.0
_LABEL_WIDTH = 26  # characters per label line before wrapping
_CHAR_PT = 7.0  # about a 10 pt Helvetica character, for width estimates
_GAP_PT = 30.0  # between two nodes side by side, or two ranks


# -- GraphML --------------------------------------------------------------------


def _graphml_value(value: Any) -> Any:
    """A value GraphML can store: bool/int/float/str kept, containers as JSON, None dropped."""
    if value is None:
        return None
    if isinstance(value, bool | int | float | str):
        return value
    if isinstance(value, tuple | list | dict | set | frozenset):
        items = sorted(value) if isinstance(value, set | frozenset) else value
        return json.dumps(items, default=str)
    return str(value)


def _clean_attrs(records: Iterable[dict[str, Any]]) -> None:
    """Convert attribute dicts in place; a key whose values mix types becomes a string."""
    records = list(records)
    types: dict[str, set[type]] = {}
    for attrs in records:
        for key in list(attrs):
            value = _graphml_value(attrs[key])
            if value is None:
                del attrs[key]
            else:
                attrs[key] = value
                types.setdefault(key, set()).add(type(value))
    # networkx declares one GraphML type per key: mixed int/float becomes float,
    # any other mix becomes text, so every graph exports.
    for key, seen in types.items():
        if len(seen) <= 1:
            continue
        if seen <= {int, float}:
            conv: Any = float
        else:
            conv = _as_text
        for attrs in records:
            if key in attrs:
                attrs[key] = conv(attrs[key])


def _as_text(value: Any) -> str:
    return value if isinstance(value, str) else json.dumps(value)


def graphml_ready(graph: nx.DiGraph) -> nx.DiGraph:
    """A copy of ``graph`` whose attributes all fit GraphML (node ids are kept)."""
    out = graph.copy()
    graph_attrs = dict(out.graph)
    _clean_attrs([graph_attrs])
    out.graph.clear()
    out.graph.update(graph_attrs)
    _clean_attrs(attrs for _, attrs in out.nodes(data=True))
    _clean_attrs(attrs for _, _, attrs in out.edges(data=True))
    return out


def to_graphml(graph: nx.DiGraph, path: Path | str) -> Path:
    """Write an AMT, MEG or MDG as GraphML to ``path``; return the path.

    Tuples and lists (``args``, ``loops``, ``cond`` ...) are stored as JSON
    strings, ``None`` attributes are left out; node ids stay as they are.
    """
    path = Path(path)
    nx.write_graphml(graphml_ready(graph), path, encoding="utf-8", prettyprint=True)
    return path


# -- colours and labels ------------------------------------------------------------


def drone_colours(drones: Iterable[str]) -> dict[str, str]:
    """A fill colour per participant: GCS grey, drones by the palette in natural name order."""
    names = sorted({d for d in drones if d and d != GROUND_STATION}, key=natural_key)
    colours = {GROUND_STATION: GROUND_COLOUR, "": UNASSIGNED_COLOUR}
    for i, name in enumerate(names):
        if i < len(PALETTE):
            colours[name] = PALETTE[i]
        else:
            # Past the palette, spread hues by the golden angle: distinct and stable.
            hue = (i * 0.381966) % 1.0
            r, g, b = colorsys.hls_to_rgb(hue, 0.78, 0.75)
            colours[name] = f"#{round(r * 255):02x}{round(g * 255):02x}{round(b * 255):02x}"
    return colours


def _wrap(text: str, width: int = _LABEL_WIDTH) -> list[str]:
    """Break a long label (conditions) into lines of about ``width`` characters.

    Breaks go after ``&&`` and ``||`` first, so each line holds whole
    comparisons (``D3.X() > -30 &&``); a longer piece is broken at spaces.
    """
    pieces = re.split(r"(?<= &&| \|\|) ", text)
    lines: list[str] = []
    current = ""
    for piece in pieces:
        if current and len(current) + 1 + len(piece) > width:
            lines.append(current)
            current = ""
        if not current and len(piece) <= width + 8:
            current = piece  # one comparison stays on one line, a little over width
            continue
        for word in piece.split(" "):
            if current and len(current) + 1 + len(word) > width:
                lines.append(current)
                current = word
            else:
                current = f"{current} {word}" if current else word
    if current or not lines:
        lines.append(current)
    return lines


def _label_width(attrs: dict[str, Any]) -> float:
    lines = _wrap(str(attrs.get("label", attrs.get("kind", ""))))
    return max(len(line) for line in lines) * _CHAR_PT + _GAP_PT


def _narrower_on_its_side(tree: nx.DiGraph) -> bool:
    """True when a tree drawn left to right is narrower than drawn top-down.

    Top-down, its width is about its leaves side by side; on its side,
    about its levels side by side, each as wide as its widest label.
    """
    roots = [n for n in tree if tree.in_degree(n) == 0]
    if not roots:
        return False
    depth = nx.multi_source_dijkstra_path_length(tree, roots)
    leaves = sum(_label_width(tree.nodes[n]) for n in tree if tree.out_degree(n) == 0)
    levels: dict[int, float] = {}
    for n, d in depth.items():
        levels[d] = max(levels.get(d, 0.0), _label_width(tree.nodes[n]))
    return sum(levels.values()) < leaves


def _stacking_arcs(graph: nx.DiGraph) -> list[tuple[Any, Any]]:
    """Invisible arcs that stack a graph's separate parts top to bottom, in mission order.

    An MDG falls apart into one part per stretch of the mission the drone
    takes part in; side by side they make pictures thousands of points wide.
    Chained from the last node of one part to the first of the next, they
    read from top to bottom like the mission.
    """
    parts = [
        sorted(part, key=lambda n: _sort_key(n, graph.nodes[n]))
        for part in nx.weakly_connected_components(graph)
    ]
    if len(parts) < 2:
        return []
    parts.sort(key=lambda part: _sort_key(part[0], graph.nodes[part[0]]))
    arcs: list[tuple[Any, Any]] = []
    for upper, lower in itertools.pairwise(parts):
        bottom = [n for n in upper if not any(s in upper for s in graph.successors(n))]
        top = [n for n in lower if not any(p in lower for p in graph.predecessors(n))]
        # Every bottom node to every top node: pulled evenly, the parts stay
        # centred under each other instead of drifting into a staircase.
        arcs.extend((a, b) for a in bottom or upper[-1:] for b in top or lower[:1])
    return arcs


def _dot_quote(text: str) -> str:
    """A DOT double-quoted string; newlines become DOT's centred line break."""
    out = text.replace("\\", "\\\\").replace('"', '\\"')
    return '"' + out.replace("\n", "\\n") + '"'


def _sort_key(node: Any, attrs: dict[str, Any]) -> tuple[Any, ...]:
    meg = attrs.get("meg", node)
    return (meg if isinstance(meg, int) else 1 << 60, str(node))


def _node_id_text(node: Any, attrs: dict[str, Any]) -> str:
    """``n<id>``: the MEG id for MDG nodes (forks' replicas share their fork's id)."""
    meg = attrs.get("meg")
    if isinstance(meg, int):
        return f"n{meg}"
    if isinstance(node, int):
        return f"n{node}"
    return str(node).split("@", 1)[0]


def _node_dot_id(node: Any) -> str:
    return _dot_quote(f"n{node}" if isinstance(node, int) else str(node))


def _drones_of(graph: nx.DiGraph) -> list[str]:
    return [str(a.get("drone", "")) for _, a in graph.nodes(data=True)]


def to_dot(
    graph: nx.DiGraph,
    which: GraphKind,
    *,
    fleet: Sequence[str] | None = None,
    title: str | None = None,
) -> str:
    """Graphviz DOT text drawing ``graph`` (an AMT, MEG or MDG) in the paper's style.

    ``fleet`` fixes the colours across several pictures of one mission (pass
    every participant); by default the drones found in ``graph`` are used.
    The output is deterministic: nodes and arcs are sorted.
    """
    if which not in ("amt", "meg", "mdg"):
        raise ValueError(f"which must be 'amt', 'meg' or 'mdg', not {which!r}")
    colours = drone_colours(list(fleet or ()) + _drones_of(graph))
    if title is None:
        mission = graph.graph.get("mission", "mission")
        title = {
            "amt": "Abstract Mission Tree",
            "meg": "Mission Execution Graph",
            "mdg": f"Mission Dependency Graph of {graph.graph.get('drone', '?')}",
        }[which]
        title = f"{mission}: {title}"
    # Pictures a page wide: an AMT lies on its side when that is narrower; an
    # MDG's parts stack (see _stacking_arcs).
    rankdir = "LR" if which == "amt" and _narrower_on_its_side(graph) else "TB"
    lines = [
        f"digraph {_dot_quote(which)} {{",
        f'  graph [rankdir={rankdir}, fontname="Helvetica", labelloc=t, '
        + ("ranksep=0.3, " if rankdir == "LR" else "")
        + f"label={_dot_quote(title)}];",
        '  node [fontname="Helvetica", fontsize=10, style=filled, fillcolor="#ffffff"];',
        '  edge [fontname="Helvetica", fontsize=9];',
    ]
    for node, attrs in sorted(graph.nodes(data=True), key=lambda na: _sort_key(*na)):
        kind = str(attrs.get("kind", ""))
        drone = str(attrs.get("drone", ""))
        if which != "mdg" and kind in ("seq", "par", "fork"):
            drone = ""  # structural nodes are assigned only by slicing
        label = str(attrs.get("label", kind))
        if "cond" in attrs and " " in label:
            # A control structure: its name on the first line, the condition below.
            head, cond = label.split(" ", 1)
            label_lines = [f"{_node_id_text(node, attrs)} {head}", *_wrap(cond)]
        else:
            label_lines = _wrap(f"{_node_id_text(node, attrs)} {label}")
        text = "\n".join(label_lines + ([drone] if drone else []))
        shape = KIND_SHAPES.get(kind, CONTROL_SHAPE if kind else "ellipse")
        # Arrow-like shapes eat into their box: more room, so the text stays inside.
        margin = {CONTROL_SHAPE: ', margin="0.25,0.12"', "larrow": ', margin="0.2,0.08"'}.get(
            shape, ""
        )
        style = "filled"
        if which == "mdg" and not attrs.get("native", True):
            style = "filled,dashed"  # a proxy: executed by another drone
        elif which == "mdg":
            # One group for the drone's own nodes: Graphviz keeps arcs inside a
            # group straight, so its own chain runs down the middle instead of
            # drifting sideways at every proxy (a staircase pages wide).
            margin += ', group="native"'
        fill = colours.get(drone, UNASSIGNED_COLOUR)
        lines.append(
            f"  {_node_dot_id(node)} [label={_dot_quote(text)}, shape={shape}, "
            f"style={_dot_quote(style)}, fillcolor={_dot_quote(fill)}{margin}];"
        )

    def edge_key(e: tuple[Any, Any, dict[str, Any]]) -> tuple[Any, ...]:
        a, b, _ = e
        return (_sort_key(a, graph.nodes[a]), _sort_key(b, graph.nodes[b]))

    for a, b, data in sorted(graph.edges(data=True), key=edge_key):
        attrs_out: list[str] = []
        kind = str(data.get("role" if which == "amt" else "kind", ""))
        if which == "amt" and "order" in data:
            attrs_out.append(f"label={_dot_quote(str(data['order']))}")
        elif kind in _LABELLED_ARCS:
            attrs_out.append(f"label={_dot_quote(kind)}")
        if kind == "loop":
            attrs_out.append('style="dotted"')
            if data.get("external"):
                attrs_out.append("penwidth=2")  # external and a loop arc: dotted, thicker
        elif data.get("external"):
            attrs_out.append('style="dashed"')
        suffix = f" [{', '.join(attrs_out)}]" if attrs_out else ""
        lines.append(f"  {_node_dot_id(a)} -> {_node_dot_id(b)}{suffix};")
    if which == "mdg":
        for a, b in _stacking_arcs(graph):
            lines.append(f'  {_node_dot_id(a)} -> {_node_dot_id(b)} [style="invis"];')
    lines.append("}")
    return "\n".join(lines) + "\n"


# -- SVG ------------------------------------------------------------------------------


def render_svg(
    dot_text: str,
    *,
    engine: Literal["auto", "dot", "builtin"] = "auto",
    timeout: float = DOT_TIMEOUT_S,
    warnings: list[str] | None = None,
) -> str:
    """SVG text for ``dot_text``: Graphviz ``dot -Tsvg`` if installed, else the built-in renderer.

    Graphviz failing, timing out or missing (with ``engine="dot"``) falls back
    to the built-in renderer; the reason is appended to ``warnings`` when a
    list is given, and logged otherwise.  Very large graphs (more than
    :data:`MAX_DOT_STATEMENTS` nodes and arcs) skip Graphviz, which could run for minutes.
    """

    def warn(message: str) -> None:
        # A caller that collects warnings reports them itself; otherwise log them.
        if warnings is not None:
            warnings.append(message)
        else:
            log.warning(message)

    if engine != "builtin":
        exe = shutil.which("dot")
        if exe is None:
            if engine == "dot":
                warn("Graphviz 'dot' is not installed; drawing with the built-in renderer")
        elif dot_text.count(";") > MAX_DOT_STATEMENTS:
            warn(
                f"graph too large for Graphviz (over {MAX_DOT_STATEMENTS} nodes and arcs); "
                "drawing with the built-in renderer"
            )
        else:
            try:
                done = subprocess.run(
                    [exe, "-Tsvg"],
                    input=dot_text.encode("utf-8"),
                    capture_output=True,
                    timeout=timeout,
                    check=False,
                )
            except subprocess.TimeoutExpired:
                warn(f"Graphviz took longer than {timeout:g} s; drawing with the built-in renderer")
            except OSError as exc:
                warn(f"Graphviz could not run ({exc}); drawing with the built-in renderer")
            else:
                if done.returncode == 0 and done.stdout.lstrip().startswith((b"<?xml", b"<svg")):
                    return done.stdout.decode("utf-8", errors="replace")
                err = done.stderr.decode("utf-8", errors="replace").strip().splitlines()
                warn(
                    f"Graphviz failed ({err[0] if err else f'exit code {done.returncode}'}); "
                    "drawing with the built-in renderer"
                )
    return builtin_svg(dot_text)


__all__ = [
    "CONTROL_SHAPE",
    "KIND_SHAPES",
    "MAX_DOT_STATEMENTS",
    "GraphKind",
    "builtin_svg",
    "drone_colours",
    "graphml_ready",
    "parse_dot",
    "render_svg",
    "to_dot",
    "to_graphml",
]
