"""The ``eamos compile`` and ``eamos graph`` commands.

``eamos/cli.py`` registers them with :func:`add_compile_parser` and
:func:`add_graph_parser`; each sets ``func`` (the handler, returning the exit
code) in the parsed arguments.  Exit codes: 0 success, 1 the mission has
errors (or a file cannot be written), 2 an internal error or bad usage.
Mission errors are printed as ``file:line:col: error: ...`` with the line,
a caret and a hint; never as a traceback.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import shutil
import subprocess
import sys
import traceback
import webbrowser
from pathlib import Path
from typing import Any, TextIO

import networkx as nx

from .artifacts import write_artifacts
from .drawing import GraphKind, graphml_ready, render_svg, to_dot, to_graphml
from .errors import Diagnostic, MissionError
from .phases import CompiledMission, compile_file

EXIT_OK = 0
EXIT_MISSION = 1
EXIT_INTERNAL = 2

_COMPILE_HELP = """\
Compile a mission file into one drone program per participant.

Writes, under OUT (default: out/<mission name>/):
  programs/<Drone>.program.json   the program each drone (and the ground station GCS) runs
  graphs/amt|meg|mdg_<Drone>.graphml/.dot/.svg   the mission graphs (paper Figures 6-8)
  stats.json, manifest.json       graph sizes (paper Table 7) and checksums of every file

Errors are reported as FILE:LINE:COL with a hint; all errors of the file at once.
Exit code: 0 compiled, 1 the mission has errors, 2 internal error."""

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
    p.add_argument("mission", metavar="MISSION.go", help="the mission file")
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
    p.add_argument(
        "--no-svg",
        dest="svg",
        action="store_false",
        help="skip drawing the SVG pictures (faster for big missions)",
    )
    p.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        help="more detail, and the traceback of internal errors",
    )
    p.set_defaults(func=run_compile)
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
    p.add_argument("mission", metavar="MISSION.go", help="the mission file")
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
    p.add_argument("-v", "--verbose", action="store_true", help="the traceback of internal errors")
    p.set_defaults(func=run_graph)
    return p


# -- shared helpers -----------------------------------------------------------------


def _source_text(path: str) -> str | None:
    """The mission text for error rendering (None if it cannot be read)."""
    try:
        text = Path(path).read_bytes().decode("utf-8", errors="replace")
    except OSError:
        return None
    # Never echo a binary file's bytes to the terminal.
    return None if "\x00" in text else text


def _print_warnings(
    warnings: tuple[Diagnostic, ...] | list[Diagnostic], path: str, source: str | None, err: TextIO
) -> None:
    for w in warnings:
        print(w.render(path, source), file=err)


def _compile(path: str, verbose: bool, err: TextIO) -> tuple[CompiledMission | None, int]:
    """Compile ``path``; on failure print the diagnosis and return the exit code."""
    try:
        return compile_file(Path(path)), EXIT_OK
    except MissionError as exc:
        print(exc.render(path, _source_text(path)), file=err)
        return None, EXIT_MISSION
    except Exception as exc:  # any other failure is our bug, reported as such
        return None, _internal_error(exc, verbose, err)


def _internal_error(exc: BaseException, verbose: bool, err: TextIO) -> int:
    if verbose:
        traceback.print_exception(exc, file=err)
    detail = str(exc) or type(exc).__name__
    advice = "please report it" if verbose else "(run with -v for details), please report it"
    print(f"internal error: {type(exc).__name__}: {detail} {advice}", file=err)
    return EXIT_INTERNAL


def default_out_dir(mission: str) -> Path:
    """``out/<mission file stem>/`` under the current folder."""
    return Path("out") / Path(mission).stem


# -- eamos compile ----------------------------------------------------------------------


def run_compile(
    args: argparse.Namespace, out: TextIO | None = None, err: TextIO | None = None
) -> int:
    """Handle ``eamos compile``; returns the exit code."""
    out = out or sys.stdout
    err = err or sys.stderr
    path = str(args.mission)
    verbose = bool(getattr(args, "verbose", False))
    compiled, code = _compile(path, verbose, err)
    if compiled is None:
        return code
    source = _source_text(path)
    _print_warnings(compiled.warnings, path, source, err)
    out_dir = Path(args.out) if getattr(args, "out", None) else default_out_dir(path)
    notes: list[str] = []
    try:
        manifest = write_artifacts(
            compiled, out_dir, svg=getattr(args, "svg", True), warnings=notes
        )
    except OSError as exc:
        print(f"error: cannot write the output to {out_dir}: {exc.strerror or exc}", file=err)
        return EXIT_MISSION
    except Exception as exc:  # our bug: reported as an internal error
        return _internal_error(exc, verbose, err)
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
    out = out or sys.stdout
    err = err or sys.stderr
    path = str(args.mission)
    verbose = bool(getattr(args, "verbose", False))
    which: GraphKind = args.which
    fmt: str = args.format
    compiled, code = _compile(path, verbose, err)
    if compiled is None:
        return code
    _print_warnings(compiled.warnings, path, _source_text(path), err)
    if which == "mdg":
        names = ", ".join(compiled.mdgs)
        if not args.drone:
            print(f"error: --which mdg needs --drone NAME (one of {names})", file=err)
            return EXIT_INTERNAL
        if args.drone not in compiled.mdgs:
            print(f"error: no drone '{args.drone}' in this mission (one of {names})", file=err)
            return EXIT_INTERNAL
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
        print(f"error: cannot write {target}: {exc.strerror or exc}", file=err)
        return EXIT_MISSION
    except Exception as exc:  # our bug: reported as an internal error
        return _internal_error(exc, verbose, err)
    if args.open and open_file(target):
        print(f"opened {target}", file=out)
    else:
        hint = " (no viewer found: open it in a browser)" if args.open else ""
        print(f"wrote {target}{hint}", file=out)
    return EXIT_OK


def build_parser() -> argparse.ArgumentParser:
    """A stand-alone parser with just ``compile`` and ``graph`` (for ``python -m``)."""
    parser = argparse.ArgumentParser(prog="eamos", description="EAMOS mission compiler")
    sub = parser.add_subparsers(dest="command", required=True)
    add_compile_parser(sub)
    add_graph_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """``python -m eamos.compiler.cli_compile compile|graph ...``."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
