"""Write everything a compilation produced into one output folder.

Layout of ``out_dir`` (paths in the manifest are relative to it)::

    programs/<Drone>.program.json   one drone program per participant (GCS included)
    graphs/amt.{graphml,dot,svg}    the Abstract Mission Tree
    graphs/meg.{graphml,dot,svg}    the Mission Execution Graph
    graphs/mdg_<Drone>.{graphml,dot,svg}  each participant's Mission Dependency Graph
    stats.json                      Table 7's figures (``CompiledMission.stats()``)
    manifest.json                   what was written, with SHA-256 checksums

Files of an earlier compilation into the same folder that this one does not
produce (programs of drones no longer in the mission, their graphs, SVGs
when ``svg=False``) are removed, so a folder never mixes two missions.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import networkx as nx

from .drawing import GraphKind, render_svg, to_dot, to_graphml
from .phases import CompiledMission

MANIFEST_FORMAT = "eamos-artifacts"
MANIFEST_VERSION = 1


def _sha256(path: Path) -> str:
    return "sha256:" + hashlib.sha256(path.read_bytes()).hexdigest()


def _write_text(path: Path, text: str) -> Path:
    """Write atomically, so an interrupted compile never leaves half a file."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)
    return path


def graph_files(compiled: CompiledMission) -> list[tuple[str, GraphKind, nx.DiGraph]]:
    """``(file stem, kind, graph)`` for every graph of a compilation, AMT and MEG first."""
    out: list[tuple[str, GraphKind, nx.DiGraph]] = [
        ("amt", "amt", compiled.amt),
        ("meg", "meg", compiled.meg),
    ]
    out.extend((f"mdg_{drone}", "mdg", mdg) for drone, mdg in compiled.mdgs.items())
    return out


def _remove_stale(folder: Path, keep: set[Path], suffixes: tuple[str, ...]) -> None:
    if not folder.is_dir():
        return
    for path in folder.iterdir():
        if path.is_file() and path.name.endswith(suffixes) and path not in keep:
            path.unlink()


def write_artifacts(
    compiled: CompiledMission,
    out_dir: Path | str,
    svg: bool = True,
    *,
    warnings: list[str] | None = None,
    render: Callable[..., str] = render_svg,
) -> dict[str, Any]:
    """Write programs, graphs (GraphML, DOT, SVG) and stats of ``compiled`` under ``out_dir``.

    Returns the manifest (also written as ``manifest.json``)::

        {"format": "eamos-artifacts", "version": 1, "mission", "mission_id", "source_file",
         "programs": {DRONE: {"path", "checksum"}},   # the program's own checksum
         "graphs": {STEM: {"graphml", "dot"[, "svg"]}},
         "stats": "stats.json",
         "files": {PATH: "sha256:<hex>"},             # every file written
         "warnings": [...]}                           # e.g. Graphviz fell back

    ``svg=False`` skips the pictures (the slow part for big missions).
    Problems drawing SVG are added to ``warnings`` (when given) and to the
    manifest; OSErrors writing files propagate.
    """
    out = Path(out_dir)
    programs_dir = out / "programs"
    graphs_dir = out / "graphs"
    programs_dir.mkdir(parents=True, exist_ok=True)
    graphs_dir.mkdir(parents=True, exist_ok=True)
    notes: list[str] = []
    written: list[Path] = []
    manifest: dict[str, Any] = {
        "format": MANIFEST_FORMAT,
        "version": MANIFEST_VERSION,
        "mission": compiled.mission.name,
        "mission_id": compiled.mission_id,
        "source_file": compiled.source_file,
        "programs": {},
        "graphs": {},
        "stats": "stats.json",
        "files": {},
        "warnings": notes,
    }

    for drone, program in compiled.programs.items():
        path = program.save(programs_dir / f"{drone}.program.json")
        written.append(path)
        manifest["programs"][drone] = {
            "path": path.relative_to(out).as_posix(),
            "checksum": program.checksum,
        }

    fleet = list(compiled.programs)
    dots: list[tuple[str, str]] = []
    for stem, kind, graph in graph_files(compiled):
        entry: dict[str, str] = {}
        graphml = to_graphml(graph, graphs_dir / f"{stem}.graphml")
        dot_text = to_dot(graph, kind, fleet=fleet)
        dot_path = _write_text(graphs_dir / f"{stem}.dot", dot_text)
        written += [graphml, dot_path]
        entry["graphml"] = graphml.relative_to(out).as_posix()
        entry["dot"] = dot_path.relative_to(out).as_posix()
        manifest["graphs"][stem] = entry
        dots.append((stem, dot_text))

    if svg and render is render_svg and shutil.which("dot") is None:
        # Said once, not per picture: the pictures are still drawn.
        notes.append(
            "Graphviz 'dot' is not installed: pictures drawn by the built-in renderer "
            "(install graphviz for its layouts)"
        )
    if svg:
        # Graphviz runs as a subprocess, so a few threads draw in parallel.
        def draw(item: tuple[str, str]) -> tuple[str, str, list[str]]:
            stem, dot_text = item
            found: list[str] = []
            return stem, render(dot_text, warnings=found), found

        workers = max(1, min(4, os.cpu_count() or 1, len(dots)))
        with ThreadPoolExecutor(max_workers=workers) as pool:
            for stem, svg_text, found in pool.map(draw, dots):
                path = _write_text(graphs_dir / f"{stem}.svg", svg_text)
                written.append(path)
                manifest["graphs"][stem]["svg"] = path.relative_to(out).as_posix()
                notes.extend(f"{stem}.svg: {w}" for w in found)

    stats_path = _write_text(out / "stats.json", json.dumps(compiled.stats(), indent=1) + "\n")
    written.append(stats_path)

    keep = set(written)
    _remove_stale(programs_dir, keep, (".program.json", ".tmp"))
    _remove_stale(graphs_dir, keep, (".graphml", ".dot", ".svg", ".tmp"))

    manifest["files"] = {p.relative_to(out).as_posix(): _sha256(p) for p in written}
    _write_text(out / "manifest.json", json.dumps(manifest, indent=1) + "\n")
    if warnings is not None:
        warnings.extend(notes)
    return manifest


__all__ = ["graph_files", "write_artifacts"]
