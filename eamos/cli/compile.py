"""``eamos compile`` and ``eamos graph``: compile a mission, draw one of its graphs.

Mission errors are printed as ``file:line:col: error: ...`` with the line, a
caret and a hint (by :mod:`eamos.cli.errors`), never as a traceback.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import shutil
import subprocess
import sys
import webbrowser
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from .errors import BadInput, command, source_text
from .exits import EXIT_OK
from .options import add_fleet_file, add_mission, add_svg, add_verbose

if TYPE_CHECKING:  # the compiler (networkx, tree-sitter) loads when a command runs, not for --help
    from eamos.compiler import CompiledMission, Diagnostic
    from eamos.compiler.drawing import GraphKind

_COMPILE_HELP = """\
Compile a mission file into one drone program per participant.

Writes, under OUT (default: out/<mission name>/):
  programs/<Drone>.program.json   the program each drone (and the ground station GCS) runs
  graphs/amt|meg|mdg_<Drone>.graphml/.dot/.svg   the mission graphs (paper Figures 6-8)
  stats.json, manifest.json       graph sizes (paper Table 7) and checksums of every file

Errors are reported as FILE:LINE:COL with a hint; all errors of the file at once.
With --fleet, each drone's adapter (sim, px4, ardupilot) must implement every action the
mission calls on that drone (the uniform API's and installed action plugins'); each call it
lacks is an error.

