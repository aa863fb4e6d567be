"""The ``eamos`` command: compile, draw and run missions.

    eamos compile MISSION.go [-o OUT] [--stats]    compile to drone programs and graphs
    eamos graph MISSION.go [--which meg] ...         draw one graph
    eamos run MISSION.go [--fleet F] [--speedup K]   fly it on simulated drones, one process each
    eamos rollout / start / status / abort / logs fetch / report   real drones over SSH
    eamos keys OUT [--fleet NAMES...]                the fleet's network keys (CURVE)

Every command prints clear errors and exits non-zero on bad input; a
traceback appears only with ``-v``.
"""

from __future__ import annotations

import argparse
import sys
import threading
import traceback
from pathlib import Path

from eamos import __version__
from eamos.compiler import MissionError
from eamos.compiler.cli_compile import add_compile_parser, add_graph_parser
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


def build_parser() -> argparse.ArgumentParser:
    """The ``eamos`` argument parser with every subcommand."""
    parser = argparse.ArgumentParser(
        prog="eamos",
        description="EAMOS: write a multi-drone mission as a short Go-syntax text file, "
        "compile it into one program per drone, and run it decentralized.",
    )
    parser.add_argument("--version", action="version", version=f"eamos {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    add_compile_parser(sub)
    add_graph_parser(sub)
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
    # --- fleet operations (eamos/ops/cli.py): rollout, start, status, abort, logs, report ---
    from eamos.ops.cli import add_fleet_commands

    add_fleet_commands(sub)
    # --- end of fleet operations ---
    # --- network keys (eamos/net/keys.py): eamos keys ---
    from eamos.net.keys import add_keys_parser

    add_keys_parser(sub)
    # --- end of network keys ---
    return parser


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


def main(argv: list[str] | None = None) -> int:
    """Console entry point of ``eamos``."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # an internal error: one line, the trace only with -v
        if getattr(args, "verbose", False):
            traceback.print_exc()
        print(
            f"eamos: internal error: {exc!r} (run with -v for details); please report it",
            file=sys.stderr,
        )
        return 4


if __name__ == "__main__":
    sys.exit(main())
