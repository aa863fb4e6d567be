"""The built-in SVG renderer: a tiny DOT reader and a layered layout.

Used by :func:`~.drawing.render_svg` when Graphviz is missing, fails, takes
too long or would take too long, so pictures never need Graphviz.  It reads
the DOT text :func:`~.drawing.to_dot` writes (not arbitrary DOT) and lays the
nodes out in layers along the longest path from the sources.
"""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass, field
from xml.sax.saxutils import escape as _xml_escape

# -- built-in renderer: a tiny DOT reader and a layered layout --------------------------

_TOKEN = re.compile(
    r'\s*(?:(?P<comment>//[^\n]*|#[^\n]*|/\*.*?\*/)|(?P<string>"(?:[^"\\]|\\.)*")'
    r"|(?P<arrow>->|--)|(?P<punct>[\[\]{};,=])|(?P<ident>-?[\w.@\u0080-\U0010ffff]+))",
    re.S,
)


@dataclass
class _DotGraph:
    name: str = ""
    graph: dict[str, str] = field(default_factory=dict)
    nodes: dict[str, dict[str, str]] = field(default_factory=dict)
    edges: list[tuple[str, str, dict[str, str]]] = field(default_factory=list)


def _unquote(token: str) -> str:
    if token.startswith('"') and token.endswith('"') and len(token) >= 2:
        body = token[1:-1]
        out = []
        i = 0
        while i < len(body):
            ch = body[i]
            if ch == "\\" and i + 1 < len(body):
                nxt = body[i + 1]
                out.append("\n" if nxt in "nlr" else nxt)
                i += 2
                continue
            out.append(ch)
            i += 1
        return "".join(out)
    return token


def _tokens(text: str) -> list[str]:
    out = []
    pos = 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            if text[pos:].strip():
                raise ValueError(f"cannot read DOT text at offset {pos}")
            break
        pos = m.end()
        if m.group("comment") is None:
            tok = m.group(m.lastgroup or "ident")
            out.append(tok)
    return out


def parse_dot(text: str) -> _DotGraph:
    """Read the simple DOT this module writes (statements, attribute lists, edge chains).

    Subgraphs are flattened; ports and HTML labels are not understood.
    """
    toks = _tokens(text)
    g = _DotGraph()
    i = 0
    node_defaults: dict[str, str] = {}
    edge_defaults: dict[str, str] = {}
    # Header: [strict] (di)graph [name] {
    while i < len(toks) and toks[i] != "{":
        if toks[i] not in ("strict", "digraph", "graph"):
            g.name = _unquote(toks[i])
        i += 1
    i += 1

    def attr_list(j: int) -> tuple[dict[str, str], int]:
        attrs: dict[str, str] = {}
        while j < len(toks) and toks[j] == "[":
            j += 1
            while j < len(toks) and toks[j] != "]":
                if toks[j] in (",", ";"):
                    j += 1
                    continue
                key = _unquote(toks[j])
                if j + 2 < len(toks) and toks[j + 1] == "=":
                    attrs[key] = _unquote(toks[j + 2])
                    j += 3
                else:
                    attrs[key] = "true"
                    j += 1
            j += 1
        return attrs, j

    while i < len(toks):
        tok = toks[i]
        if tok in ("}", "{", ";", "subgraph") or (
            tok not in ("[",) and i + 1 < len(toks) and toks[i + 1] == "{"
        ):
            i += 1
            continue
        if tok in ("graph", "node", "edge") and i + 1 < len(toks) and toks[i + 1] == "[":
            attrs, i = attr_list(i + 1)
            {"graph": g.graph, "node": node_defaults, "edge": edge_defaults}[tok].update(attrs)
            continue
        if i + 2 < len(toks) and toks[i + 1] == "=":  # graph attribute: a = b
            g.graph[_unquote(tok)] = _unquote(toks[i + 2])
            i += 3
            continue
        chain = [_unquote(tok)]
        i += 1
        while i + 1 < len(toks) and toks[i] in ("->", "--"):
            chain.append(_unquote(toks[i + 1]))
            i += 2
        attrs, i = attr_list(i)
        for name in chain:
            if name not in g.nodes:
                g.nodes[name] = dict(node_defaults)
        if len(chain) == 1:
            g.nodes[chain[0]].update(attrs)
        for a, b in itertools.pairwise(chain):
            g.edges.append((a, b, {**edge_defaults, **attrs}))
    return g


