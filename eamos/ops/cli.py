"""The fleet commands of ``eamos``: rollout, start, status, abort, logs fetch, report.

``eamos/cli.py`` adds them with :func:`add_fleet_commands`.  Exit codes: 0
done, 1 the operation failed on the fleet (a drone unreachable, a mission not
ok, ...), 2 bad input (mission, fleet file, run folder).
"""

from __future__ import annotations

import argparse
import sys
import threading
from pathlib import Path
from typing import Any

from eamos.config import positive_number as _positive

_ROLLOUT_HELP = """\
Roll a mission out to real drones over SSH (paper V-E, VI-E/F): compile it here
into a run folder, check every drone (reachable, same eamos version, enough
disk), copy each drone only what changed since the last roll-out (its program,
its config), and start eamos-node on every drone, detached, with its logs.
Then `eamos start RUN_DIR` waits until all are ready and starts the mission
(scripts/rollout.sh does both).  Each step and each drone's part is timed.

Nothing is copied or started unless every drone passes the checks."""

_ROLLOUT_EPILOG = """\
examples:
  eamos rollout missions/experiment_b.go configs/fleet_example.toml --run-dir runs/b
  eamos start runs/b
see docs/operations.md for the fleet file ([ground], [drones.NAME.ssh])"""

_START_HELP = """\
Be the ground station of a rolled-out mission: wait until every drone reports
ready (with the program the roll-out deployed), send the start trigger, show
progress, declare completion, write RUN_DIR/summary.json.  If a drone never
becomes ready, the mission is not started and the others are told to abort.
Ctrl-C (or `eamos abort RUN_DIR`) aborts: every drone lands."""

_STATUS_HELP = """\
Show every drone of a rolled-out mission: whether its eamos-node runs, its
program, the action in progress and its position (live telemetry, else the
last logged position)."""

_ABORT_HELP = """\
Every drone lands now.  If `eamos start` runs for this run folder it is told
to abort (it broadcasts the abort); otherwise this command takes the ground
station's endpoint itself, broadcasts the abort and waits for the drones to
report they landed."""

_LOGS_HELP = """\
Collect every drone's logs (mission.log, uniform.log, adapter.log, node.out,
report.json) over SSH into RUN_DIR/logs/<Drone>/."""

_REPORT_HELP = """\
Write a self-contained HTML page about a run folder (of `eamos run` or a
roll-out): each drone's mission timeline (Gantt chart of its actions),
trajectories, triggers against MDG arcs (paper Table 7), durations."""


def _source_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "source",
        metavar="RUN_DIR|FLEET.toml",
        type=Path,
        help="the roll-out's run folder, or the fleet file (then the drones say what they have)",
    )
    parser.add_argument(
        "--mission", metavar="NAME", help="with a fleet file: which rolled-out mission"
    )
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="tracebacks of internal errors"
    )


