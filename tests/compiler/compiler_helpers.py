"""Shared helpers for the compiler tests: where the missions are, and graph lookups."""

from __future__ import annotations

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