@dataclass
class _Box:
    x: float = 0.0
    y: float = 0.0
    w: float = 0.0
    h: float = 0.0
    lines: list[str] = field(default_factory=list)


_CHAR_W = 6.4  # average width of a 10 pt Helvetica character, in px
_LINE_H = 13.0
_LAYER_GAP = 56.0
_NODE_GAP = 22.0
_MARGIN = 24.0
_BOW_MAX = 110.0  # how far an arc over several layers bows sideways, at most


def _layers(names: list[str], edges: list[tuple[str, str, dict[str, str]]]) -> dict[str, int]:
    """Longest-path layering after breaking cycles at DFS back arcs (loop arcs)."""
    succ: dict[str, list[str]] = {n: [] for n in names}
    for a, b, _ in edges:
        if a != b:
            succ[a].append(b)
    index = {n: i for i, n in enumerate(names)}
    state: dict[str, int] = {}
    forward: dict[str, list[str]] = {n: [] for n in names}
    has_pred = {b for a, b, _ in edges if a != b}
    roots = [n for n in names if n not in has_pred] + names
    order: list[str] = []  # post-order
    for root in roots:
        if root in state:
            continue
        state[root] = 1
        stack = [(root, iter(sorted(succ[root], key=index.__getitem__)))]
        while stack:
            node, it = stack[-1]
            nxt = next(it, None)
            if nxt is None:
                stack.pop()
                state[node] = 2
                order.append(node)
                continue
            if state.get(nxt) == 1:
                continue  # back arc: drawn, but ignored for layering
            forward[node].append(nxt)
            if nxt not in state:
                state[nxt] = 1
                stack.append((nxt, iter(sorted(succ[nxt], key=index.__getitem__))))
    layer = dict.fromkeys(names, 0)
    for node in reversed(order):  # reverse post-order is a topological order
        for nxt in forward[node]:
            layer[nxt] = max(layer[nxt], layer[node] + 1)
    return layer


def _order_layers(
    rows: list[list[str]], edges: list[tuple[str, str, dict[str, str]]], layer: dict[str, int]
) -> None:
    """Barycentre sweeps to reduce crossings (in place)."""
    up: dict[str, list[str]] = {}
    down: dict[str, list[str]] = {}
    for a, b, _ in edges:
        if layer[a] < layer[b]:
            down.setdefault(a, []).append(b)
            up.setdefault(b, []).append(a)
    for sweep in range(4):
        pos = {n: i for row in rows for i, n in enumerate(row)}
        rng = range(1, len(rows)) if sweep % 2 == 0 else range(len(rows) - 2, -1, -1)
        nbrs = up if sweep % 2 == 0 else down
        for r in rng:
            row = rows[r]
            bary = {}
            for i, n in enumerate(row):
                ps = [pos[p] for p in nbrs.get(n, ()) if p in pos]
                bary[n] = sum(ps) / len(ps) if ps else float(i)
            row.sort(key=lambda n: (bary[n], pos[n]))
            for i, n in enumerate(row):
                pos[n] = i


def _shape_points(shape: str, b: _Box) -> str:
    x0, x1, y0, y1 = b.x - b.w / 2, b.x + b.w / 2, b.y - b.h / 2, b.y + b.h / 2
    t = min(b.h / 2, 14.0)
    pts = {
        "diamond": [(b.x, y0), (x1, b.y), (b.x, y1), (x0, b.y)],
        "triangle": [(b.x, y0), (x1, y1), (x0, y1)],
        "cds": [(x0, y0), (x1 - t, y0), (x1, b.y), (x1 - t, y1), (x0, y1)],
        "larrow": [(x0 + t, y0), (x1, y0), (x1, y1), (x0 + t, y1), (x0, b.y)],
    }[shape]
    return " ".join(f"{px:.1f},{py:.1f}" for px, py in pts)


