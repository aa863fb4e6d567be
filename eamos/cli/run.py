"""``eamos run``: fly a mission on this machine, one ``eamos-node`` process per drone."""

from __future__ import annotations

import argparse
import sys
import threading
from pathlib import Path
from typing import Any

from eamos.compiler import MissionError
from eamos.config import ConfigError, FleetConfig
from eamos.config import positive_number as _positive

_RUN_HELP = """\
Fly a mission on this machine: compile it, start one eamos-node process per drone
(simulated quadcopters unless the fleet file says otherwise), act as the ground
station, show live progress, and write a run folder with the programs, graphs,
per-drone logs (mission.log, uniform.log, adapter.log) and summary.json.

Exit code 0 when every drone finished its part, 1 otherwise (a failed action, a
timeout, an abort), 2 for a bad mission or fleet file.  Ctrl-C aborts: every
drone lands, then every process ends."""

_RUN_EPILOG = """\
examples:
  eamos run missions/experiment_b.go --speedup 10
  eamos run missions/experiment_d.go --fleet configs/experiment_d_pilot.toml --summary out/d.json"""


def add_run_parser(sub: Any) -> None:
    """Add ``eamos run`` to the ``eamos`` subcommands."""
    run = sub.add_parser(
        "run",
        help="fly a mission on simulated drones (one process per drone)",
        description=_RUN_HELP,
        epilog=_RUN_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    run.add_argument("mission", metavar="MISSION.go", type=Path, help="the mission file")
    run.add_argument(
        "--fleet",
        type=Path,
        metavar="FLEET.toml",
        help="per-drone hardware settings (default: every drone simulated)",
    )
    run.add_argument(
        "--speedup",
        type=_positive,
        metavar="K",
        help="simulated time runs K times faster than real time (default 1)",
    )
    run.add_argument(
        "--summary", type=Path, metavar="PATH", help="also write the summary JSON here"
    )
    run.add_argument(
        "--run-dir",
        type=Path,
        metavar="DIR",
        help="the run folder (default: runs/<mission>-<date-time>/)",
    )
    run.add_argument(
        "--timeout",
        type=_positive,
        default=600.0,
        metavar="SECONDS",
        help="abort (everyone lands) if the mission is not over after this long (600)",
    )
    run.add_argument(
        "--ready-timeout",
        type=_positive,
        default=60.0,
        metavar="SECONDS",
        help="how long drones may take to start and connect (60)",
    )
    run.add_argument(
        "--plain", action="store_true", help="plain progress lines instead of a live table"
    )
    run.add_argument(
        "--no-svg", dest="svg", action="store_false", help="skip drawing graph pictures"
    )
    run.add_argument("-v", "--verbose", action="store_true", help="tracebacks of internal errors")
    run.set_defaults(func=cmd_run)


def cmd_run(args: argparse.Namespace) -> int:
    """``eamos run``."""
    from eamos.run import RunOptions, install_stop_handler, run_mission

    try:
        fleet = FleetConfig.load(args.fleet) if args.fleet else FleetConfig.empty()
    except ConfigError as exc:
        print(f"eamos run: {exc}", file=sys.stderr)
        return 2
    stop = threading.Event()
    install_stop_handler(stop)
    opts = RunOptions(
        mission=args.mission,
        fleet=fleet,
        speedup=args.speedup,
        summary=args.summary,
        run_dir=args.run_dir,
        timeout_s=args.timeout,
        ready_timeout_s=args.ready_timeout,
        live=False if args.plain else None,
        svg=args.svg,
    )
    try:
        summary = run_mission(opts, stop)
    except MissionError as exc:
        source = None
        try:
            source = Path(args.mission).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            pass
        print(exc.render(str(args.mission), source), file=sys.stderr)
        return 2
    except ConfigError as exc:
        print(f"eamos run: {exc}", file=sys.stderr)
        return 2
    status = "finished" if summary["ok"] else f"FAILED ({summary['outcome']})"
    print(f"mission {summary['mission']} {status} in {summary['duration_s']:.1f} s")
    for name, report in summary["drones"].items():
        fails = [a for a in report.get("actions", []) if a["result"] != "ok"]
        extra = "".join(f"; {a['action']} {a['result']}: {a.get('reason', '')}" for a in fails)
        blocked = report.get("blocked_nodes") or []
        if blocked:
            extra += f"; blocked: {len(blocked)} node(s)"
        print(
            f"  {name}: {'ok' if report.get('ok') else 'not ok'}, "
            f"{len(report.get('actions', []))} actions, triggers sent/received "
            f"{report.get('triggers_sent')}/{report.get('triggers_received')}"
            f"{extra}"
        )
    print(f"summary: {summary['run_dir']}/summary.json")
    return 0 if summary["ok"] else 1