Exit code: 0 compiled, 2 the mission has errors (or the output cannot be written, or a
drone's adapter lacks an action it calls), 4 internal error."""

_COMPILE_EPILOG = """\
examples:
  eamos compile missions/experiment_c.go
  eamos compile missions/experiment_c.go -o /tmp/expc --no-svg
  eamos compile missions/experiment_d.go --stats     # only the JSON on stdout"""

_GRAPH_HELP = """\
Draw one graph of a mission: the Abstract Mission Tree (amt), the Mission
Execution Graph (meg) or one drone's Mission Dependency Graph (mdg --drone NAME).

Shapes: triangle start, box sequence, diamond fork, ellipse action, arrow-right
control structure, arrow-left its end.  Colours: grey ground station, then one
colour per drone.  Dashed: external arcs and proxy nodes; dotted: loop arcs."""

_GRAPH_EPILOG = """\
examples:
  eamos graph missions/listing01_demo.go --which amt -o amt.svg
  eamos graph missions/experiment_d.go --which mdg --drone D3 --format dot
  eamos graph missions/experiment_c.go --open"""


def add_compile_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register ``eamos compile`` on an ``add_subparsers()`` object; returns its parser."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        "compile",
        help="compile a mission file into drone programs and graphs",
        description=_COMPILE_HELP,
        epilog=_COMPILE_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_mission(p, path=False)
    p.add_argument(
        "-o",
        "--out",
        metavar="OUT",
        default=None,
        help="output folder (default: out/<mission file name without .go>/)",
    )
    p.add_argument(
        "--stats",
        action="store_true",
        help="print only the graph sizes as JSON on stdout (files are still written)",
    )
    add_svg(p, default=True)
    add_fleet_file(p, required=False)
    add_verbose(p, "more detail, and the traceback of internal errors")
    command(p, run_compile)
    return p


def add_graph_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register ``eamos graph`` on an ``add_subparsers()`` object; returns its parser."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        "graph",
        help="draw one mission graph (AMT, MEG or a drone's MDG)",
        description=_GRAPH_HELP,
        epilog=_GRAPH_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_mission(p, path=False)
    p.add_argument(
        "--which",
        choices=("amt", "meg", "mdg"),
        default="meg",
        help="amt: mission tree, meg: execution graph (default), "
        "mdg: one drone's dependency graph (needs --drone)",
    )
    p.add_argument(
        "--drone",
        metavar="NAME",
        default=None,
        help="the drone whose MDG to draw (GCS for the ground station)",
    )
    p.add_argument(
        "--format",
        choices=("svg", "dot", "graphml"),
        default="svg",
        help="svg picture (default), Graphviz dot text, or GraphML",
    )
    p.add_argument(
        "-o",
        "--out",
        metavar="FILE",
        default=None,
        help="write to FILE (default: print on stdout, or with --open "
        "out/<mission>/graphs/<graph>.<format>)",
    )
    p.add_argument(
        "--open",
        action="store_true",
        help="open the written file in a browser (or print its path if none)",
    )
    add_verbose(p, "the traceback of internal errors")
    command(p, run_graph)
    return p


# -- shared helpers -----------------------------------------------------------------


def _print_warnings(
    warnings: tuple[Diagnostic, ...] | list[Diagnostic], path: str, source: str | None, err: TextIO
) -> None:
    for w in warnings:
        print(w.render(path, source), file=err)


def default_out_dir(mission: str) -> Path:
    """``out/<mission file stem>/`` under the current folder."""
    return Path("out") / Path(mission).stem


# -- eamos compile ----------------------------------------------------------------------


def run_compile(
    args: argparse.Namespace, out: TextIO | None = None, err: TextIO | None = None
) -> int:
    """Handle ``eamos compile``; returns the exit code."""
    from eamos.compiler import compile_file, write_artifacts

    out = out or sys.stdout
    err = err or sys.stderr
    path = str(args.mission)
    verbose = bool(getattr(args, "verbose", False))
    compiled: CompiledMission = compile_file(Path(path))
    if getattr(args, "fleet", None) is not None:
        from eamos.config import FleetConfig

        from .adapter_actions import refuse_adapter_gaps

        # Every call of an action the drone's adapter lacks is a located error (exit 2).
        refuse_adapter_gaps(compiled, FleetConfig.load(args.fleet))
    source = source_text(path)
    _print_warnings(compiled.warnings, path, source, err)
    out_dir = Path(args.out) if getattr(args, "out", None) else default_out_dir(path)
    notes: list[str] = []
    try:
        manifest = write_artifacts(
            compiled, out_dir, svg=getattr(args, "svg", True), warnings=notes
        )
    except OSError as exc:
        raise BadInput(f"cannot write the output to {out_dir}: {exc.strerror or exc}") from exc
    for note in notes:
        print(f"warning: {note}", file=err)
    stats: dict[str, Any] = compiled.stats()
    if getattr(args, "stats", False):
        print(json.dumps(stats, indent=1), file=out)
        return EXIT_OK
    meg = stats["meg"]
    print(
        f"compiled {compiled.mission.name} ({path}): MEG {meg['nodes']} nodes, "
        f"{meg['arcs']} arcs, {len(compiled.programs)} participants",
        file=out,
    )
    width = max(len(d) for d in compiled.programs)
    for drone, s in stats["drones"].items():
        arcs = s["internal_arcs"] + s["external_in"] + s["external_out"]
        prog = out_dir / manifest["programs"][drone]["path"]
        print(
            f"  {drone:<{width}}  {s['nodes']:>5} nodes  {arcs:>5} arcs "
            f"({s['internal_arcs']} internal, {s['external_in']} in, {s['external_out']} out)  "
            f"{prog}",
            file=out,
        )
    if verbose:
        print(f"  mission id {compiled.mission_id}; graphs in {out_dir / 'graphs'}", file=out)
    print(f"wrote {len(manifest['files'])} files to {out_dir}/", file=out)
    return EXIT_OK


# -- eamos graph --------------------------------------------------------------------------


def _has_display() -> bool:
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def open_file(path: Path) -> bool:
    """Open ``path`` in a viewer without blocking; False when no graphical viewer exists.

    On Linux without a display, ``webbrowser`` would start a text browser in
    this terminal, so it is only used when a display is available.
    """
    if not _has_display():
        return False
    opener = shutil.which("xdg-open") if sys.platform.startswith("linux") else None
    if opener:
        try:
            subprocess.Popen(
                [opener, str(path)],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                start_new_session=True,
            )
            return True
        except OSError:
            pass
    try:
        return webbrowser.open(path.resolve().as_uri())
    except webbrowser.Error:
        return False


def run_graph(
    args: argparse.Namespace, out: TextIO | None = None, err: TextIO | None = None
) -> int:
    """Handle ``eamos graph``; returns the exit code."""
    import networkx as nx

    from eamos.compiler import compile_file
    from eamos.compiler.drawing import graphml_ready, render_svg, to_dot, to_graphml

    out = out or sys.stdout
    err = err or sys.stderr
    path = str(args.mission)
    which: GraphKind = args.which
    fmt: str = args.format
    compiled = compile_file(Path(path))
    _print_warnings(compiled.warnings, path, source_text(path), err)
    if which == "mdg":
        names = ", ".join(compiled.mdgs)
        if not args.drone:
            raise BadInput(f"--which mdg needs --drone NAME (one of {names})")
        if args.drone not in compiled.mdgs:
            raise BadInput(f"no drone '{args.drone}' in this mission (one of {names})")
        graph = compiled.mdgs[args.drone]
        stem = f"mdg_{args.drone}"
    else:
        if args.drone:
            print(f"warning: --drone is only used with --which mdg; drawing the {which}", file=err)
        graph = compiled.amt if which == "amt" else compiled.meg
        stem = which
    target: Path | None = Path(args.out) if args.out else None
    if target is None and args.open:
        target = default_out_dir(path) / "graphs" / f"{stem}.{fmt}"
    try:
        if fmt == "graphml":
            if target is None:
                buf = io.BytesIO()
                nx.write_graphml(graphml_ready(graph), buf, encoding="utf-8", prettyprint=True)
                out.write(buf.getvalue().decode("utf-8"))
                return EXIT_OK
            target.parent.mkdir(parents=True, exist_ok=True)
            to_graphml(graph, target)
        else:
            text = to_dot(graph, which, fleet=list(compiled.programs))
            if fmt == "svg":
                notes: list[str] = []
                text = render_svg(text, warnings=notes)
                for note in notes:
                    print(f"warning: {note}", file=err)
            if target is None:
                out.write(text)
                return EXIT_OK
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise BadInput(f"cannot write {target}: {exc.strerror or exc}") from exc
    if args.open and open_file(target):
        print(f"opened {target}", file=out)
    else:
        hint = " (no viewer found: open it in a browser)" if args.open else ""
        print(f"wrote {target}{hint}", file=out)
    return EXIT_OK


__all__ = ["add_compile_parser", "add_graph_parser", "open_file", "run_compile", "run_graph"]
