"""``eamos report``: an HTML page about a run folder (of ``eamos run`` or a roll-out)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from .errors import command
from .exits import EXIT_OK
from .options import add_verbose

_REPORT_HELP = """\
Write a self-contained HTML page about a run folder (of `eamos run` or a
roll-out): each drone's mission timeline (Gantt chart of its actions),
trajectories, triggers against MDG arcs (paper Table 7), durations."""


def add_report_parser(sub: Any) -> None:
    """Add ``eamos report`` to the ``eamos`` command's subparsers."""
    p = sub.add_parser(
        "report",
        help="write an HTML report of a run folder",
        description=_REPORT_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run_dir", metavar="RUN_DIR", type=Path, help="a run folder with summary.json")
    p.add_argument("-o", "--output", type=Path, metavar="HTML", help="default: RUN_DIR/report.html")
    add_verbose(p)
    command(p, cmd_report)


def cmd_report(args: argparse.Namespace) -> int:
    """``eamos report``; a :class:`~eamos.report.ReportError` is bad input (exit 2)."""
    from eamos.report import write_html

    path = write_html(args.run_dir, args.output)
    print(f"report: {path}")
    return EXIT_OK


__all__ = ["add_report_parser", "cmd_report"]