def add_fleet_commands(sub: Any) -> None:
    """Add ``rollout``, ``start``, ``status``, ``abort``, ``logs`` and ``report``."""
    fmt = argparse.RawDescriptionHelpFormatter
    p = sub.add_parser(
        "rollout",
        help="compile a mission and deploy it to real drones over SSH",
        description=_ROLLOUT_HELP,
        epilog=_ROLLOUT_EPILOG,
        formatter_class=fmt,
    )
    p.add_argument("mission", metavar="MISSION.go", type=Path, help="the mission file")
    p.add_argument(
        "fleet", metavar="FLEET.toml", type=Path, help="the drones: SSH hosts, folders, hardware"
    )
    p.add_argument(
        "--run-dir", type=Path, metavar="DIR", help="run folder (default runs/<mission>-<time>/)"
    )
    p.add_argument(
        "--speedup",
        type=_positive,
        metavar="K",
        help="simulated drones run K times faster than real time",
    )
    p.add_argument("--svg", action="store_true", help="also draw the graphs as SVG (slower)")
    p.add_argument("-v", "--verbose", action="store_true", help="tracebacks of internal errors")
    p.set_defaults(func=cmd_rollout)

    p = sub.add_parser(
        "start",
        help="start a rolled-out mission (the ground station)",
        description=_START_HELP,
        formatter_class=fmt,
    )
    p.add_argument("run_dir", metavar="RUN_DIR", type=Path, help="the roll-out's run folder")
    p.add_argument(
        "--timeout",
        type=_positive,
        default=600.0,
        metavar="SECONDS",
        help="abort (everyone lands) if the mission is not over after this long (600)",
    )
    p.add_argument(
        "--ready-timeout",
        type=_positive,
        metavar="SECONDS",
        help="how long the drones may take to be ready (default: [ground] ready_timeout_s)",
    )
    p.add_argument("--plain", action="store_true", help="plain progress lines, no live table")
    p.add_argument("-v", "--verbose", action="store_true", help="tracebacks of internal errors")
    p.set_defaults(func=cmd_start)

    p = sub.add_parser(
        "status",
        help="show the drones of a rolled-out mission",
        description=_STATUS_HELP,
        formatter_class=fmt,
    )
    _source_arg(p)
    p.add_argument(
        "--listen",
        type=_positive,
        default=2.0,
        metavar="SECONDS",
        help="how long to listen for live telemetry (2)",
    )
    p.set_defaults(func=cmd_status)

    p = sub.add_parser(
        "abort",
        help="land every drone of a rolled-out mission now",
        description=_ABORT_HELP,
        formatter_class=fmt,
    )
    _source_arg(p)
    p.add_argument("--reason", default="aborted by the operator", help="logged by every drone")
    p.add_argument(
        "--timeout",
        type=_positive,
        default=180.0,
        metavar="SECONDS",
        help="how long to wait for the drones to land (180)",
    )
    p.set_defaults(func=cmd_abort)

    logs = sub.add_parser("logs", help="drone logs of a rolled-out mission", description=_LOGS_HELP)
    logs_sub = logs.add_subparsers(dest="logs_command", required=True, metavar="ACTION")
    p = logs_sub.add_parser(
        "fetch",
        help="copy every drone's logs into the run folder",
        description=_LOGS_HELP,
        formatter_class=fmt,
    )
    _source_arg(p)
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        metavar="RUN_DIR",
        help="run folder to fill (default: the RUN_DIR given; required with a fleet file)",
    )
    p.set_defaults(func=cmd_logs_fetch)

    p = sub.add_parser(
        "report",
        help="write an HTML report of a run folder",
        description=_REPORT_HELP,
        formatter_class=fmt,
    )
    p.add_argument("run_dir", metavar="RUN_DIR", type=Path, help="a run folder with summary.json")
    p.add_argument("-o", "--output", type=Path, metavar="HTML", help="default: RUN_DIR/report.html")
    p.add_argument("-v", "--verbose", action="store_true", help="tracebacks of internal errors")
    p.set_defaults(func=cmd_report)


def _say(text: str) -> None:
    # One write per line: the drones' steps run in threads, and print() writes the
    # text and its newline separately, which interleaves lines.
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


def _fail(command: str, exc: Exception, code: int) -> int:
    print(f"eamos {command}: {exc}", file=sys.stderr, flush=True)
    return code


def cmd_rollout(args: argparse.Namespace) -> int:
    """``eamos rollout``."""
    from ..compiler import MissionError
    from ..config import ConfigError
    from .rollout import RolloutOptions, paper_table, rollout
    from .ssh import FleetError

    opts = RolloutOptions(args.mission, args.fleet, args.run_dir, args.speedup, args.svg)
    try:
        result = rollout(opts, _say)
    except MissionError as exc:
        try:
            source = Path(args.mission).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            source = None
        print(exc.render(str(args.mission), source), file=sys.stderr)
        return 2
    except ConfigError as exc:
        return _fail("rollout", exc, 2)
    except FleetError as exc:
        return _fail("rollout", exc, 1)
    rows = paper_table(result.durations)
    print(
        f"roll-out done in {result.durations.get('rollout', 0):.2f} s "
        f"(compilation {rows[0][1]:.2f} s, deployment {rows[1][1]:.2f} s); "
        f"every drone's eamos-node is waiting for the ground station"
    )
    print(f"next: eamos start {result.run_dir}")
    return 0


