"""Shared helpers for the compiler tests: where the missions are, and graph lookups."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import networkx as nx

REPO = Path(__file__).resolve().parents[2]
MISSIONS = REPO / "missions"
#: Our verbatim copy in missions/ -> the paper listing it reproduces (Listings 1, 10 to 13).
PAPER_COPIES: dict[str, str] = {
    "listing01_demo.go": "listing01_demo_mission.go",
    "experiment_a.go": "listing10_experiment_a.go",
    "experiment_b.go": "listing11_experiment_b.go",
    "experiment_c.go": "listing12_experiment_c.go",
    "experiment_d.go": "listing13_experiment_d.go",
}


def mission_files() -> list[Path]:
    """Every mission in missions/, sorted."""
    return sorted(MISSIONS.glob("*.go"))


def node_by_label(graph: nx.DiGraph, label: str, drone: str | None = None) -> Any:
    """The one node with this label (and drone); fails the test if not exactly one."""
    found = [
        n
        for n, a in graph.nodes(data=True)
        if a.get("label") == label and (drone is None or a.get("drone") == drone)
    ]
    assert len(found) == 1, f"expected one node {label!r} on {drone}, found {found}"
    return found[0]


def names(graph: nx.DiGraph) -> dict[Any, str]:
    """A readable name per node: ``label@drone`` (forks and seq nodes: their block name)."""
    out = {}
    for n, a in graph.nodes(data=True):
        drone = a.get("drone", "")
        out[n] = f"{a.get('label')}@{drone}" if drone else str(a.get("label"))
    return out


def named_edges(graph: nx.DiGraph) -> set[tuple[str, str]]:
    """The arcs as pairs of :func:`names`."""
    nm = names(graph)
    return {(nm[a], nm[b]) for a, b in graph.edges}


#: Attributes that say where a node was written, not what it does: a mission written
#: with loops and the same one written out differ there only.
PLACE_ATTRS = frozenset({"block", "line", "col", "catch_line"})


def semantics(graph: nx.DiGraph, rename: Callable[[str], str] = str) -> list[str]:
    """A graph's nodes and arcs with every attribute but where they were written, as text.

    Node ids are kept: the compiler numbers the nodes of a mission in the order it
    builds them, so two missions that expand to the same tree get the same ids.  The
    labels of ``seq``/``par`` nodes and forks are block names, so they are left out too.
    ``rename`` maps drone names (applied to the text of each node and arc).
    """
    import json

    out = []
    for node, attrs in graph.nodes(data=True):
        kept = {k: v for k, v in attrs.items() if k not in PLACE_ATTRS}
        if attrs.get("kind") in ("seq", "par", "fork"):
            kept.pop("label", None)
        out.append(rename(json.dumps([str(node), sorted(kept.items())], default=list)))
    for a, b, d in graph.edges(data=True):
        out.append(rename(json.dumps([str(a), str(b), sorted(d.items())], default=list)))
    graph_attrs = {k: v for k, v in graph.graph.items() if k not in ("mission", "entry")}
    out.append(rename(json.dumps(sorted(graph_attrs.items()), default=list)))
    return sorted(out)


def program_semantics(program: Any, rename: Callable[[str], str] = str) -> str:
    """A drone program as JSON without what says where its nodes were written.

    Nodes and arcs are compared as sets (a program orders them by names, which
    ``rename`` may reorder).
    """
    import json

    data = json.loads(rename(program.to_json()))
    for key in ("mission", "mission_id", "source_file", "checksum"):
        data.pop(key, None)
    for node in data.get("nodes", []):
        for key in PLACE_ATTRS:
            node.pop(key, None)
        if node.get("kind") in ("seq", "par", "fork"):
            node.pop("label", None)
    for key in ("nodes", "arcs"):
        data[key] = sorted(json.dumps(item, sort_keys=True) for item in data.get(key, []))
    return json.dumps(data, sort_keys=True)