def _clip(b: _Box, shape: str, tx: float, ty: float) -> tuple[float, float]:
    """Where the line from the centre of ``b`` towards (tx, ty) leaves the node."""
    dx, dy = tx - b.x, ty - b.y
    if dx == 0 and dy == 0:
        return b.x, b.y
    if shape == "ellipse":
        a, c = b.w / 2, b.h / 2
        k = 1.0 / math.sqrt((dx / a) ** 2 + (dy / c) ** 2)
    elif shape in ("diamond", "triangle"):
        k = 1.0 / (abs(dx) / (b.w / 2) + abs(dy) / (b.h / 2))
    else:
        k = min(b.w / 2 / abs(dx) if dx else math.inf, b.h / 2 / abs(dy) if dy else math.inf)
    k = min(k, 1.0)
    return b.x + dx * k, b.y + dy * k


def _dash(style: str) -> str:
    if "dotted" in style:
        return ' stroke-dasharray="2,3"'
    if "dashed" in style:
        return ' stroke-dasharray="6,4"'
    return ""


def builtin_svg(dot_text: str) -> str:
    """Draw DOT text as SVG without Graphviz: layered top to bottom, straight arrows.

    Plain but readable: longest-path layers, barycentre ordering, boxes,
    ellipses, diamonds and arrows, with the DOT's fill colours and
    dashed/dotted styles.
    """
    g = parse_dot(dot_text)
    names = list(g.nodes)
    layer = _layers(names, g.edges)
    rows: list[list[str]] = [[] for _ in range(max(layer.values(), default=-1) + 1)]
    for n in names:
        rows[layer[n]].append(n)
    _order_layers(rows, g.edges, layer)

    boxes: dict[str, _Box] = {}
    for n in names:
        attrs = g.nodes[n]
        lines = attrs.get("label", n).split("\n")
        shape = attrs.get("shape", "ellipse")
        w = max(len(line) for line in lines) * _CHAR_W + 20
        h = len(lines) * _LINE_H + 14
        # The text's box must fit inside the shape: a diamond (or triangle)
        # holds it at twice its size, an ellipse at sqrt(2) times.
        if shape in ("diamond", "triangle"):
            w, h = w * 2.0, h * 2.0
        elif shape in ("ellipse", "circle", "oval"):
            w, h = w * 1.42, h * 1.42
        boxes[n] = _Box(w=w, h=h, lines=lines)

    title = g.graph.get("label", "")
    top = _MARGIN + (24.0 if title else 0.0)
    widths = [sum(boxes[n].w for n in row) + _NODE_GAP * max(len(row) - 1, 0) for row in rows]
    # Room on both sides for arcs that bow around the nodes they skip.
    long_arcs = any(abs(layer[a] - layer[b]) > 1 for a, b, _ in g.edges)
    side = _MARGIN + (_BOW_MAX if long_arcs else 0.0)
    total_w = max([*widths, len(title) * 7.5, 80.0]) + 2 * side
    y = top
    for row, width in zip(rows, widths, strict=True):
        row_h = max((boxes[n].h for n in row), default=0.0)
        x = (total_w - width) / 2
        for n in row:
            b = boxes[n]
            b.x, b.y = x + b.w / 2, y + row_h / 2
            x += b.w + _NODE_GAP
        y += row_h + _LAYER_GAP
    total_h = y - _LAYER_GAP + _MARGIN if rows else top + _MARGIN

    out = [
        '<?xml version="1.0" encoding="UTF-8" standalone="no"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{total_w:.0f}pt" height="{total_h:.0f}pt" '
        f'viewBox="0 0 {total_w:.1f} {total_h:.1f}" font-family="Helvetica,Arial,sans-serif">',
        '<defs><marker id="arrow" viewBox="0 0 10 10" refX="10" refY="5" markerWidth="8" '
        'markerHeight="8" orient="auto-start-reverse"><path d="M0,0 L10,5 L0,10 z"/>'
        "</marker></defs>",
        f'<g class="graph"><title>{_xml_escape(g.name)}</title>',
        f'<rect x="0" y="0" width="{total_w:.1f}" height="{total_h:.1f}" fill="white"/>',
    ]
    if title:
        out.append(
            f'<text x="{total_w / 2:.1f}" y="{_MARGIN:.1f}" text-anchor="middle" '
            f'font-size="14">{_xml_escape(title)}</text>'
        )
    for src, dst, eattrs in g.edges:
        if "invis" in eattrs.get("style", ""):
            continue  # layout only (e.g. stacking an MDG's parts): not drawn
        ba, bb = boxes[src], boxes[dst]
        shape_a = g.nodes[src].get("shape", "ellipse")
        shape_b = g.nodes[dst].get("shape", "ellipse")
        if src == dst:  # self loop: a small arc on the right
            x, y0 = ba.x + ba.w / 2, ba.y
            path = (
                f"M{x:.1f},{y0 - 6:.1f} C{x + 30:.1f},{y0 - 20:.1f} "
                f"{x + 30:.1f},{y0 + 20:.1f} {x:.1f},{y0 + 6:.1f}"
            )
            lx, ly = x + 26, y0
        elif abs(layer[dst] - layer[src]) <= 1:
            x1, y1 = _clip(ba, shape_a, bb.x, bb.y)
            x2, y2 = _clip(bb, shape_b, ba.x, ba.y)
            path = f"M{x1:.1f},{y1:.1f} L{x2:.1f},{y2:.1f}"
            lx, ly = (x1 + x2) / 2 + 4, (y1 + y2) / 2
        else:
            # Arcs over several layers (and back arcs) bow sideways, so they do not
            # run through the nodes between their ends.
            span = abs(layer[dst] - layer[src])
            sign = 1.0 if bb.x >= ba.x else -1.0
            off = sign * min(_BOW_MAX, 30.0 + 14.0 * span)
            c1 = (ba.x + off, ba.y + (bb.y - ba.y) / 3)
            c2 = (bb.x + off, bb.y - (bb.y - ba.y) / 3)
            x1, y1 = _clip(ba, shape_a, *c1)
            x2, y2 = _clip(bb, shape_b, *c2)
            path = (
                f"M{x1:.1f},{y1:.1f} C{c1[0]:.1f},{c1[1]:.1f} {c2[0]:.1f},{c2[1]:.1f} "
                f"{x2:.1f},{y2:.1f}"
            )
            lx = 0.125 * x1 + 0.375 * c1[0] + 0.375 * c2[0] + 0.125 * x2 + 4
            ly = 0.125 * y1 + 0.375 * c1[1] + 0.375 * c2[1] + 0.125 * y2
        pen = eattrs.get("penwidth", "1")
        out.append(
            f'<g class="edge"><title>{_xml_escape(src)}-&gt;{_xml_escape(dst)}</title>'
            f'<path d="{path}" fill="none" stroke="black" '
            f'stroke-width="{_xml_escape(pen)}"'
            f'{_dash(eattrs.get("style", ""))} marker-end="url(#arrow)"/>'
        )
        if eattrs.get("label"):
            out.append(
                f'<text x="{lx:.1f}" y="{ly:.1f}" font-size="9">'
                f"{_xml_escape(eattrs['label'])}</text>"
            )
        out.append("</g>")
    for n in names:
        attrs = g.nodes[n]
        b = boxes[n]
        shape = attrs.get("shape", "ellipse")
        filled = "filled" in attrs.get("style", "filled")
        fill = attrs.get("fillcolor", "white") if filled else "white"
        common = f'fill="{_xml_escape(fill)}" stroke="black"{_dash(attrs.get("style", ""))}'
        out.append(f'<g class="node"><title>{_xml_escape(n)}</title>')
        if shape in ("box", "rect", "rectangle", "square"):
            out.append(
                f'<rect x="{b.x - b.w / 2:.1f}" y="{b.y - b.h / 2:.1f}" width="{b.w:.1f}" '
                f'height="{b.h:.1f}" {common}/>'
            )
        elif shape in ("diamond", "triangle", "cds", "larrow"):
            out.append(f'<polygon points="{_shape_points(shape, b)}" {common}/>')
        else:
            out.append(
                f'<ellipse cx="{b.x:.1f}" cy="{b.y:.1f}" rx="{b.w / 2:.1f}" '
                f'ry="{b.h / 2:.1f}" {common}/>'
            )
        first = b.y - (len(b.lines) - 1) * _LINE_H / 2 + 3.5
        if shape == "triangle":
            first += b.h / 6  # the wide part of a triangle is at the bottom
        for k, line in enumerate(b.lines):
            out.append(
                f'<text x="{b.x:.1f}" y="{first + k * _LINE_H:.1f}" text-anchor="middle" '
                f'font-size="10">{_xml_escape(line)}</text>'
            )
        out.append("</g>")
    out.append("</g>")
    out.append("</svg>")
    return "\n".join(out) + "\n"


__all__ = ["builtin_svg", "parse_dot"]