def print_table7(durations: dict[str, float]) -> None:
    """The paper's Table 7 roll-out rows."""
    from .rollout import paper_table

    print("roll-out (paper Table 7):")
    for row, value in paper_table(durations):
        print(f"  {row:<20} {value:8.2f} s")


def cmd_start(args: argparse.Namespace) -> int:
    """``eamos start``."""
    from ..config import ConfigError
    from ..program.format import ProgramError
    from ..run import install_stop_handler
    from .ground import StartOptions, start
    from .ssh import FleetError

    stop = threading.Event()
    install_stop_handler(stop)
    opts = StartOptions(
        args.run_dir, args.timeout, args.ready_timeout, live=False if args.plain else None
    )
    try:
        summary = start(opts, stop)
    except (ConfigError, ProgramError) as exc:
        return _fail("start", exc, 2)
    except FleetError as exc:
        return _fail("start", exc, 1 if (Path(args.run_dir) / "rollout.json").exists() else 2)
    status = "finished" if summary["ok"] else f"FAILED ({summary['outcome']})"
    print(f"mission {summary['mission']} {status} in {summary['duration_s']:.1f} s")
    for name, report in summary["drones"].items():
        if report.get("error") == "no report":
            print(f"  {name} ({report.get('host')}): no report")
            continue
        print(
            f"  {name} ({report.get('host')}): {'ok' if report.get('ok') else 'not ok'}, "
            f"{len(report.get('actions', []))} actions, triggers sent/received "
            f"{report.get('triggers_sent')}/{report.get('triggers_received')} "
            f"(MDG external arcs out/in {report.get('external_out')}/{report.get('external_in')})"
        )
    print_table7(summary["rollout"]["durations"])
    print(f"summary: {summary['run_dir']}/summary.json; logs: eamos logs fetch {args.run_dir}")
    return 0 if summary["ok"] else 1


def _deployment(args: argparse.Namespace) -> Any:
    from .deployment import resolve

    return resolve(args.source, args.mission)


def cmd_status(args: argparse.Namespace) -> int:
    """``eamos status``."""
    from ..config import ConfigError
    from .ssh import FleetError
    from .status import fleet_status, format_status

    try:
        dep = _deployment(args)
        rows = fleet_status(dep, args.listen)
    except ConfigError as exc:
        return _fail("status", exc, 2)
    except FleetError as exc:
        return _fail("status", exc, 1)
    print(format_status(dep, rows))
    return 1 if any(r.error for r in rows) else 0


def cmd_abort(args: argparse.Namespace) -> int:
    """``eamos abort``."""
    from ..config import ConfigError
    from .ground import abort
    from .ssh import FleetError

    try:
        result = abort(args.source, args.mission, args.reason, args.timeout, _say)
    except ConfigError as exc:
        return _fail("abort", exc, 2)
    except FleetError as exc:
        return _fail("abort", exc, 1)
    for name, landed in result.landed.items():
        print(f"  {name}: {'landed' if landed else 'NOT confirmed landed'}")
    for note in result.notes:
        print(f"  {note}")
    return 0 if result.ok else 1


def cmd_logs_fetch(args: argparse.Namespace) -> int:
    """``eamos logs fetch``."""
    from ..config import ConfigError
    from .ssh import FleetError
    from .status import fetch_logs

    try:
        dep = _deployment(args)
    except ConfigError as exc:
        return _fail("logs fetch", exc, 2)
    except FleetError as exc:
        return _fail("logs fetch", exc, 1)
    out = args.output or dep.run_dir
    if out is None:
        print("eamos logs fetch: -o RUN_DIR is required with a fleet file", file=sys.stderr)
        return 2
    print(f"fetching the logs of {', '.join(dep.drones)} into {Path(out) / 'logs'}")
    result = fetch_logs(dep, Path(out), _say)
    for err in result.errors:
        print(f"  {err}", file=sys.stderr)
    return 1 if result.errors else 0


def cmd_report(args: argparse.Namespace) -> int:
    """``eamos report``."""
    from ..report import ReportError, write_html

    try:
        path = write_html(args.run_dir, args.output)
    except ReportError as exc:
        return _fail("report", exc, 2)
    print(f"report: {path}")
    return 0


__all__ = ["add_fleet_commands"]
